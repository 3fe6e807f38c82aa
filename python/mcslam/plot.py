"""Plots of trajectories (matplotlib; imported only when used)."""


def plot_trajectories(path, estimate, groundtruth=None, title=None, evaluation=None):
    """Writes a PNG of the estimate's x-y path against the ground truth's (top view), the estimate
    aligned as the ATE aligns it when `evaluation` (mcslam.eval's result) is given."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    est = np.asarray(estimate, dtype=float)
    fig, ax = plt.subplots(figsize=(6, 6))
    if groundtruth is not None:
        gt = np.asarray(groundtruth, dtype=float)
        ax.plot(gt[:, 1], gt[:, 2], "k-", lw=1, label="ground truth")
    xyz = est[:, 1:4]
    if evaluation is not None:
        T = np.asarray(evaluation["ate_T_gt_est"], dtype=float).reshape(4, 4)
        xyz = xyz @ T[:3, :3].T + T[:3, 3]
    ax.plot(xyz[:, 0], xyz[:, 1], "r-", lw=1, label="mcslam")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.axis("equal")
    ax.legend()
    if title:
        ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
