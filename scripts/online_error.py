#!/usr/bin/env python3
"""Where in a run the online pose's error is, against the final trajectory's.

`trajectory_online.txt` holds each pose as the map gave it at the time; `trajectory.txt` the
same frames re-expressed in the map at the end of the run. Their difference is what the map
learnt after each frame (local bundle adjustment with later keyframes, loops, the final
adjustment and smoothing), which no causal filter of the online pose can have. This prints,
per window of the run, both trajectories' RMS position error against the ground truth (each
with its own rigid alignment of the whole run, as its ATE has) and the window's share of the
online ATE's sum of squares: a window where the online error is high and the final low is one
where the map at the time was off and was corrected later. A last column smooths the online
positions with every frame before and after them, with the model `trajectory.txt`'s smoothing
uses (white-noise acceleration, 0.01 m^2/s^3, the positions' noise measured from their second
differences; optim/trajectory_smoothing.hpp): not causal, so no filter or fixed lag of that model
can leave less error on these poses; what it leaves is the error of the map they were solved
against at the time.

Usage: scripts/online_error.py [--bonn] [--window SECONDS] [--noise MM] GROUNDTRUTH.txt RUN...
  RUN: an output folder of `mcslam run` (trajectory_online.txt and trajectory.txt in it).
  --bonn: the ground truth is Bonn RGB-D Dynamic's marker poses (converted to the camera as
          `mcslam eval --bonn` does).
  --window: the windows' length (default 2 s).
  --noise: the online positions' noise the smoothing assumes, per axis (default: measured from
           their second differences, as `trajectory.txt`'s smoothing measures it); a larger
           noise smooths more.
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


def solve_banded(a0, a1, a2, rhs):
    """Solves A x = rhs for a symmetric positive definite A with two bands off the diagonal
    (a0[i] = A[i, i], a1[i] = A[i, i + 1], a2[i] = A[i, i + 2]) by its banded Cholesky factor:
    linear in the number of poses."""
    n = len(a0)
    d, l1, l2 = np.zeros(n), np.zeros(n), np.zeros(n)  # L[i, i], L[i + 1, i], L[i + 2, i]
    for i in range(n):
        v = a0[i] - (l1[i - 1] ** 2 if i >= 1 else 0.0) - (l2[i - 2] ** 2 if i >= 2 else 0.0)
        d[i] = np.sqrt(v)
        if i + 1 < n:
            l1[i] = (a1[i] - (l2[i - 1] * l1[i - 1] if i >= 1 else 0.0)) / d[i]
        if i + 2 < n:
            l2[i] = a2[i] / d[i]
    y = np.array(rhs, dtype=float)
    for i in range(n):
        if i >= 1:
            y[i] -= l1[i - 1] * y[i - 1]
        if i >= 2:
            y[i] -= l2[i - 2] * y[i - 2]
        y[i] /= d[i]
    for i in range(n - 1, -1, -1):
        if i + 1 < n:
            y[i] -= l1[i] * y[i + 1]
        if i + 2 < n:
            y[i] -= l2[i] * y[i + 2]
        y[i] /= d[i]
    return y


def smooth_positions(stamps, positions, q=0.01, outlier_sigmas=3.0, iterations=5, sigma=None,
                     max_gap=1.0):
    """The positions (n x 3) smoothed as optim/trajectory_smoothing.cpp smooths them: least
    squares of the positions against a white-noise-acceleration prior (density q) on their
    second differences, the noise sigma from the second differences' median absolute deviation
    less the motion's part (unless sigma is given, metres), poses beyond outlier_sigmas sigma
    down-weighted, the path cut where no pose came for max_gap seconds."""
    stamps = np.asarray(stamps, dtype=float)
    cuts = [0] + [i for i in range(1, len(stamps)) if stamps[i] - stamps[i - 1] > max_gap]
    segments = [(a, b) for a, b in zip(cuts, cuts[1:] + [len(stamps)]) if b - a >= 3]
    ops = []
    for a, b in segments:
        before = 1.0 / np.diff(stamps[a:b])[:-1]
        after = 1.0 / np.diff(stamps[a:b])[1:]
        coeffs = np.column_stack([before, -(before + after), after])
        ops.append((a, b, coeffs, 0.5 * (1.0 / before + 1.0 / after),
                    np.sum(coeffs ** 2, axis=1)))
    if sum(len(op[3]) for op in ops) < 10:  # as kMinSecondDifferences
        return positions.copy()
    if sigma is None:
        normalised, motion = [], []
        for a, b, c, mean_dt, gain2 in ops:
            x = positions[a:b]
            dv = c[:, :1] * x[:-2] + c[:, 1:2] * x[1:-1] + c[:, 2:] * x[2:]
            normalised.append((np.abs(dv) / np.sqrt(gain2)[:, None]).ravel())
            motion.append(q * mean_dt / gain2)
        spread = 1.4826 * np.median(np.concatenate(normalised))
        sigma = np.sqrt(max(spread ** 2 - np.median(np.concatenate(motion)), 1e-8))
    out = positions.copy()
    for a, b, c, mean_dt, _ in ops:
        n, y = b - a, positions[a:b]
        prior = 1.0 / (q * mean_dt)
        m0, m1, m2 = np.zeros(n), np.zeros(n), np.zeros(n)  # the prior's bands
        for r in range(3):
            np.add.at(m0, np.arange(n - 2) + r, prior * c[:, r] ** 2)
        for r in range(2):
            np.add.at(m1, np.arange(n - 2) + r, prior * c[:, r] * c[:, r + 1])
        np.add.at(m2, np.arange(n - 2), prior * c[:, 0] * c[:, 2])
        weights = np.ones(n)
        for _ in range(iterations):
            w = weights / sigma ** 2
            smoothed = solve_banded(m0 + w, m1, m2, w[:, None] * y)
            r = np.linalg.norm(smoothed - y, axis=1)
            new = np.where(r <= outlier_sigmas * sigma, 1.0,
                           outlier_sigmas * sigma / np.maximum(r, 1e-12))
            if np.max(np.abs(new - weights)) <= 1e-3:
                break
            weights = new
        out[a:b] = smoothed
    return out


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


def analyse(gt, online, final, length, noise=None):
    """Per window of the online trajectory: (first stamp, last stamp, frames, online RMS, final
    RMS, share of the online ATE's sum of squares, smoothed online RMS); and the three ATEs
    (online, final, smoothed online). Metres."""
    t_on, e_on = position_errors(gt, online)
    t_fi, e_fi = position_errors(gt, final)
    smoothed = online.copy()
    smoothed[:, 1:4] = smooth_positions(online[:, 0], online[:, 1:4], sigma=noise)
    _, e_sm = position_errors(gt, smoothed)
    total = float(np.sum(e_on ** 2))
    rows = []
    for a, b in windows(t_on, length):
        in_final = (t_fi >= t_on[a] - 1e-6) & (t_fi <= t_on[b - 1] + 1e-6)
        rows.append((t_on[a], t_on[b - 1], b - a, rms(e_on[a:b]), rms(e_fi[in_final]),
                     float(np.sum(e_on[a:b] ** 2)) / total if total > 0 else 0.0,
                     rms(e_sm[a:b])))
    return rows, rms(e_on), rms(e_fi), rms(e_sm)


def take_positive(args, flag, what, default):
    """Removes `flag VALUE` from args and returns VALUE, which must be a positive number (the
    default without the flag); ValueError names the flag."""
    if flag not in args:
        return default
    i = args.index(flag)
    try:
        value = float(args[i + 1])
    except (IndexError, ValueError):
        raise ValueError(f'{flag} needs {what}') from None
    if not value > 0:
        raise ValueError(f'{flag} must be positive')
    del args[i:i + 2]
    return value


def main(argv):
    args = list(argv)
    bonn = '--bonn' in args
    if bonn:
        args.remove('--bonn')
    try:
        length = take_positive(args, '--window', 'a number of seconds', 2.0)
        noise = take_positive(args, '--noise', 'a number of millimetres', None)
    except ValueError as e:
        print(f'online_error.py: {e}', file=sys.stderr)
        return 2
    if noise is not None:
        noise /= 1000.0
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
            results.append(analyse(gt, online, final, length, noise))
        except (OSError, ValueError, IndexError) as e:
            print(f'online_error.py: {run}: cannot score the run ({e})', file=sys.stderr)
            return 1
    first = results[0][0]
    t0 = first[0][0]
    print(f'{"seconds":>13} {"poses":>9} {"online mm":>10} {"final mm":>9} {"share":>6} '
          f'{"online smoothed mm":>19}')
    frame = 0
    for k, row in enumerate(first):
        per_run = [r[0][k] for r in results if k < len(r[0])]
        med = lambda j: float(np.median([r[j] for r in per_run]))  # noqa: E731
        print(f'{row[0] - t0:6.1f}-{row[1] - t0:6.1f} {frame:4d}-{frame + row[2] - 1:4d} '
              f'{1000 * med(3):10.1f} {1000 * med(4):9.1f} {100 * med(5):5.0f}% '
              f'{1000 * med(6):19.1f}')
        frame += row[2]
    ate = lambda j: 1000 * float(np.median([r[j] for r in results]))  # noqa: E731
    print(f'ATE (median of {len(results)}): online {ate(1):.1f} mm, final {ate(2):.1f} mm, '
          f'online smoothed {ate(3):.1f} mm')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
