"""A standstill: the robot held at its home pose, so that the drives' currents at rest can be
recorded (the quality verdict's noise floor of each axis, ``ident_hw.experiment.quality``).

Any robot's: imports nothing of the project but the :class:`~trajectories.trajectory.Trajectory`.
"""

from __future__ import annotations

import numpy as np

from .trajectory import Trajectory


def standstill(robot, duration: float, rate: float, name: str = "standstill") -> Trajectory:
    """``duration`` s at ``rate`` Hz of the robot (a :class:`ident_hw.model.interface.RobotModel`)
    held at its home pose (``robot.home_actuated()``): every rate and acceleration zero."""
    if not duration > 0:
        raise ValueError(f"a standstill needs a positive duration, got {duration} s")
    home = np.asarray(robot.home_actuated(), dtype=float)
    t = np.arange(int(np.floor(duration * rate + 1e-9)) + 1) / rate
    Theta = np.tile(home, (len(t), 1))
    X = np.tile(robot.pose_series(home[None], np.zeros(robot.pose_size))[0], (len(t), 1))
    return Trajectory(name, t, X, np.zeros_like(X), np.zeros_like(X), Theta, np.zeros_like(Theta),
                      np.zeros_like(Theta), metadata={"generator": "standstill", "duration_s": duration, "rate_hz": rate})
