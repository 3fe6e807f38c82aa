#!/usr/bin/env python3
"""How much of a trajectory's ATE a fixed offset between the ground truth's frame and the camera
explains, tested on data the offset was not fitted to.

A ground truth measured on a marker (a motion-capture body) gives the camera's pose only through
a hand-eye calibration. If that calibration misplaces the camera centre by a lever arm l (in the
camera's axes), every ground-truth position is off by R_i l, which turns with the camera: an error
no alignment of the whole trajectory removes and every estimate pays alike. This fits l together
with the rigid alignment (estimate ~ R_A (p_i + R_i l) + t_A, alternating the alignment and a
linear least-squares step for l and t_A) and, so that l cannot simply absorb the estimate's own
drift, cross-validates it: fitted on one half of the trajectory, applied to the other half (only
the alignment refitted there), and the other way round. A real calibration error lowers the ATE
of the half it was not fitted on; drift fitted as an offset does not carry over.

Usage: scripts/camera_offset.py [--bonn] [--frames K,K,...] GROUNDTRUTH.txt TRAJECTORY.txt [...]
  --bonn: the ground truth is Bonn RGB-D Dynamic's marker poses (converted to the camera as
          `mcslam eval --bonn` does).
  --frames: also print, at these poses (0-based, in the trajectory's order), the position error
          (mm) and the rotation error (mrad) in the camera's axes, with the whole run's lever arm
          and alignment: where an error appears, and whether a turn and a sideways shift came
          together (the pair that moves nearby points alike).
Prints per trajectory: the ATE (rigid alignment), the lever arm fitted on the whole, the ATE with
it, and per half the held-out ATE without and with the other half's lever arm (mm).
"""
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import pose_noise as pn  # noqa: E402  (the loaders, interpolation and alignment)


def rms(e):
    return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))


def aligned(X, P, Rs, lever):
    """The ground truth's positions moved by the lever arm (Q), and the rigid alignment R, t with
    X ~ R Q + t."""
    Q = P + np.einsum('nij,j->ni', Rs, lever)
    R, t = pn.align(Q, X)
    return Q, R, t


def fit(X, P, Rs, lever=None, iterations=30):
    """Aligns ground-truth positions P (rotations Rs, camera to world) moved by a lever arm to
    the estimate's X. lever None: the lever arm is fitted too. Returns (ATE in m, lever arm)."""
    l = np.zeros(3) if lever is None else np.asarray(lever, dtype=float)
    for _ in range(iterations):
        _, R, _ = aligned(X, P, Rs, l)
        if lever is not None:
            break
        # X - R P = t + (R R_i) l: linear in [t; l].
        A = np.zeros((3 * len(X), 6))
        A[:, :3] = np.tile(np.eye(3), (len(X), 1))
        A[:, 3:] = np.einsum('ij,njk->nik', R, Rs).reshape(-1, 3)
        b = (X - P @ R.T).reshape(-1)
        step = np.linalg.lstsq(A, b, rcond=None)[0]
        if np.linalg.norm(step[3:] - l) < 1e-7:
            l = step[3:]
            break
        l = step[3:]
    Q, R, t = aligned(X, P, Rs, l)
    return rms(X - (Q @ R.T + t)), l


def pairs(gt, estimate, rows=None):
    """The estimate's positions and the ground truth interpolated at their stamps; with a list
    `rows`, the indices of the estimate's poses kept are appended to it."""
    stamps, positions, quats = gt
    X, P, Rs = [], [], []
    for k, row in enumerate(estimate):
        g = pn.interpolate(stamps, positions, quats, row[0])
        if g is not None:
            X.append(row[1:4])
            P.append(g[0])
            Rs.append(g[1])
            if rows is not None:
                rows.append(k)
    return np.array(X), np.array(P), np.array(Rs)


def frame_errors(X, P, Rs, Re, lever):
    """Per pose, the position error (m) and the rotation error (rad, axis-angle) of the estimate
    (positions X, rotations Re, camera to world) in the camera's axes, after the rigid alignment
    of the ground truth moved by the lever arm: the error of estimate i is
    (R_A R_i)^T (x_i - R_A q_i - t_A) and log((R_A R_i)^T Re_i)."""
    Q, R, t = aligned(X, P, Rs, lever)
    axes = np.einsum('ij,njk->nik', R, Rs)
    position = np.einsum('nji,nj->ni', axes, X - (Q @ R.T + t))
    rotation = np.array([pn.rotation_log(a.T @ r) for a, r in zip(axes, Re)])
    return position, rotation


def analyse(X, P, Rs):
    """The figures the script prints, in metres: ATE, lever, ATE with it, and per held-out half
    (ATE without, with the other half's lever, that lever)."""
    ate, _ = fit(X, P, Rs, lever=np.zeros(3))
    ate_lever, lever = fit(X, P, Rs)
    half = len(X) // 2
    halves = [slice(0, half), slice(half, len(X))]
    held_out = []
    for fitted, other in [(halves[0], halves[1]), (halves[1], halves[0])]:
        _, l = fit(X[fitted], P[fitted], Rs[fitted])
        without, _ = fit(X[other], P[other], Rs[other], lever=np.zeros(3))
        with_lever, _ = fit(X[other], P[other], Rs[other], lever=l)
        held_out.append((without, with_lever, l))
    return ate, lever, ate_lever, held_out


def load_ground_truth(path, bonn):
    raw = pn.load(path)
    if bonn:
        converted = pn.bonn_to_camera(raw)
        return (np.array([c[0] for c in converted]), np.array([c[1] for c in converted]),
                np.array([pn.matrix_quat(c[2]) for c in converted]))
    return raw[:, 0], raw[:, 1:4], raw[:, 4:8]


def parse(argv):
    """(bonn, frames or None, the rest); raises ValueError on a bad --frames."""
    bonn = '--bonn' in argv
    args = [a for a in argv if a != '--bonn']
    frames = None
    if '--frames' in args:
        at = args.index('--frames')
        if at + 1 >= len(args):
            raise ValueError('--frames needs a list of pose indices')
        try:
            frames = [int(k) for k in args[at + 1].split(',')]
        except ValueError:
            raise ValueError(f'--frames {args[at + 1]}: not a list of integers') from None
        if any(k < 0 for k in frames):
            raise ValueError(f'--frames {args[at + 1]}: indices start at 0')
        del args[at:at + 2]
    return bonn, frames, args


def print_frames(path, estimate, rows, X, P, Rs, lever, frames):
    Re = np.array([pn.quat_matrix(estimate[k, 4:8]) for k in rows])
    position, rotation = frame_errors(X, P, Rs, Re, lever)
    where = {k: i for i, k in enumerate(rows)}
    xyz = lambda v, scale: ' '.join(f'{scale * x:+6.1f}' for x in v)  # noqa: E731
    for k in frames:
        if k not in where:
            print(f'  pose {k}: not within the ground truth' if k < len(estimate)
                  else f'  pose {k}: beyond the {len(estimate)} poses of {path}')
            continue
        i = where[k]
        print(f'  pose {k} (t {estimate[k, 0]:.3f}): position error ({xyz(position[i], 1000)}) mm,'
              f' rotation error ({xyz(rotation[i], 1000)}) mrad, camera axes')


def main(argv):
    try:
        bonn, frames, args = parse(argv)
    except ValueError as e:
        print(f'camera_offset.py: {e}', file=sys.stderr)
        return 2
    if len(args) < 2:
        print(__doc__.strip().split('\n\n')[-2], file=sys.stderr)
        return 2
    try:
        gt = load_ground_truth(args[0], bonn)
    except (OSError, ValueError, IndexError) as e:
        print(f'camera_offset.py: {args[0]}: cannot read the ground truth ({e})', file=sys.stderr)
        return 1
    for path in args[1:]:
        rows = []
        try:
            estimate = pn.load(path)
            X, P, Rs = pairs(gt, estimate, rows)
        except (OSError, ValueError, IndexError) as e:
            print(f'camera_offset.py: {path}: cannot read the trajectory ({e})', file=sys.stderr)
            return 1
        if len(X) < 20:
            print(f'camera_offset.py: {path}: {len(X)} poses within the ground truth, need 20',
                  file=sys.stderr)
            return 1
        ate, lever, ate_lever, held_out = analyse(X, P, Rs)
        mm = lambda v: ' '.join(f'{1000 * x:+.0f}' for x in v)  # noqa: E731
        print(f'{path}: ATE {1000 * ate:.1f} mm; lever arm ({mm(lever)}) mm -> {1000 * ate_lever:.1f}'
              f' mm; held-out halves: ' + ', '.join(
                  f'{1000 * w:.1f} -> {1000 * l:.1f} mm (lever {mm(v)})' for w, l, v in held_out))
        if frames:
            print_frames(path, estimate, rows, X, P, Rs, lever, frames)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
