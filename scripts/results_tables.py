#!/usr/bin/env python3
"""Tables of scripts/results.sh: reads the run folders it made and writes docs/results.md and
the results table of README.md (between the `results:begin` and `results:end` markers), and
prints that table. Figures: median (min-max) over the runs of a threaded row; one run for a
sequential row (deterministic)."""
import argparse
import glob
import json
import os
import re
import statistics
import sys


def load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def values(xs):
    return [x for x in xs if x is not None]


def fig(xs, digits=4, scale=1.0):
    """Median (min-max) of the values, or the value alone, or '-'."""
    xs = [x * scale for x in values(xs)]
    if not xs:
        return "-"
    m = statistics.median(xs)
    if len(xs) == 1 or min(xs) == max(xs):
        return f"{m:.{digits}f}"
    return f"{m:.{digits}f} ({min(xs):.{digits}f}-{max(xs):.{digits}f})"


def median(xs):
    xs = values(xs)
    return statistics.median(xs) if xs else None


class Runs:
    """The runs of one row: their summaries and their trajectories' scores."""

    def __init__(self, pattern):
        self.dirs = sorted(d for d in glob.glob(pattern) if os.path.isdir(d))
        self.summaries = [load(os.path.join(d, "summary.json")) for d in self.dirs]
        self.traj = [load(os.path.join(d, "trajectory.eval.json")) for d in self.dirs]
        self.online = [load(os.path.join(d, "trajectory_online.eval.json")) for d in self.dirs]
        self.unsmoothed = [load(os.path.join(d, "trajectory_unsmoothed.eval.json"))
                           for d in self.dirs]

    def count(self):
        return len([s for s in self.summaries if s])

    def summary(self, *keys):
        out = []
        for s in self.summaries:
            for k in keys:
                s = s.get(k) if isinstance(s, dict) else None
            out.append(s)
        return out

    def ate(self):
        return [e.get("ate_rmse_m") if e else None for e in self.traj]

    def unsmoothed_ate(self):
        return [e.get("ate_rmse_m") if e else None for e in self.unsmoothed]

    def online_ate(self):
        return [e.get("ate_rmse_m") if e else None for e in self.online]

    def online_rpe(self):
        return [e.get("rpe_frame_trans_rmse_m") if e else None for e in self.online]

    def rpe(self):
        return [e.get("rpe_frame_trans_rmse_m") if e else None for e in self.traj]

    def tracking_ms(self):
        return self.summary("stages", "tracking_total", "median_ms")

    def fps(self):
        return self.summary("frames_per_second")

    def tracked(self):
        return self.summary("tracked_ratio")


def tracking_row(name, run, runs):
    return (f"| {name} | {run} | {runs.count()} | {fig(runs.ate())} | {fig(runs.unsmoothed_ate())} "
            f"| {fig(runs.online_ate())} "
            f"| {fig(runs.rpe(), 1, 1000)} | {fig(runs.online_rpe(), 1, 1000)} "
            f"| {fig(runs.tracked(), 1, 100)} | {fig(runs.fps(), 1)} | {fig(runs.tracking_ms(), 1)} |")


def section_tracking(out):
    rows = {
        "rpy_seq": Runs(f"{out}/runs/rpy-sequential-*"),
        "rpy_det": Runs(f"{out}/runs/rpy-detector-*"),
        "rpy_geo": Runs(f"{out}/runs/rpy-geometry-*"),
        "rpy_pts": Runs(f"{out}/runs/rpy-points-*"),
        "bonn_seq": Runs(f"{out}/runs/bonn-sequential-*"),
        "bonn": Runs(f"{out}/crowd/runs/default-*"),
        "cold": Runs(f"{out}/crowd/runs/cold-*"),
        "realtime": Runs(f"{out}/crowd/runs/realtime-*"),
        "bonn_geo": Runs(f"{out}/crowd/runs/no-detector-*"),
    }
    lines = [
        "| sequence | run | runs | ATE `trajectory.txt` (m) | ATE `trajectory_unsmoothed.txt` (m) "
        "| ATE `trajectory_online.txt` (m) "
        "| RPE 1 frame, `trajectory.txt` (mm) | RPE 1 frame, online (mm) | tracked % | fps "
        "| tracking ms (median) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    rpy, part1 = "freiburg1_rpy", "Bonn crowd part1"
    spec = [
        (rpy, "yolov8n_320, `--sequential`", "rpy_seq"),
        (rpy, "yolov8n_320, threaded", "rpy_det"),
        (rpy, "no detector, threaded", "rpy_geo"),
        (rpy, "no detector, `--features points`, threaded", "rpy_pts"),
        (part1, "yolov8n_320, `--sequential`", "bonn_seq"),
        (part1, "yolov8n_320, threaded", "bonn"),
        (part1, "yolov8n_320, threaded, `--first-frame 240`", "cold"),
        (part1, "yolov8n_320, `--realtime`", "realtime"),
        (part1, "no detector, threaded", "bonn_geo"),
    ]
    for seq, run, key in spec:
        lines.append(tracking_row(seq, run, rows[key]))
    rt = rows["realtime"]
    processed = [r.get("processed_ratio") if r else None for r in rt.summary("realtime")]
    latency = [r.get("latency_p95_ms") if r else None for r in rt.summary("realtime")]
    geo, pts = median(rows["rpy_geo"].tracking_ms()), median(rows["rpy_pts"].tracking_ms())
    ratio = f"{geo / pts:.2f}x" if geo and pts else "-"
    text = "\n".join(lines) + "\n\n"
    text += (f"`--realtime` (frames delivered at their timestamps, dropped when late; ATE over the "
             f"frames processed): {fig(processed, 1, 100)} % of the frames processed, latency "
             f"p95 {fig(latency, 0)} ms. On freiburg1_rpy without a detector, all three feature "
             f"kinds (points, lines, planes) cost {ratio} the tracking time of points alone.\n")
    return text, rows, (processed, latency, ratio)


def section_synthetic_crowd(out):
    rows = {
        "room": Runs(f"{out}/runs/synth-room"),
        "undetected": Runs(f"{out}/runs/synth-undetected"),
        "no_established": Runs(f"{out}/runs/synth-undetected-no-established"),
        "crowd4": Runs(f"{out}/runs/synth-crowd4"),
    }
    spec = [
        ("the room, no people (a chair slides)", "room"),
        ("3 people, the third without a box (fills up to 45 % of the view)", "undetected"),
        ("the same, `tracker.established_age: 0` (every observation at once)", "no_established"),
        ("4 people, the fourth without a box", "crowd4"),
    ]
    room = median(rows["room"].ate())
    lines = ["| scene | ATE `trajectory.txt` (m) | x the room | ATE online (m) "
             "| RPE 1 frame, online (mm) | frames with a mover found without a box |",
             "|---|---|---|---|---|---|"]
    for name, key in spec:
        r = rows[key]
        ate = median(r.ate())
        times = f"{ate / room:.2f}" if ate and room else "-"
        movers = fig(r.summary("dynamics", "mover_frames"), 0)
        lines.append(f"| {name} | {fig(r.ate())} | {times} | {fig(r.online_ate())} "
                     f"| {fig(r.online_rpe(), 1, 1000)} | {movers} |")
    return "\n".join(lines) + "\n", rows


def dynamic_scenes(out):
    """ATE of the four dynamic rooms: geometry only and the full system."""
    ate = {"geometry": [], "full": []}
    for d in sorted(glob.glob(f"{out}/dynamic/runs/dyn_*")):
        for config in ate:
            s = load(os.path.join(d, f"{config}-1", "summary.json"))
            ate[config].append(s.get("ate_rmse_m") if s else None)
    return ate


def read(path):
    try:
        with open(path) as f:
            return f.read().strip() + "\n"
    except OSError:
        return "(not measured)\n"


def span(xs, digits=4):
    xs = values(xs)
    if not xs:
        return "-"
    return f"{min(xs):.{digits}f}-{max(xs):.{digits}f}"


def readme_table(rows, crowd, realtime, dyn, ref):
    processed, latency, ratio = realtime
    r = rows
    def ate2(runs):
        return (f"{fig([median(runs.ate())])} ({fig([median(runs.unsmoothed_ate())])}) / "
                f"{fig([median(runs.online_ate())])}")
    room, und = median(crowd["room"].ate()), median(crowd["undetected"].ate())
    times = f" ({und / room:.1f}x the room without people)" if und and room else ""
    lines = [
        "| sequence | run | ATE m: `trajectory.txt` (unsmoothed) / online | speed |",
        "|---|---|---|---|",
        f"| TUM freiburg1_rpy (694 frames, static) | yolov8n_320, sequential (deterministic) "
        f"| {ate2(r['rpy_seq'])} | |",
        f"| TUM freiburg1_rpy | yolov8n_320, threaded | {ate2(r['rpy_det'])} "
        f"| **{fig([ref], 1)} fps** (the machine's reference speed) |",
        f"| TUM freiburg1_rpy | no detector, threaded | {ate2(r['rpy_geo'])} "
        f"| {fig([median(r['rpy_geo'].fps())], 1)} fps; all features {ratio} points only |",
        f"| Bonn crowd part1 (460 frames, people from frame ~240) | yolov8n_320, threaded "
        f"| {ate2(r['bonn'])} | {fig([median(r['bonn'].fps())], 1)} fps |",
        f"| Bonn crowd part1 from frame 240 (people from the first frame) | the same, "
        f"`--first-frame 240` | {ate2(r['cold'])} | {fig([median(r['cold'].fps())], 1)} fps |",
        f"| Bonn crowd part1 | the same, `--realtime` | {ate2(r['realtime'])} "
        f"| {fig([median(processed)], 1, 100)} % of frames processed, latency p95 "
        f"{fig([median(latency)], 0)} ms |",
        f"| Bonn crowd part1 | no detector (geometry only), threaded | {ate2(r['bonn_geo'])} "
        f"| {fig([median(r['bonn_geo'].fps())], 1)} fps |",
        f"| synthetic room, 3 people, one without a box | ground-truth boxes, sequential "
        f"| {ate2(crowd['undetected'])}{times} | |",
        f"| four synthetic rooms, a person walking and a chair sliding | ground-truth boxes, "
        f"sequential | {span(dyn['full'])} (geometry only: {span(dyn['geometry'])}) | |",
    ]
    return "\n".join(lines) + "\n"


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--output", required=True)
    p.add_argument("--runs", type=int, required=True)
    p.add_argument("--seconds", type=int, required=True)
    p.add_argument("--docs", required=True)
    p.add_argument("--readme", default="")
    p.add_argument("--max-frames", type=int, default=0)
    p.add_argument("--machine", default="")
    a = p.parse_args()
    out = a.output
    tracking, rows, realtime = section_tracking(out)
    crowd_text, crowd = section_synthetic_crowd(out)
    ref_runs = rows["rpy_det"].fps()
    ref = median(ref_runs)
    dyn = dynamic_scenes(out)
    cut = f" (every real run cut to {a.max_frames} frames: a check of the script)" if a.max_frames else ""
    doc = f"""# Results

<!-- Generated by scripts/results.sh: do not edit; run it again. -->

Generated by `scripts/results.sh` (`flock /tmp/mcslam-build.lock scripts/results.sh`, or
`scripts/results.sh` alone on a machine nobody shares), which builds mcslam, runs everything
below and writes this page and the table in the [README](../README.md); {a.seconds // 60} min
{a.seconds % 60} s on this machine ({a.machine}){cut}. Every figure on this page comes from that
one run of the script, on the source tree this file is part of. Threaded and
real-time runs differ from run to run: {a.runs} runs each, median (min-max). Sequential runs
are deterministic: one run each. How each tool measures: [benchmarks.md](benchmarks.md).

**The machine's reference speed: freiburg1_rpy with yolov8n_320, threaded:
{fig(ref_runs, 1)} fps.** Speeds differ by up to 2x between machines and between hours of a
shared machine; compare speeds against this figure.

ATE is the RMSE of the absolute trajectory error after a rigid alignment (`mcslam eval`, as
TUM's tools; Bonn with its marker-to-camera transform, `--bonn`), of `trajectory.txt` (the
final trajectory: each frame placed on its bundle-adjusted keyframe, positions smoothed with a
motion prior; `trajectory_unsmoothed.txt` is the same before the smoothing, what comparisons to
other systems are against) and of `trajectory_online.txt` (each pose as `process()` returned
it: what a robot steers by). RPE 1
frame is the RMSE of the translation error between consecutive frames: the online pose's noise.

## Tracking

Data: `../shared/data/tum/rgbd_dataset_freiburg1_rpy` (694 frames, a static desk),
`../shared/data/bonn/rgbd_bonn_crowd_part1` (460 frames; three people walk in from frame ~240),
detector `../shared/models/yolov8n_320.onnx`.

{tracking}
## The object pipeline on Bonn crowd part1

`scripts/bench_crowd.sh --variants ...`: each variant takes one part of the object pipeline
away ([crowd.md](crowd.md) says what each part does); ATE of `trajectory.txt`, and of its
frames before and after the people enter (each aligned on its own).

{read(f"{out}/crowd/table.md")}
## Dynamic synthetic scenes

`scripts/bench_dynamic.sh --no-real`: four rooms of 300 frames (Kinect-like depth noise) with
a person moving freely and a chair sliding on the floor (seeds, speeds and sizes vary);
ground-truth boxes, sequential. `geometry`: no boxes; `alg1`: dynamic objects left out;
`full`: and the moving constraints (9), (10). Rates count the frames where the object moves
(static objects: every frame where seen); in brackets the frames counted.

{read(f"{out}/dynamic/table.md")}
## Synthetic crowd

`mcslam synth --frames 300 --seed 1 --depth-noise --dynamic` with `--no-person`, with
`--people 3 --undetected-people 1` and with `--people 4 --undetected-people 1`; `mcslam run
--sequential --detections DIR/detections.json` (the people with a box get their ground-truth
box; the one without is found, if at all, as a region of motion).

{crowd_text}
## The navigation map

`scripts/bench_mapping.sh` ([mapping.md](mapping.md)): the occupancy map's ghost rate
(occupied voxels off every static surface) and completeness on synthetic rooms, with the masks
and without (`mapping.use_masks: false`); on Bonn crowd part1, the cells FULL (the whole of
part1) has occupied where REF (its first 240 frames, nobody in view) saw free space.

{read(f"{out}/mapping/table.md")}"""
    doc = re.sub(r"\n{3,}", "\n\n", doc)
    with open(a.docs, "w") as f:
        f.write(doc)
    table = readme_table(rows, crowd, realtime, dyn, ref)
    if a.readme:
        with open(a.readme) as f:
            text = f.read()
        begin, end = "<!-- results:begin -->\n", "<!-- results:end -->"
        i, j = text.find(begin), text.find(end)
        if i < 0 or j < i:
            sys.exit(f"results: {a.readme} has no {begin.strip()} ... {end} markers")
        with open(a.readme, "w") as f:
            f.write(text[: i + len(begin)] + table + text[j:])
    print(table)


if __name__ == "__main__":
    main()
