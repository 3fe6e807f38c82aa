#!/usr/bin/env python3
"""Where in a run the online pose's error is, against the final trajectory's.

`trajectory_online.txt` holds each pose as the map gave it at the time; `trajectory.txt` the
same frames re-expressed in the map at the end of the run. Their difference is what the map
learnt after each frame (local bundle adjustment with later keyframes, loops, the final
adjustment and smoothing), which no causal filter of the online pose can have. This prints,
per window of the run, both trajectories' RMS position error against the ground truth (each
with its own rigid alignment of the whole run, as its ATE has) and the window's share of the
online ATE's sum of squares: a window where the online error is high and the final low is one
where the map at the time was off and was corrected later.

Usage: scripts/online_error.py [--bonn] [--window SECONDS] GROUNDTRUTH.txt RUN [RUN ...]
  RUN: an output folder of `mcslam run` (trajectory_online.txt and trajectory.txt in it).
  --bonn: the ground truth is Bonn RGB-D Dynamic's marker poses (converted to the camera as
          `mcslam eval --bonn` does).
  --window: the windows' length (default 2 s).
With several runs, each figure is the median over the runs (the windows follow the first run's
frames). The ground truth is interpolated at the estimate's stamps, so the ATE can differ from
`mcslam eval`'s (nearest stamp) by a few tenths of a millimetre.
"""
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import camera_offset as co  # noqa: E402  (the ground truth's loader, pairing with stamps)
import pose_noise as pn  # noqa: E402  (the trajectory loader and alignment)


def position_errors(gt, trajectory):
    """Stamps of the poses within the ground truth and their position errors (m, n x 3) after
    the rigid alignment of the whole trajectory."""
    stamps = []
    for row in trajectory:
        if pn.interpolate(gt[0], gt[1], gt[2], row[0]) is not None:
            stamps.append(row[0])
    X, P, _ = co.pairs(gt, trajectory)
    if len(X) < 3:
        raise ValueError(f'{len(X)} poses within the ground truth, need 3')
    R, t = pn.align(P, X)
    return np.array(stamps), X - (P @ R.T + t)


def windows(stamps, length):
    """[start, end) index ranges of consecutive windows of `length` seconds."""
    out, start = [], 0
    for i in range(1, len(stamps) + 1):
        if i == len(stamps) or stamps[i] - stamps[start] >= length:
            out.append((start, i))
            start = i
    return out


def rms(e):
    return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1)))) if len(e) else float('nan')


def analyse(gt, online, final, length):
    """Per window of the online trajectory: (first stamp, last stamp, frames, online RMS, final
    RMS, share of the online ATE's sum of squares); and both ATEs. Metres."""
    t_on, e_on = position_errors(gt, online)
    t_fi, e_fi = position_errors(gt, final)
    total = float(np.sum(e_on ** 2))
    rows = []
    for a, b in windows(t_on, length):
        in_final = (t_fi >= t_on[a] - 1e-6) & (t_fi <= t_on[b - 1] + 1e-6)
        rows.append((t_on[a], t_on[b - 1], b - a, rms(e_on[a:b]), rms(e_fi[in_final]),
                     float(np.sum(e_on[a:b] ** 2)) / total if total > 0 else 0.0))
    return rows, rms(e_on), rms(e_fi)


def main(argv):
    args = list(argv)
    bonn = '--bonn' in args
    if bonn:
        args.remove('--bonn')
    length = 2.0
    if '--window' in args:
        i = args.index('--window')
        try:
            length = float(args[i + 1])
            del args[i:i + 2]
        except (IndexError, ValueError):
            print('online_error.py: --window needs a number of seconds', file=sys.stderr)
            return 2
        if not length > 0:
            print('online_error.py: --window must be positive', file=sys.stderr)
            return 2
    if len(args) < 2:
        print(__doc__.strip().split('\n\n')[1], file=sys.stderr)
        return 2
    try:
        gt = co.load_ground_truth(args[0], bonn)
    except (OSError, ValueError, IndexError) as e:
        print(f'online_error.py: {args[0]}: cannot read the ground truth ({e})', file=sys.stderr)
        return 1
    results = []
    for run in args[1:]:
        files = [pathlib.Path(run) / name for name in ('trajectory_online.txt', 'trajectory.txt')]
        try:
            online, final = (pn.load(f) for f in files)
            results.append(analyse(gt, online, final, length))
        except (OSError, ValueError, IndexError) as e:
            print(f'online_error.py: {run}: cannot score the run ({e})', file=sys.stderr)
            return 1
    first = results[0][0]
    t0 = first[0][0]
    print(f'{"seconds":>13} {"poses":>9} {"online mm":>10} {"final mm":>9} {"share":>6}')
    frame = 0
    for k, row in enumerate(first):
        per_run = [r[0][k] for r in results if k < len(r[0])]
        med = lambda j: float(np.median([r[j] for r in per_run]))  # noqa: E731
        print(f'{row[0] - t0:6.1f}-{row[1] - t0:6.1f} {frame:4d}-{frame + row[2] - 1:4d} '
              f'{1000 * med(3):10.1f} {1000 * med(4):9.1f} {100 * med(5):5.0f}%')
        frame += row[2]
    print(f'ATE (median of {len(results)}): online {1000 * np.median([r[1] for r in results]):.1f}'
          f' mm, final {1000 * np.median([r[2] for r in results]):.1f} mm')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
