#!/usr/bin/env python3
"""The frame-to-frame error of estimated trajectories, against ground truth.

For each pair of consecutive estimated poses (i, i+1), the relative pose error over one frame
(evo's E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)), its translation and rotation per axis of camera i,
with the ground truth interpolated at the estimate's timestamps (linear positions, slerp
rotations; not associated to the nearest stamp, whose 5 ms offsets at 100 Hz would add
~0.3 deg of the camera's own turn to every pair); the second differences of the positions
(p[k+1] - 2 p[k] + p[k-1]) of the estimate and of the ground truth; ATE after a rigid
alignment; and how much of the translation error a rotation error explains (least-squares fit
te = M re: the columns of M are lever arms in metres, a pose loose along the direction where a
small turn and a sideways shift move the image alike). Without the ground truth: each pose's own
jitter, its position and rotation against the midpoint of its two neighbours (camera axes), and
the same fit of the position jitter to the rotation jitter, which the ground truth's own rotation
noise does not enter (the rotations' second differences are printed for both).

Writes OUT.noise beside each estimate: timestamp, translation error x y z (mm), rotation
error x y z (deg), per pair.

Usage: scripts/pose_noise.py [--bonn] GROUNDTRUTH.txt TRAJECTORY.txt [TRAJECTORY.txt ...]
  --bonn: the ground truth is Bonn RGB-D Dynamic's marker poses (converted to the camera as
          `mcslam eval --bonn` does).
"""
import sys

import numpy as np


def load(path):
    rows = [[float(x) for x in line.split()[:8]] for line in open(path)
            if line.strip() and not line.startswith('#')]
    a = np.array(rows)
    return a[np.argsort(a[:, 0])]


def quat_matrix(q):  # x y z w
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def rotation_log(R):
    angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return v * (0.5 if angle < 1e-8 else angle / (2 * np.sin(angle)))


def slerp(q0, q1, s):
    if np.dot(q0, q1) < 0:
        q1 = -q1
    angle = np.arccos(np.clip(np.dot(q0, q1), -1, 1))
    if angle < 1e-9:
        return q0
    return (np.sin((1 - s) * angle) * q0 + np.sin(s * angle) * q1) / np.sin(angle)


def bonn_to_camera(gt):
    """Bonn's marker poses to the camera's: T_ros * T_marker * T_ros * T_m (eval/bonn.cpp)."""
    t_ros = np.array([[-1, 0, 0, 0], [0, 0, 1, 0], [0, 1, 0, 0], [0, 0, 0, 1.0]])
    t_m = np.array([[1.0157, 0.1828, -0.2389, 0.0113], [0.0009, -0.8431, -0.6413, -0.0098],
                    [-0.3009, 0.6147, -0.8085, 0.0111], [0, 0, 0, 1]])
    u, _, vt = np.linalg.svd(t_m[:3, :3])
    d = np.eye(3)
    d[2, 2] = np.sign(np.linalg.det(u @ vt))
    t_m[:3, :3] = u @ d @ vt
    out = []
    for r in gt:
        t = np.eye(4)
        t[:3, :3] = quat_matrix(r[4:8])
        t[:3, 3] = r[1:4]
        c = t_ros @ t @ t_ros @ t_m
        out.append((r[0], c[:3, 3], c[:3, :3]))
    return out


def interpolate(stamps, positions, quats, t):
    i = np.searchsorted(stamps, t)
    if i == 0 or i >= len(stamps) or stamps[i] - stamps[i - 1] > 0.05:
        return None
    s = (t - stamps[i - 1]) / (stamps[i] - stamps[i - 1])
    p = positions[i - 1] * (1 - s) + positions[i] * s
    return p, quat_matrix(slerp(quats[i - 1], quats[i], s))


def matrix_quat(R):
    w = np.sqrt(max(0.0, 1 + np.trace(R))) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + R[0, 0] - R[1, 1] - R[2, 2])) / 2, R[2, 1] - R[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - R[0, 0] + R[1, 1] - R[2, 2])) / 2, R[0, 2] - R[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - R[0, 0] - R[1, 1] + R[2, 2])) / 2, R[1, 0] - R[0, 1])
    return np.array([x, y, z, w])


def align(a, b):  # R, t with b ~ R a + t
    ma, mb = a.mean(0), b.mean(0)
    u, _, vt = np.linalg.svd((a - ma).T @ (b - mb))
    d = np.eye(3)
    d[2, 2] = np.sign(np.linalg.det(vt.T @ u.T))
    R = vt.T @ d @ u.T
    return R, mb - R @ ma


def rotation_exp(w):
    angle = np.linalg.norm(w)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    if angle < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + np.sin(angle) / angle * K + (1 - np.cos(angle)) / angle ** 2 * K @ K


def own_jitter(stamps, P, Rs):
    """Each inner pose against the midpoint of its neighbours (linear in time): position (m) and
    rotation (rad) jitter in the camera's axes."""
    dp, dw = [], []
    for k in range(1, len(P) - 1):
        f = (stamps[k] - stamps[k - 1]) / (stamps[k + 1] - stamps[k - 1])
        mid_p = P[k - 1] + f * (P[k + 1] - P[k - 1])
        mid_R = Rs[k - 1] @ rotation_exp(f * rotation_log(Rs[k - 1].T @ Rs[k + 1]))
        dp.append(Rs[k].T @ (P[k] - mid_p))
        dw.append(rotation_log(mid_R.T @ Rs[k]))
    return np.array(dp), np.array(dw)


def rotation_second_difference(Rs):
    steps = [rotation_log(a.T @ b) for a, b in zip(Rs, Rs[1:])]
    return np.sqrt(np.mean([np.sum((b - a) ** 2) for a, b in zip(steps, steps[1:])]))


def coupling(te, re):
    """Least-squares te = re @ M and the share of te it explains."""
    M = np.linalg.lstsq(re, te, rcond=None)[0]
    return M, 1 - np.sum((te - re @ M) ** 2) / np.sum(te ** 2)


def analyse(gt, path):
    stamps, positions, quats = gt
    est = load(path)
    rows = []
    for r in est:
        g = interpolate(stamps, positions, quats, r[0])
        if g is not None:
            rows.append((r[0], r[1:4], quat_matrix(r[4:8]), g[0], g[1]))
    if len(rows) < 3:
        sys.exit(f'pose_noise: {path}: fewer than 3 poses within the ground truth')
    P = np.array([x[1] for x in rows])
    G = np.array([x[3] for x in rows])
    R, t = align(P, G)
    ate = np.sqrt(np.mean(np.sum((G - (P @ R.T + t)) ** 2, 1)))
    te, re = [], []
    for (_, pi, Ri, gi, Qi), (_, pj, Rj, gj, Qj) in zip(rows, rows[1:]):
        dR_est, dt_est = Ri.T @ Rj, Ri.T @ (pj - pi)
        dR_gt, dt_gt = Qi.T @ Qj, Qi.T @ (gj - gi)
        te.append(dR_gt.T @ (dt_est - dt_gt))
        re.append(rotation_log(dR_gt.T @ dR_est))
    te, re = np.array(te), np.array(re)

    def second_difference(X):
        return np.sqrt(np.mean(np.sum((X[2:] - 2 * X[1:-1] + X[:-2]) ** 2, 1)))

    M, explained = coupling(te, re)
    rms = lambda X: np.sqrt(np.mean(np.sum(X ** 2, 1)))
    print(f'{path}')
    print(f'  ATE {ate * 1e3:.2f} mm; RPE over one frame: translation {rms(te) * 1e3:.2f} mm '
          f'(x y z {" ".join(f"{v:.2f}" for v in np.sqrt(np.mean(te ** 2, 0)) * 1e3)}), '
          f'rotation {np.degrees(rms(re)):.3f} deg '
          f'(x y z {" ".join(f"{v:.3f}" for v in np.degrees(np.sqrt(np.mean(re ** 2, 0))))})')
    print(f'  second differences of the positions: estimate {second_difference(P) * 1e3:.2f} mm, '
          f'ground truth {second_difference(G) * 1e3:.2f} mm')
    print(f'  translation error explained by the rotation error: {explained * 100:.0f} % '
          f'(lever arms, m: {" ".join(f"{v:.2f}" for v in M.T.flatten())})')
    est_R, gt_R = [x[2] for x in rows], [x[4] for x in rows]
    dp, dw = own_jitter(np.array([x[0] for x in rows]), P, est_R)
    Mj, explained_j = coupling(dp, dw)
    print(f'  own jitter (no ground truth): position x y z '
          f'{" ".join(f"{v:.2f}" for v in np.sqrt(np.mean(dp ** 2, 0)) * 1e3)} mm, rotation x y z '
          f'{" ".join(f"{v:.3f}" for v in np.degrees(np.sqrt(np.mean(dw ** 2, 0))))} deg; '
          f'{explained_j * 100:.0f} % of the position jitter follows the rotation jitter '
          f'(lever arms, m: {" ".join(f"{v:.2f}" for v in Mj.T.flatten())})')
    print(f'  second differences of the rotations: estimate '
          f'{np.degrees(rotation_second_difference(est_R)):.3f} deg, ground truth '
          f'{np.degrees(rotation_second_difference(gt_R)):.3f} deg')
    t_pairs = np.array([x[0] for x in rows[1:]])
    np.savetxt(path + '.noise', np.column_stack([t_pairs, te * 1e3, np.degrees(re)]),
               fmt='%.6f', header='timestamp te_x te_y te_z (mm) re_x re_y re_z (deg), camera i')


def main(argv):
    bonn = '--bonn' in argv
    args = [a for a in argv if a != '--bonn']
    if len(args) < 2:
        sys.exit(__doc__)
    raw = load(args[0])
    if bonn:
        converted = bonn_to_camera(raw)
        stamps = np.array([c[0] for c in converted])
        positions = np.array([c[1] for c in converted])
        quats = np.array([matrix_quat(c[2]) for c in converted])
    else:
        stamps, positions, quats = raw[:, 0], raw[:, 1:4], raw[:, 4:8]
    for path in args[1:]:
        analyse((stamps, positions, quats), path)


if __name__ == '__main__':
    main(sys.argv[1:])
