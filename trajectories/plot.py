"""Plot a trajectory to a PNG file (matplotlib, Agg backend): the path in the plane with the robot
drawn at a few poses, and the six actuator time series."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)
import numpy as np  # noqa: E402

from .trajectory import COLUMNS, Trajectory  # noqa: E402

if TYPE_CHECKING:
    from ident_hw.model import ThreePRRR


def plot_trajectory(traj: Trajectory, robot: ThreePRRR, path: str | Path, poses: int = 4,
                    stroke: float = 0.10) -> Path:
    """Write a figure of ``traj`` to ``path`` (PNG) and return the path.

    Args:
        traj: the trajectory.
        robot: the model, for the joint positions of the drawn poses.
        path: output file.
        poses: number of poses drawn (evenly spaced in time, first and last included).
        stroke: half-length of the drawn linear guides, m.
    """
    kin = robot.kinematics
    fig, axes = plt.subplot_mosaic([["plane", "theta"], ["plane", "zeta"]], figsize=(12, 6), layout="constrained")
    ax = axes["plane"]
    samples = np.linspace(0, len(traj.t) - 1, poses).astype(int)
    _, beta = robot.inverse_kinematics(traj.X[samples], traj.zeta[samples])
    theta = traj.Theta[samples, :3]
    A = kin.base_points(traj.zeta[samples])
    B = kin.elbow_points(theta, traj.zeta[samples])
    C = kin.platform_points(traj.X[samples])
    colours = plt.cm.viridis(np.linspace(0, 1, poses))
    for k, colour in enumerate(colours):
        for i in range(3):
            chain = np.array([A[k, i], B[k, i], C[k, i]])
            ax.plot(chain[:, 0], chain[:, 1], "-o", color=colour, lw=1, ms=3)
        ax.fill(C[k, :, 0], C[k, :, 1], color=colour, alpha=0.3, label=f"t = {traj.t[samples[k]]:.2f} s")
    guide = kin.base_points(np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]]) * stroke)
    for i in range(3):
        ax.plot(guide[:, i, 0], guide[:, i, 1], "k-", lw=3, alpha=0.4)
    ax.plot(traj.X[:, 0], traj.X[:, 1], "r-", lw=1.5, label="end-effector path")
    ax.set(aspect="equal", xlabel="x [m]", ylabel="y [m]", title=traj.name)
    ax.legend(fontsize=7, loc="upper right")
    for key, cols, unit in (("theta", slice(0, 3), "rad"), ("zeta", slice(3, 6), "m")):
        for j, (name, _) in enumerate(COLUMNS["Theta"][cols]):
            axes[key].plot(traj.t, traj.Theta[:, cols][:, j], label=name)
        axes[key].set(xlabel="t [s]", ylabel=f"{key} [{unit}]")
        axes[key].legend(fontsize=7)
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
