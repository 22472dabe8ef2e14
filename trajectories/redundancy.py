"""Redundancy resolution: a carriage schedule ``zeta(s)`` that keeps a pose path away from singularities.

The 3PRRR has six actuators for three pose coordinates; along a given pose path the carriages are
free. :func:`carriage_schedule` chooses them for a waypoint path (straight pose segments, see
:mod:`trajectories.timing`): the carriage positions at the interior waypoints and, per segment and
chain, ``harmonics`` sine bends ``c_k sin(k pi s)`` (zero at both ends, so the vertices are
unchanged). It maximises the smallest singularity margin along the path, measured against the
rig's limits::

    margin(s) = min( min_i |sin(beta_i - theta_i)| / min_serial_margin,  max_cond_A / cond(A) )

(> 1 means feasible), through a smooth soft-minimum (``scipy.optimize.minimize``, L-BFGS-B). The
bounds keep every carriage within 80 % (waypoints) + 20 % (bends) of the stroke; the speed and
acceleration limits are met afterwards by the timing, and a small penalty on carriage travel
keeps those durations short.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.optimize import minimize

from ident_hw.model import KinematicsError

from .feasibility import Limits
from .timing import Segment

if TYPE_CHECKING:
    from ident_hw.model import ThreePRRR

#: Sharpness of the soft-minimum (in units of the margin ratio).
SOFTMIN_SHARPNESS = 30.0
#: Weight of the carriage-travel penalty, per (stroke)^2.
TRAVEL_WEIGHT = 1e-3


@dataclass(frozen=True)
class CarriageSchedule:
    """Carriage positions at the waypoints and sine bends per segment.

    Attributes:
        zeta: ``(M, 3)`` carriages at the ``M`` waypoints, m.
        bends: ``(M - 1, K, 3)`` amplitudes of ``sin(k pi s)``, ``k = 1..K``, per segment, m.
        min_margin: smallest margin ratio along the path (see module docstring; > 1 is feasible).
    """

    zeta: np.ndarray
    bends: np.ndarray
    min_margin: float

    def segments(self, poses: np.ndarray) -> list[Segment]:
        """Unit-duration segments in ``[x, y, alpha, zeta1..3]`` through ``poses`` (``(M, 3)``)."""
        q = np.hstack([poses, self.zeta])
        shapes = np.concatenate([np.zeros(self.bends.shape[:2] + (3,)), self.bends], axis=2)
        return [Segment(a, b, 1.0, shape) for a, b, shape in zip(q[:-1], q[1:], shapes)]


def path_margins(robot: ThreePRRR, poses: np.ndarray, schedule: CarriageSchedule, limits: Limits,
                 samples: int = 25) -> np.ndarray:
    """Margin ratio (see module docstring) at ``samples`` points of each segment, ``((M - 1) * samples,)``.

    Raises:
        KinematicsError: a point of the path is out of reach.
    """
    s = np.linspace(0.0, 1.0, samples)
    q = np.vstack([seg.geometry(s).q for seg in schedule.segments(poses)])
    m = robot.singularity_margins(q[:, :3], q[:, 3:])
    return np.minimum(m.serial.min(axis=1) / limits.min_serial_margin, limits.max_cond_A / m.cond_A)


def carriage_schedule(robot: ThreePRRR, poses: np.ndarray, limits: Limits, harmonics: int = 1,
                      fix_ends: bool = True, samples: int = 25, max_iter: int = 200) -> CarriageSchedule:
    """Optimise the carriage schedule along the waypoint path ``poses`` (``(M, 3)``, m, m, rad).

    Args:
        robot: the model.
        poses: pose waypoints; the path is straight in ``[x, y, alpha]`` between them.
        limits: stroke and singularity thresholds.
        harmonics: sine bends per segment and chain (0 for straight carriage moves).
        fix_ends: keep the carriages at 0 at the first and last waypoint (home).
        samples: points per segment where the margins are evaluated.
        max_iter: iteration cap of the optimiser (deterministic; no random start).
    """
    poses = np.asarray(poses, dtype=float)
    M = len(poses)
    free = np.arange(1, M - 1) if fix_ends else np.arange(M)
    n_z, n_b = 3 * len(free), 3 * (M - 1) * harmonics
    stroke = limits.carriage_stroke

    def unpack(v: np.ndarray) -> CarriageSchedule:
        zeta = np.zeros((M, 3))
        zeta[free] = v[:n_z].reshape(-1, 3) * stroke
        bends = v[n_z:].reshape(M - 1, harmonics, 3) * stroke
        return CarriageSchedule(zeta, bends, np.nan)

    def cost(v: np.ndarray) -> float:
        try:
            margin = path_margins(robot, poses, unpack(v), limits, samples)
        except KinematicsError:
            return 1e3
        soft_min = -np.log(np.mean(np.exp(-SOFTMIN_SHARPNESS * margin))) / SOFTMIN_SHARPNESS
        travel = np.sum(np.diff(unpack(v).zeta, axis=0) ** 2) / stroke**2 + np.sum(v[n_z:] ** 2)
        return -soft_min + TRAVEL_WEIGHT * travel

    bounds = [(-0.8, 0.8)] * n_z + [(-0.2 / max(harmonics, 1), 0.2 / max(harmonics, 1))] * n_b
    result = minimize(cost, np.zeros(n_z + n_b), method="L-BFGS-B", bounds=bounds,
                      options={"maxiter": max_iter})
    best = unpack(result.x)
    margin = path_margins(robot, poses, best, limits, samples)
    return CarriageSchedule(best.zeta, best.bends, float(margin.min()))
