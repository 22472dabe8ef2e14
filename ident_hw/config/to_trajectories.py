"""Config sections → the trajectories' own types (:mod:`trajectories`): the actuators' limits for
the feasibility checks, and the coefficients of a 3PRRR Fourier excitation."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np

import trajectories
from ident_hw.model.interface import POSITION_UNITS
from trajectories.feasibility import ActuatorLimits
from trajectories.feasibility import Limits as FeasibilityLimits

from .file import Config
from .robot import RobotConfig
from .trajectory import TrajectoryConfig

#: the Fourier excitation optimised for the nominal 3PRRR, shipped with ``trajectories``
NOMINAL_EXCITATION = resources.files(trajectories) / "data" / "fourier-nominal.json"


def actuator_limits(robot: RobotConfig) -> ActuatorLimits:
    """Every actuator's position range, speed and acceleration limits, for
    :func:`trajectories.feasibility.check_actuator_limits`."""
    acts = robot.actuators
    return ActuatorLimits(names=tuple(a.name for a in acts),
                          low=np.array([a.limits.position[0] for a in acts]),
                          high=np.array([a.limits.position[1] for a in acts]),
                          speed=np.array([a.limits.velocity for a in acts]),
                          accel=np.array([a.limits.acceleration for a in acts]),
                          units=tuple(POSITION_UNITS[a.kind] for a in acts))


def feasibility_limits(robot: RobotConfig) -> FeasibilityLimits:
    """Limits for :func:`trajectories.feasibility.check_trajectory` of the 3PRRR (the tightest
    axis of each kind: revolute actuators first, then the carriages)."""
    rev, pri = robot.actuators[:3], robot.actuators[3:]
    return FeasibilityLimits(
        carriage_stroke=robot.stroke,
        carriage_speed=min(a.limits.velocity for a in pri),
        carriage_accel=min(a.limits.acceleration for a in pri),
        revolute_speed=min(a.limits.velocity for a in rev),
        revolute_accel=min(a.limits.acceleration for a in rev),
        min_serial_margin=robot.safety.min_serial_margin,
        max_cond_A=robot.safety.max_cond_A)


def excitation_of(config: Config, tcfg: TrajectoryConfig) -> trajectories.FourierExcitation:
    """The coefficients of a 3PRRR ``fourier`` trajectory: its ``path`` (written relative to the
    config file, made relative to the working directory when the config was read) or the
    excitation shipped for the nominal rig."""
    path = NOMINAL_EXCITATION if tcfg.path is None else Path(tcfg.path)   # relative to the config when read
    return trajectories.FourierExcitation.load(path)
