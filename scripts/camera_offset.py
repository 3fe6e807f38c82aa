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

Usage: scripts/camera_offset.py [--bonn] GROUNDTRUTH.txt TRAJECTORY.txt [TRAJECTORY.txt ...]
  --bonn: the ground truth is Bonn RGB-D Dynamic's marker poses (converted to the camera as
          `mcslam eval --bonn` does).
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


def fit(X, P, Rs, lever=None, iterations=30):
    """Aligns ground-truth positions P (rotations Rs, camera to world) moved by a lever arm to
    the estimate's X. lever None: the lever arm is fitted too. Returns (ATE in m, lever arm)."""
    l = np.zeros(3) if lever is None else np.asarray(lever, dtype=float)
    for _ in range(iterations):
        Q = P + np.einsum('nij,j->ni', Rs, l)
        R, t = pn.align(Q, X)
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
    Q = P + np.einsum('nij,j->ni', Rs, l)
    R, t = pn.align(Q, X)
    return rms(X - (Q @ R.T + t)), l


def pairs(gt, estimate):
    """The estimate's positions and the ground truth interpolated at their stamps."""
    stamps, positions, quats = gt
    X, P, Rs = [], [], []
    for row in estimate:
        g = pn.interpolate(stamps, positions, quats, row[0])
        if g is not None:
            X.append(row[1:4])
            P.append(g[0])
            Rs.append(g[1])
    return np.array(X), np.array(P), np.array(Rs)


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


def main(argv):
    bonn = '--bonn' in argv
    args = [a for a in argv if a != '--bonn']
    if len(args) < 2:
        print(__doc__.strip().split('\n\n')[-2], file=sys.stderr)
        return 2
    try:
        gt = load_ground_truth(args[0], bonn)
    except (OSError, ValueError, IndexError) as e:
        print(f'camera_offset.py: {args[0]}: cannot read the ground truth ({e})', file=sys.stderr)
        return 1
    for path in args[1:]:
        try:
            X, P, Rs = pairs(gt, pn.load(path))
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
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
