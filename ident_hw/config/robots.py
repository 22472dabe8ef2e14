"""The robot registry: one :class:`RobotKind` per value of ``robot.kind``.

A robot kind is everything the rest of the tool asks of a robot beyond its
:class:`~ident_hw.model.interface.RobotModel`: which section of ``robot`` holds its settings and
which key of ``sim`` its true parameters, its model, its CAD and true parameter vectors, the
actuators it expects, its trajectory kinds with their builders and its feasibility check. The
config, the campaign plan and the simulated rig's set-up look the kind up here instead of
comparing ``robot.kind`` with names; this module is the only place that does (a test holds it).

Three kinds: ``3prrr`` and ``delta`` (hand-derived models, :mod:`ident_hw.model`) and
``described``: any robot from its description file (:class:`ident_hw.model.described.DescribedRobot`),
settings in ``robot.described`` (:class:`~ident_hw.config.robot_described.DescribedConfig`), true
parameters in ``sim.parameters`` (:class:`~ident_hw.config.robot_described.ParameterSetConfig`).
Adding a robot of this kind is a description file and a config, no code.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable
from pathlib import Path

import numpy as np

import trajectories
from ident_hw.model import Delta, ThreePRRR
from ident_hw.model.interface import RobotModel
from ident_hw.model.pseudo_inertia import SPATIAL
from trajectories import delta_paper, joint_space

from . import to_model
from .robot_described import ParameterSetConfig
from .schema import FieldError
from .sim import SeedStream
from .to_trajectories import actuator_limits, excitation_of, feasibility_limits

if TYPE_CHECKING:  # pinocchio, which described imports, is imported by described robots only
    from ident_hw.model.described import DescribedRobot

    from .file import Config
    from .robot import RobotConfig


# ----------------------------------------------------------------------------- the registry


@dataclass(frozen=True)
class RobotKind:
    """One robot kind (see the module docstring). Its functions take the config's ``robot``
    section (``truth`` also ``sim`` and the robot's model; ``build`` and ``check`` the whole
    config) and never look at ``robot.kind``.

    Attributes:
        name: the value of ``robot.kind``.
        sections: the keys of ``robot`` this kind needs.
        truth_key: the key of ``sim`` holding the simulated robot's true parameters.
        trajectory_kinds: the generated trajectory kinds of this robot (``file`` is any robot's).
        model: ``robot -> RobotModel``.
        initial: ``robot -> (P,)`` the CAD parameters in the model's order.
        truth: ``(robot, sim, robot model) -> (P,)`` the true parameters in the model's order.
        actuators: ``robot -> (names, kinds)`` the actuators the robot expects, in order.
        build: ``(config, trajectory, robot model, rate) -> Trajectory`` one generated trajectory.
        check: ``(config, trajectory, robot model) -> Report`` its feasibility.
        validate: ``robot -> None`` checks beyond the schema (FieldError, key relative to ``robot``).
        friction_models: its model takes any friction model of ``robot.friction`` (else only the
            default Coulomb and viscous terms).
    """

    name: str
    sections: tuple[str, ...]
    truth_key: str
    trajectory_kinds: tuple[str, ...]
    model: Callable[[Any], RobotModel]
    initial: Callable[[Any], np.ndarray]
    truth: Callable[[Any, Any, RobotModel], np.ndarray]
    actuators: Callable[[Any], tuple[tuple[str, ...], tuple[str, ...]]]
    build: Callable[[Any, Any, RobotModel, float], trajectories.Trajectory]
    check: Callable[[Any, trajectories.Trajectory, RobotModel], trajectories.Report]
    validate: Callable[[Any], None] = lambda robot: None
    friction_models: bool = False


# ---- the 3PRRR
def _threeprrr_build(config, tcfg, robot, rate):
    limits = feasibility_limits(config.robot)
    k = tcfg.speed_scale
    # a generated path keeps within the stroke and within the carriage drives' software position
    # limits (those the set-points are checked against): the carriage schedule's bounds
    room = min(min(-a.limits.position[0], a.limits.position[1]) for a in config.robot.actuators[3:])
    timing = dataclasses.replace(limits, carriage_stroke=min(limits.carriage_stroke, room),
                                 carriage_speed=limits.carriage_speed * k,
                                 carriage_accel=limits.carriage_accel * k * k,
                                 revolute_speed=limits.revolute_speed * k,
                                 revolute_accel=limits.revolute_accel * k * k)
    if tcfg.kind == "carriage_sweep":
        return trajectories.carriage_sweep(robot, timing, amplitude=tcfg.size, rate=rate, dwell=tcfg.dwell)
    if tcfg.kind == "square":
        return trajectories.square(robot, timing, tcfg.rotation, side=tcfg.size, rate=rate, dwell=tcfg.dwell,
                                   name=tcfg.name)
    if tcfg.kind == "triangle":
        return trajectories.validation_triangle(robot, timing, rate=rate, dwell=tcfg.dwell)
    return excitation_of(config, tcfg).trajectory(robot, rate, name=tcfg.name)


def _threeprrr_validate(robot) -> None:
    for key in ("geometry", "stroke", "cad"):
        if getattr(robot, key) is None:
            raise FieldError(key, "missing key (a 3PRRR needs geometry, stroke and cad)")


THREE_PRRR = RobotKind(
    name="3prrr", sections=("geometry", "stroke", "cad", "safety"), truth_key="truth",
    trajectory_kinds=("carriage_sweep", "square", "triangle", "fourier"),
    model=lambda robot: ThreePRRR(to_model.geometry(robot.geometry), coulomb_width=robot.coulomb_width),
    initial=lambda robot: to_model.inertial_params(robot.cad).as_vector(),
    truth=lambda robot, sim, model: to_model.inertial_params(sim.truth).as_vector(),
    actuators=lambda robot: (ThreePRRR.actuator_names, ThreePRRR.actuator_kinds),
    build=_threeprrr_build,
    check=lambda config, traj, robot: trajectories.check_trajectory(traj, robot, feasibility_limits(config.robot)),
    validate=_threeprrr_validate)


# ---- the Delta
def _delta_validate(robot) -> None:
    if robot.delta is None:
        raise FieldError("delta", "missing key: a Delta needs its delta section (geometry, cad)")


def _delta_check(config, traj, robot):
    safety = config.robot.safety
    return delta_paper.check_delta_trajectory(traj, robot, actuator_limits(config.robot),
                                              safety.min_serial_margin, safety.max_cond_A)


DELTA = RobotKind(
    name="delta", sections=("delta", "safety"), truth_key="delta_truth",
    trajectory_kinds=("delta_training", "delta_verification", "delta_held_arm"),
    model=lambda robot: Delta(to_model.delta_geometry(robot.delta.geometry), coulomb_width=robot.coulomb_width),
    initial=lambda robot: to_model.delta_parameters(robot.delta.cad, to_model.delta_geometry(robot.delta.geometry)),
    truth=lambda robot, sim, model: to_model.delta_parameters(sim.delta_truth, to_model.delta_geometry(robot.delta.geometry)),
    actuators=lambda robot: (Delta.actuator_names, Delta.actuator_kinds),
    build=lambda config, tcfg, robot, rate: delta_paper.delta_trajectory(
        robot, tcfg.kind, tcfg.duration, rate, tcfg.fade, name=tcfg.name, amplitude=tcfg.amplitude),
    check=_delta_check, validate=_delta_validate)


# ---- any robot from its description file
def described_model(robot, presliding: float | None = None, stribeck: float | None = None) -> DescribedRobot:
    """The :class:`DescribedRobot` of a ``described`` robot section, with its friction model
    (:func:`to_model.friction_model`; ``presliding``, ``stribeck``: the Dahl distance and the
    Stribeck velocity where the config leaves them ``auto``)."""
    from ident_hw.model.described import DescribedRobot
    d = robot.described
    return DescribedRobot(d.description, [a.joint or a.name for a in robot.actuators],
                          actuator_names=[a.name for a in robot.actuators], home=d.home,
                          home_actuated=d.home_actuated, end_effector=d.end_effector,
                          coulomb_width=robot.coulomb_width, friction=to_model.friction_model(robot, presliding, stribeck))


def check_parameter_set(params: ParameterSetConfig, model: DescribedRobot) -> None:
    """Every name of a described robot's parameter set a parameter of ``model``, one drive term
    per actuator (FieldError, key relative to the set, otherwise)."""
    names = model.parameter_names
    for key in ("factors", "values"):
        for name in getattr(params, key):
            if name not in names:
                bodies = sorted({n.split(".")[0] for n in names if "." in n})
                raise FieldError(f"{key}.{name}", f"unknown parameter of {model.path.name}; expected "
                                 f"<body>.<parameter> with bodies {bodies} and parameters of "
                                 f"{list(SPATIAL)}")
    n = len(model.actuator_names)
    for key in ("fv", "fc", "Jm"):
        given = getattr(params, key)
        if given and len(given) != n:
            raise FieldError(key, f"expected one value per actuator ({n}: {', '.join(model.actuator_names)}), "
                                  f"got {len(given)}")


def _described_validate(robot) -> None:
    if robot.described is None:
        raise FieldError("described", "missing key: a described robot needs its described section (description)")
    from ident_hw.model.described import DescriptionError
    try:
        model = described_model(robot)
    except DescriptionError as exc:
        raise FieldError(_described_key(exc, robot), str(exc)) from None
    model_kinds = dict(zip(model.actuated_joints, model.actuator_kinds))
    for i, act in enumerate(robot.actuators):
        joint = act.joint or act.name
        if model_kinds[joint] != act.kind:
            raise FieldError(f"actuators[{i}].kind", f"joint {joint!r} of {model.path.name} is "
                             f"{model_kinds[joint]}, the actuator says {act.kind!r}")
    try:
        check_parameter_set(robot.described.cad, model)
    except FieldError as exc:
        raise FieldError(f"described.cad.{exc.key}", exc.message) from None


#: the config key (relative to ``robot``) of each :class:`~ident_hw.model.described.DescribedRobot`
#: argument a description error names (:attr:`~ident_hw.model.described.DescriptionError.argument`)
_DESCRIBED_KEYS = {None: "described.description", "home": "described.home", "home_actuated": "described.home_actuated",
                   "end_effector": "described.end_effector"}


def _described_key(exc, robot) -> str:
    """Where in the ``robot`` section the description error ``exc`` points: the key its argument
    came from; for an actuated joint, that actuator's ``joint`` (its ``name`` where it names none)."""
    if exc.argument == "actuated":
        return f"actuators[{exc.index}].{'joint' if robot.actuators[exc.index].joint else 'name'}"
    return _DESCRIBED_KEYS[exc.argument]


def excitation_bandwidth(config, tcfg) -> float:
    """Hz, the highest frequency of a ``joint_excitation``: the trajectory's ``bandwidth``, else the
    identification filter's (what it is filtered at)."""
    return tcfg.bandwidth or (config.identification.filter.bandwidth if config.identification else 2.0)


def joint_harmonics_of(config, tcfg, robot) -> joint_space.JointHarmonics | None:
    """The sines a ``joint_excitation`` reads from its ``path`` (an optimised set,
    :mod:`trajectories.joint_optimisation`; relative to the config), None where it draws them.

    Raises:
        ValueError: not such a file, not one row per actuator, or sines above the trajectory's
            bandwidth (its identification filter would cut them), naming the file."""
    if tcfg.path is None:
        return None
    path = Path(tcfg.path)                 # made relative to the config's folder when it was read
    sines = joint_space.JointHarmonics.load(path, len(robot.home_actuated()))
    bandwidth = excitation_bandwidth(config, tcfg)
    top = float(np.max(sines.frequencies)) / (2 * np.pi)
    if top > bandwidth * (1 + 1e-9):
        raise ValueError(f"{path}: sines up to {top:.4g} Hz, above the trajectory's bandwidth {bandwidth:g} Hz")
    return sines


def _described_build(config, tcfg, robot, rate):
    return joint_space.joint_excitation(robot, actuator_limits(config.robot), tcfg.duration, rate,
                                        excitation_bandwidth(config, tcfg), fade=tcfg.fade,
                                        seed=tcfg.seed, name=tcfg.name, amplitude=tcfg.amplitude,
                                        harmonics=tcfg.harmonics, sines=joint_harmonics_of(config, tcfg, robot))


DESCRIBED = RobotKind(
    name="described", sections=("described",), truth_key="parameters", trajectory_kinds=("joint_excitation",),
    model=described_model,
    initial=lambda robot: to_model.described_parameters(robot.described.cad, described_model(robot)),
    truth=lambda robot, sim, model: to_model.described_parameters(sim.parameters, model),
    actuators=lambda robot: (tuple(a.name for a in robot.actuators), tuple(a.kind for a in robot.actuators)),
    build=_described_build,
    check=lambda config, traj, robot: joint_space.check_described_trajectory(
        traj, robot, actuator_limits(config.robot), config.robot.described.max_condition),
    validate=_described_validate, friction_models=True)


#: every robot kind by its ``robot.kind``
KINDS: dict[str, RobotKind] = {k.name: k for k in (THREE_PRRR, DELTA, DESCRIBED)}
#: trajectory kinds any robot can run
COMMON_TRAJECTORY_KINDS = ("file", "standstill", "recorded")


def kind_of(robot) -> RobotKind:
    """The :class:`RobotKind` of a ``robot`` section."""
    return KINDS[robot.kind]


def model_of(robot: RobotConfig) -> RobotModel:
    """The model of a ``robot`` section (its kind's), a new one per call."""
    return kind_of(robot).model(robot)


def initial_parameters(robot: RobotConfig) -> np.ndarray:
    """The CAD values (P,) of a ``robot`` section, in the order of its model's ``parameter_names``."""
    return kind_of(robot).initial(robot)


def true_parameters(config: Config, model: RobotModel | None = None) -> np.ndarray | None:
    """The simulated rig's true parameters (P,) in the order of ``model`` (the config robot's,
    :func:`model_of`; built when not given), drawn around the configured ones when
    ``sim.perturb`` is set (:func:`perturbed`); None without ``sim``."""
    if config.sim is None:
        return None
    model = model_of(config.robot) if model is None else model
    values = kind_of(config.robot).truth(config.robot, config.sim, model)
    if config.sim.perturb:
        values = perturbed(values, model.parameter_names, config.sim.perturb, config.sim.seed)
    return values


def perturbed(values: np.ndarray, names: tuple[str, ...], relative_std: float, seed: int) -> np.ndarray:
    """``values`` (P,) with each group of parameters scaled by its own factor ``exp(relative_std *
    z)``, ``z`` standard normal drawn from ``seed``: a group is a body's inertial parameters (the
    names sharing the part before a '.', ``rod1.m``, ``rod1.Ixx``, ...; a realisable body stays
    realisable, its pseudo-inertia scaled by a positive factor), every name without a '.' a group
    of its own (the 3PRRR's masses and inertias, friction, rotor inertias). Signs and zeros stay."""
    groups = [name.split(".", 1)[0] if "." in name else name for name in names]
    order = list(dict.fromkeys(groups))
    z = SeedStream.TRUTH_PERTURBATION.rng(seed).standard_normal(len(order))
    factor = dict(zip(order, np.exp(relative_std * z)))
    return np.asarray(values, dtype=float) * np.array([factor[g] for g in groups])
