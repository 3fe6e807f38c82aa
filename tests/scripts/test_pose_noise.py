"""scripts/pose_noise.py's own-jitter analysis on trajectories made here (fixed seed)."""

import numpy as np

from script_loader import load


def smooth_path(pn, n=300, rate=30.0):
    """A camera moving and turning smoothly: stamps, positions, rotations (camera to world)."""
    t = np.arange(n) / rate
    P = np.column_stack([0.3 * np.sin(0.5 * t), 0.1 * t, 0.05 * np.cos(0.7 * t)])
    Rs = [pn.rotation_exp(np.array([0.2 * np.sin(0.4 * s), 0.3 * s, 0.1 * np.cos(0.3 * s)]))
          for s in t]
    return t, P, Rs


def test_position_jitter_that_follows_the_rotation_jitter_is_found_with_its_lever():
    pn = load('pose_noise')
    rng = np.random.default_rng(7)
    t, P, Rs = smooth_path(pn)
    lever = 2.5  # metres: a turn about the camera's x axis shifts it along its y axis
    noisy_P, noisy_R = [], []
    for p, R in zip(P, Rs):
        turn = rng.normal(0.0, 0.002)
        noisy_R.append(R @ pn.rotation_exp(np.array([turn, 0.0, 0.0])))
        shift = np.array([0.0, lever * turn, 0.0]) + rng.normal(0.0, 0.0002, 3)
        noisy_P.append(p + R @ shift)
    dp, dw = pn.own_jitter(t, np.array(noisy_P), noisy_R)
    M, explained = pn.coupling(dp, dw)
    assert explained > 0.95
    assert abs(M[0, 1] - lever) < 0.1  # y position per x rotation


def test_independent_jitter_is_not_taken_for_coupling():
    pn = load('pose_noise')
    rng = np.random.default_rng(11)
    t, P, Rs = smooth_path(pn)
    noisy_P = [p + rng.normal(0.0, 0.004, 3) for p in P]
    noisy_R = [R @ pn.rotation_exp(rng.normal(0.0, 0.002, 3)) for R in Rs]
    dp, dw = pn.own_jitter(t, np.array(noisy_P), noisy_R)
    _, explained = pn.coupling(dp, dw)
    assert explained < 0.1
    # white noise of sigma against the midpoint of two neighbours: sqrt(1.5) sigma
    assert abs(np.sqrt(np.mean(dp ** 2)) / 0.004 - np.sqrt(1.5)) < 0.15


def test_a_smooth_path_has_no_jitter():
    pn = load('pose_noise')
    t, P, Rs = smooth_path(pn)
    dp, dw = pn.own_jitter(t, P, Rs)
    assert np.sqrt(np.mean(dp ** 2)) < 1e-4  # the midpoint is linear in time: curvature only
    assert np.sqrt(np.mean(dw ** 2)) < 1e-4
