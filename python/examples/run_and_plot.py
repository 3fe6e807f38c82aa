#!/usr/bin/env python3
"""Runs mcslam on a TUM-layout sequence and plots its trajectory against the ground truth.

    PYTHONPATH=build/python python3 python/examples/run_and_plot.py SEQ_DIR [--output plot.png]

A synthetic sequence to try it on: ./build/mcslam synth --output /tmp/synth --frames 100
"""
import argparse
import sys

import mcslam
from mcslam.plot import plot_trajectories


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sequence", help="a TUM-layout folder (rgb.txt, depth.txt, ...)")
    parser.add_argument("--output", default="trajectory.png", help="the plot (PNG)")
    parser.add_argument("--settings", help="a settings file (mcslam or ORB-SLAM2 keys)")
    parser.add_argument("--model", help="an ONNX detector for object boxes (YOLOv8/YOLO11, YOLOX)")
    parser.add_argument("--max-frames", type=int, default=0)
    args = parser.parse_args()

    try:
        sequence = mcslam.Sequence(args.sequence)
        options = {"model": args.model} if args.model else {}
        system = mcslam.run(sequence, args.settings, max_frames=args.max_frames, **options)
    except mcslam.InputError as e:
        sys.exit(f"run_and_plot: {e}")
    estimate = system.trajectory()
    groundtruth = sequence.groundtruth()
    print(f"{len(estimate)} of {len(sequence)} frames tracked; "
          f"map: {len(system.points())} points, {len(system.lines())} lines, "
          f"{len(system.planes())} planes")
    evaluation = None
    if groundtruth is not None and len(estimate) > 0:
        evaluation = mcslam.eval(groundtruth, estimate)
        print(f"ATE RMSE {evaluation['ate_rmse_m']:.4f} m over {evaluation['matched']} poses, "
              f"RPE (1 frame) {evaluation['rpe_frame_trans_rmse_m']:.4f} m")
    plot_trajectories(args.output, estimate, groundtruth, title=sequence.directory,
                      evaluation=evaluation)
    print(f"plot: {args.output}")


if __name__ == "__main__":
    main()
