"""Each robot kind's trajectories: how a generated trajectory of the config is built and checked
(:data:`KINDS`, by the robot kinds of :mod:`ident_hw.config.robots`), and the config's sections
turned into the trajectories' own types (the actuators' limits, a 3PRRR Fourier excitation's
coefficients). Here and not in the config: the config imports nothing of :mod:`trajectories`.

    kind = trajectories_of(config.robot)           # RobotTrajectories of robot.kind
    traj = kind.build(config.robot, tcfg, model, 250.0, 2.0)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

import trajectories
from ident_hw.config import RobotConfig, TrajectoryConfig
from ident_hw.config.robots import KINDS as ROBOT_KINDS
from ident_hw.model.interface import POSITION_UNITS, RobotModel
from trajectories import delta_paper, joint_space
from trajectories.feasibility import ActuatorLimits
from trajectories.feasibility import Limits as FeasibilityLimits

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
    if robot.stroke is None or robot.safety is None:
        raise ValueError("robot: a 3PRRR needs its stroke and safety sections")
    return FeasibilityLimits(
        carriage_stroke=robot.stroke,
        carriage_speed=min(a.limits.velocity for a in pri),
        carriage_accel=min(a.limits.acceleration for a in pri),
        revolute_speed=min(a.limits.velocity for a in rev),
        revolute_accel=min(a.limits.acceleration for a in rev),
        min_serial_margin=robot.safety.min_serial_margin,
        max_cond_A=robot.safety.max_cond_A)


def excitation_of(tcfg: TrajectoryConfig) -> trajectories.FourierExcitation:
    """The coefficients of a 3PRRR ``fourier`` trajectory: its ``path`` (written relative to the
    config file, made relative to the working directory when the config was read) or the
    excitation shipped for the nominal rig."""
    path = NOMINAL_EXCITATION if tcfg.path is None else Path(tcfg.path)   # relative to the config when read
    return trajectories.FourierExcitation.load(path)


def excitation_bandwidth(tcfg: TrajectoryConfig, filter_band: float) -> float:
    """Hz, the highest frequency of a ``joint_excitation``: the trajectory's ``bandwidth``, else
    ``filter_band``, the identification filter's (what it is filtered at; 2 Hz without one)."""
    return tcfg.bandwidth or filter_band


def joint_harmonics_of(tcfg: TrajectoryConfig, model: RobotModel, bandwidth: float) -> joint_space.JointHarmonics | None:
    """The sines a ``joint_excitation`` reads from its ``path`` (an optimised set,
    :mod:`trajectories.joint_optimisation`; relative to the config), None where it draws them;
    ``bandwidth``: the trajectory's (:func:`excitation_bandwidth`).

    Raises:
        ValueError: not such a file, not one row per actuator, or sines above the trajectory's
            bandwidth (its identification filter would cut them), naming the file."""
    if tcfg.path is None:
        return None
    path = Path(tcfg.path)                 # made relative to the config's folder when it was read
    sines = joint_space.JointHarmonics.load(path, len(model.home_actuated()))
    top = float(np.max(sines.frequencies)) / (2 * np.pi)
    if top > bandwidth * (1 + 1e-9):
        raise ValueError(f"{path}: sines up to {top:.4g} Hz, above the trajectory's bandwidth {bandwidth:g} Hz")
    return sines


@dataclass(frozen=True)
class RobotTrajectories:
    """The generated trajectories of one robot kind.

    Attributes:
        build: ``(robot section, trajectory, robot model, rate (Hz), the identification filter's
            band (Hz)) -> Trajectory``: one generated trajectory at the SYNC rate (a file's path
            is already relative to the config's folder when read).
        check: ``(robot section, trajectory, robot model) -> Report``: its feasibility (reach,
            safety margins, speeds and accelerations).
    """

    build: Callable[[RobotConfig, TrajectoryConfig, RobotModel, float, float], trajectories.Trajectory]
    check: Callable[[RobotConfig, trajectories.Trajectory, RobotModel], trajectories.Report]


# ---- the 3PRRR
def _threeprrr_build(robot: RobotConfig, tcfg: TrajectoryConfig, model: RobotModel, rate: float,
                     bandwidth: float) -> trajectories.Trajectory:
    limits = feasibility_limits(robot)
    k = tcfg.speed_scale
    # a generated path keeps within the stroke and within the carriage drives' software position
    # limits (those the set-points are checked against): the carriage schedule's bounds
    room = min(min(-a.limits.position[0], a.limits.position[1]) for a in robot.actuators[3:])
    timing = dataclasses.replace(limits, carriage_stroke=min(limits.carriage_stroke, room),
                                 carriage_speed=limits.carriage_speed * k,
                                 carriage_accel=limits.carriage_accel * k * k,
                                 revolute_speed=limits.revolute_speed * k,
                                 revolute_accel=limits.revolute_accel * k * k)
    if tcfg.kind == "carriage_sweep":
        return trajectories.carriage_sweep(model, timing, amplitude=tcfg.size, rate=rate, dwell=tcfg.dwell)
    if tcfg.kind == "square":
        return trajectories.square(model, timing, tcfg.rotation, side=tcfg.size, rate=rate, dwell=tcfg.dwell,
                                   name=tcfg.name)
    if tcfg.kind == "triangle":
        return trajectories.validation_triangle(model, timing, rate=rate, dwell=tcfg.dwell)
    return excitation_of(tcfg).trajectory(model, rate, name=tcfg.name)


THREE_PRRR = RobotTrajectories(
    build=_threeprrr_build,
    check=lambda robot, traj, model: trajectories.check_trajectory(traj, model, feasibility_limits(robot)))


# ---- the Delta
def _delta_check(robot: RobotConfig, traj: trajectories.Trajectory, model: RobotModel) -> trajectories.Report:
    safety = robot.safety
    if safety is None:
        raise ValueError("robot: a Delta needs its safety section")
    return delta_paper.check_delta_trajectory(traj, model, actuator_limits(robot), safety.min_serial_margin,
                                              safety.max_cond_A)


def _duration(tcfg: TrajectoryConfig) -> float:
    """The ``duration`` of a generated trajectory (s), which its kind requires (the config's check)."""
    if tcfg.duration is None:
        raise ValueError(f"trajectory {tcfg.name!r}: a {tcfg.kind} trajectory needs its duration")
    return tcfg.duration


DELTA = RobotTrajectories(
    build=lambda robot, tcfg, model, rate, bandwidth: delta_paper.delta_trajectory(
        model, tcfg.kind, _duration(tcfg), rate, tcfg.fade, name=tcfg.name, amplitude=tcfg.amplitude),
    check=_delta_check)


# ---- any robot from its description file
def _described_build(robot: RobotConfig, tcfg: TrajectoryConfig, model: RobotModel, rate: float,
                     bandwidth: float) -> trajectories.Trajectory:
    band = excitation_bandwidth(tcfg, bandwidth)
    return joint_space.joint_excitation(model, actuator_limits(robot), _duration(tcfg), rate, band, fade=tcfg.fade,
                                        seed=tcfg.seed, name=tcfg.name, amplitude=tcfg.amplitude,
                                        harmonics=tcfg.harmonics, sines=joint_harmonics_of(tcfg, model, band))


def _described_check(robot: RobotConfig, traj: trajectories.Trajectory, model: RobotModel) -> trajectories.Report:
    return joint_space.check_described_trajectory(traj, model, actuator_limits(robot),
                                                  robot.described_settings.max_condition)


DESCRIBED = RobotTrajectories(build=_described_build, check=_described_check)

#: each robot kind's trajectories, by ``robot.kind`` (the kinds of :data:`ident_hw.config.robots.KINDS`)
KINDS: dict[str, RobotTrajectories] = {"3prrr": THREE_PRRR, "delta": DELTA, "described": DESCRIBED}
assert set(KINDS) == set(ROBOT_KINDS), "every robot kind has its trajectories"


def trajectories_of(robot: RobotConfig) -> RobotTrajectories:
    """The :class:`RobotTrajectories` of a ``robot`` section's kind."""
    return KINDS[robot.kind]
