"""Waypoint trajectories: straight segments passed at rest, timed by the actuator limits.

Two spaces: pose waypoints ``[x, y, alpha]`` with a carriage schedule (blocked, user-given or
optimised by :mod:`trajectories.redundancy`), or actuator waypoints ``Theta`` (the pose then follows
by forward kinematics). Both start and end wherever the waypoints say; the paper set starts and ends
at home so that trajectories can be run one after the other.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .feasibility import Limits
from .redundancy import CarriageSchedule, carriage_schedule
from .motion import SampledMotion
from .timing import rest_to_rest_path, time_grid
from .trajectory import Trajectory, actuator_map

if TYPE_CHECKING:
    from ident_hw.model import ThreePRRR

#: Pose of the end-effector at home, ``[x, y, alpha]``.
HOME_POSE = np.zeros(3)


def home_actuators(robot: ThreePRRR) -> np.ndarray:
    """``(6,)`` actuator coordinates at home (pose 0, carriages 0)."""
    theta, _ = robot.inverse_kinematics(HOME_POSE[None], np.zeros((1, 3)))
    return np.concatenate([theta[0], np.zeros(3)])


def _identity(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> SampledMotion:
    return SampledMotion(q, qd, qdd)


def pose_trajectory(robot: ThreePRRR, name: str, poses: np.ndarray, limits: Limits, rate: float = 250.0,
                    carriages: np.ndarray | str = "blocked", dwell: float = 0.0,
                    metadata: dict | None = None) -> Trajectory:
    """Trajectory through pose waypoints, at rest at each (segment durations are whole sample periods).

    Args:
        robot: the model.
        name: name of the trajectory.
        poses: ``(M, 3)`` waypoints ``[x, y, alpha]`` (m, m, rad).
        limits: actuator limits used for the timing (and stroke/singularity limits for ``"optimise"``).
        rate: sample rate, Hz.
        carriages: ``"blocked"`` (all at 0), ``"optimise"`` (see :func:`carriage_schedule`) or a
            user-given ``(M, 3)`` array of carriage positions at the waypoints (m).
        dwell: time held at rest at every waypoint, s.
        metadata: extra metadata stored with the trajectory.
    """
    poses = np.asarray(poses, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"poses must be (M, 3), got shape {poses.shape}")
    if isinstance(carriages, str):
        if carriages == "blocked":
            schedule = CarriageSchedule(np.zeros((len(poses), 3)), np.zeros((len(poses) - 1, 0, 3)), np.nan)
        elif carriages == "optimise":
            schedule = carriage_schedule(robot, poses, limits)
        else:
            raise ValueError(f"carriages must be 'blocked', 'optimise' or an (M, 3) array, got {carriages!r}")
    else:
        zeta = np.asarray(carriages, dtype=float)
        if zeta.shape != poses.shape:
            raise ValueError(f"carriages must have the shape of poses {poses.shape}, got {zeta.shape}")
        schedule = CarriageSchedule(zeta, np.zeros((len(poses) - 1, 0, 3)), np.nan)
    segments = schedule.segments(poses)
    waypoints = np.vstack([segments[0].start] + [seg.end for seg in segments])
    shapes = [seg.shape if seg.shape is not None and seg.shape.size else None for seg in segments]
    path = rest_to_rest_path(waypoints, actuator_map(robot), limits.max_speed, limits.max_accel, shapes, dwell,
                             time_step=1.0 / rate)
    meta = {"generator": "pose_trajectory", "waypoints": poses.tolist(), "carriages": schedule.zeta.tolist(),
            "carriage_bends": schedule.bends.tolist(), "rate_hz": rate, **(metadata or {})}
    t = time_grid(path.duration, rate)
    motion = path.evaluate(t)
    return Trajectory.from_pose(robot, name, t, motion.q, motion.qd, motion.qdd, metadata=meta)


def actuator_trajectory(robot: ThreePRRR, name: str, waypoints: np.ndarray, limits: Limits, rate: float = 250.0,
                        dwell: float = 0.0, metadata: dict | None = None) -> Trajectory:
    """Trajectory through actuator waypoints ``(M, 6)`` (``[theta1..3 rad, zeta1..3 m]``), at rest at each.

    The pose follows from the model's forward kinematics, continued from home.
    """
    waypoints = np.asarray(waypoints, dtype=float)
    path = rest_to_rest_path(waypoints, _identity, limits.max_speed, limits.max_accel, dwell=dwell, time_step=1.0 / rate)
    t = time_grid(path.duration, rate)
    meta = {"generator": "actuator_trajectory", "waypoints": waypoints.tolist(), "rate_hz": rate,
            **(metadata or {})}
    motion = path.evaluate(t)
    return Trajectory.from_actuators(robot, name, t, motion.q, motion.qd, motion.qdd, HOME_POSE, metadata=meta)
