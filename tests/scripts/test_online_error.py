"""scripts/online_error.py on trajectories made here (fixed seeds)."""

import numpy as np

from script_loader import load


def write_tum(path, stamps, positions, quats):
    with open(path, 'w') as f:
        f.write('# timestamp tx ty tz qx qy qz qw\n')
        for t, p, q in zip(stamps, positions, quats):
            f.write(f'{t:.6f} ' + ' '.join(f'{v:.9f}' for v in (*p, *q)) + '\n')


def make_run(tmp_path, seed=3):
    """Ground truth at 100 Hz over 12 s; a run at 30 Hz whose online pose is 2 mm noisy and
    3 cm off from 4 to 6 s (the map at the time shifted, corrected later), and whose final
    trajectory is 2 mm noisy throughout. Both in a world of their own (rotated and shifted)."""
    rng = np.random.default_rng(seed)
    gt_t = 100.0 + np.arange(0, 12.0, 0.01)
    path = lambda t: np.column_stack([0.5 * np.sin(0.4 * t), 0.2 * np.cos(0.3 * t),  # noqa: E731
                                      0.1 * t])
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (len(gt_t), 1))
    write_tum(tmp_path / 'gt.txt', gt_t, path(gt_t - 100.0), quat)
    t = 100.0 + np.arange(0.02, 11.9, 1.0 / 30.0)
    world = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    truth = path(t - 100.0) @ world.T + np.array([1.0, 2.0, -0.5])
    bump = ((t - 100.0 >= 4.0) & (t - 100.0 < 6.0))[:, None] * np.array([0.03, 0.0, 0.0])
    run = tmp_path / 'run'
    run.mkdir()
    q = np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1))
    write_tum(run / 'trajectory_online.txt', t, truth + bump + rng.normal(0, 0.002, truth.shape),
              q)
    write_tum(run / 'trajectory.txt', t, truth + rng.normal(0, 0.002, truth.shape), q)
    return run


def test_the_window_where_the_map_was_off_carries_the_online_error(tmp_path):
    oe = load('online_error')
    run = make_run(tmp_path)
    gt = oe.co.load_ground_truth(str(tmp_path / 'gt.txt'), False)
    rows, online, final, smoothed = oe.analyse(gt, oe.pn.load(run / 'trajectory_online.txt'),
                                               oe.pn.load(run / 'trajectory.txt'), 2.0)
    assert len(rows) == 6  # 11.9 s in windows of 2 s
    shares = [r[5] for r in rows]
    assert abs(sum(shares) - 1.0) < 1e-9
    worst = int(np.argmax([r[3] for r in rows]))
    assert rows[worst][0] - 100.0 >= 3.9 and rows[worst][1] - 100.0 < 6.0
    # Half the online ATE's sum of squares from a sixth of the run (the alignment of the whole run
    # spreads part of the 3 cm over the other windows).
    assert shares[worst] > 0.5
    assert rows[worst][4] < 0.006  # the final trajectory is not off there
    assert online > 3 * final
    assert final < 0.005
    # Smoothing with the frames after each pose takes the 2 mm noise (the last window, away from
    # the shift: 4.5 -> 3.0 mm, the rest being the alignment's share of the shift) but not the
    # map's 3 cm shift.
    assert rows[-1][6] < rows[-1][3] - 0.001
    assert rows[worst][6] > 0.8 * rows[worst][3]
    assert smoothed > 0.9 * online


def test_smoothing_a_noisy_path_keeps_the_path_and_measures_the_noise():
    oe = load('online_error')
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 10.0, 1.0 / 30.0)
    truth = np.column_stack([np.sin(t), 0.5 * np.cos(0.7 * t), 0.2 * t])
    noisy = truth + rng.normal(0, 0.003, truth.shape)
    out = oe.smooth_positions(t, noisy)
    before = np.sqrt(np.mean(np.sum((noisy - truth) ** 2, axis=1)))
    after = np.sqrt(np.mean(np.sum((out - truth) ** 2, axis=1)))
    assert after < 0.5 * before
    # A pose 10 cm off is down-weighted, not followed.
    noisy[150] += [0.1, 0.0, 0.0]
    out = oe.smooth_positions(t, noisy)
    assert np.linalg.norm(out[150] - truth[150]) < 0.01


def test_prints_a_table_and_refuses_a_missing_run(tmp_path, capsys):
    oe = load('online_error')
    run = make_run(tmp_path)
    assert oe.main([str(tmp_path / 'gt.txt'), str(run), '--window', '3']) == 0
    out = capsys.readouterr().out
    assert 'online mm' in out and 'ATE (median of 1)' in out and 'online smoothed' in out
    assert len([line for line in out.splitlines() if '%' in line]) == 4
    assert oe.main([str(tmp_path / 'gt.txt'), str(tmp_path / 'nowhere')]) == 1
    assert 'nowhere' in capsys.readouterr().err
    assert oe.main([str(tmp_path / 'gt.txt'), str(run), '--window', '-1']) == 2
    assert oe.main([str(tmp_path / 'gt.txt'), str(run), '--noise', 'x']) == 2
    assert '--noise needs' in capsys.readouterr().err
    assert oe.main([str(tmp_path / 'gt.txt'), str(run), '--noise', '5']) == 0


def test_the_banded_solve_is_the_dense_one():
    oe = load('online_error')
    rng = np.random.default_rng(7)
    n = 40
    a0, a1, a2 = 6.0 + rng.random(n), rng.random(n) - 0.5, rng.random(n) - 0.5
    A = np.diag(a0) + np.diag(a1[:-1], 1) + np.diag(a1[:-1], -1) + np.diag(a2[:-2], 2) + \
        np.diag(a2[:-2], -2)
    rhs = rng.normal(size=(n, 3))
    assert np.allclose(oe.solve_banded(a0, a1, a2, rhs), np.linalg.solve(A, rhs))


def test_a_gap_cuts_the_path():
    # Two stretches of a still camera 1.2 s apart and 1 m from each other (a relocalisation
    # after a loss): each is smoothed on its own, so their ends stay where they were; smoothed
    # as one path, the ends lean towards each other.
    oe = load('online_error')
    rng = np.random.default_rng(9)
    t = np.concatenate([np.arange(0.0, 3.0, 1.0 / 30.0), 4.2 + np.arange(0.0, 3.0, 1.0 / 30.0)])
    truth = np.where(t[:, None] < 3.5, 0.0, 1.0) * np.array([1.0, 0.0, 0.0])
    noisy = truth + rng.normal(0, 0.002, truth.shape)
    worst = lambda gap: np.max(np.linalg.norm(  # noqa: E731
        oe.smooth_positions(t, noisy, max_gap=gap) - truth, axis=1))
    assert worst(1.0) < 0.0045 < 0.005 < worst(10.0)
