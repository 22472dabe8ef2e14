"""The robot registry: one :class:`RobotKind` per value of ``robot.kind``.

A robot kind is everything the rest of the tool asks of a robot beyond its
:class:`~ident_hw.model.interface.RobotModel`: which section of ``robot`` holds its settings and
which key of ``sim`` its true parameters, its model, its CAD and true parameter vectors, the
actuators it expects and the names of its trajectory kinds (their builders and feasibility
checks are the runner's, :mod:`ident_hw.experiment.robot_trajectories`: the config imports
nothing of :mod:`trajectories`). The config, the campaign plan and the simulated rig's set-up look
the kind up here instead of comparing ``robot.kind`` with names; this module is the only place
that does (a test holds it).

Three kinds: ``3prrr`` and ``delta``, read from their description files like any robot and run on
their hand-derived models (:mod:`ident_hw.model`), the compiled fast paths held to the files'
generic models at load (:mod:`ident_hw.model.fast_path`), and
``described``: any robot from its description file (:class:`ident_hw.model.described.DescribedRobot`),
the file in ``robot.description`` as every kind's, its other settings in ``robot.described``
(:class:`~ident_hw.config.robot_described.DescribedConfig`), true parameters in ``sim.parameters``
(:class:`~ident_hw.config.robot_described.ParameterSetConfig`).
Adding a robot of this kind is a description file and a config, no code.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, cast

import numpy as np

from ident_hw.model import Delta, DeltaGeometry, Geometry, ThreePRRR
from ident_hw.model.interface import RobotModel
from ident_hw.model.pseudo_inertia import SPATIAL

from . import to_model
from .robot_described import ParameterSetConfig
from .schema import FieldError
from .sim import SeedStream

if TYPE_CHECKING:  # pinocchio, which described imports, is imported by described robots only
    from ident_hw.model.described import DescribedRobot
    from ident_hw.model.fast_path import FastPath

    from .file import Config
    from .robot import RobotConfig


# ----------------------------------------------------------------------------- the registry


@dataclass(frozen=True)
class RobotKind:
    """One robot kind (see the module docstring). Its functions take the config's ``robot``
    section (``truth`` also ``sim`` and the robot's model) and never look at ``robot.kind``.

    Attributes:
        name: the value of ``robot.kind``.
        sections: the keys of ``robot`` this kind needs.
        truth_key: the key of ``sim`` holding the simulated robot's true parameters.
        trajectory_kinds: the generated trajectory kinds of this robot (``file`` is any robot's;
            :mod:`ident_hw.experiment.robot_trajectories` builds and checks them).
        model: ``robot -> RobotModel``.
        initial: ``robot -> (P,)`` the CAD parameters in the model's order.
        truth: ``(robot, sim, robot model) -> (P,)`` the true parameters in the model's order.
        actuators: ``robot -> (names, kinds)`` the actuators the robot expects, in order.
        validate: ``robot -> None`` checks beyond the schema (FieldError, key relative to ``robot``).
        friction_models: its model takes any friction model of ``robot.friction`` (else only the
            default Coulomb and viscous terms).
        described: ``robot -> (DescribedRobot, map)`` the robot's generic model and the map of its
            model's parameter vector to the generic model's (what ``ident-hw export`` writes).
    """

    name: str
    sections: tuple[str, ...]
    truth_key: str
    trajectory_kinds: tuple[str, ...]
    model: Callable[[Any], RobotModel]
    initial: Callable[[Any], np.ndarray]
    truth: Callable[[Any, Any, RobotModel], np.ndarray]
    actuators: Callable[[Any], tuple[tuple[str, ...], tuple[str, ...]]]
    validate: Callable[[Any], None] = lambda robot: None
    friction_models: bool = False
    described: Callable[[Any], tuple[DescribedRobot, Callable[[np.ndarray], np.ndarray]]] | None = None


# ---- the 3PRRR
def threeprrr_file(robot) -> FastPath:
    """The 3PRRR of a ``robot`` section: the hand model's values read off ``robot.description``
    and checked against its generic model (:func:`ident_hw.model.prrr_file.fast_path`); a file
    that is no 3PRRR is a FieldError on ``description``."""
    from ident_hw.model.described import DescriptionError
    from ident_hw.model.prrr_file import fast_path
    try:
        return fast_path(robot.description, robot.modes or (1, 1, 1), robot.coulomb_width)
    except DescriptionError as exc:
        raise FieldError("description", str(exc)) from None


def _threeprrr_validate(robot) -> None:
    for key in ("description", "stroke"):
        if getattr(robot, key) is None:
            raise FieldError(key, "missing key (a 3PRRR needs its description file, e.g. robots/3prrr.xml, and stroke)")
    threeprrr_file(robot)


def _threeprrr_described(robot) -> tuple[DescribedRobot, Callable[[np.ndarray], np.ndarray]]:
    from ident_hw.model.prrr_file import described_3prrr, described_parameters
    fast = threeprrr_file(robot)
    described = described_3prrr(robot.description, cast(Geometry, fast.geometry), robot.coulomb_width)
    return described, lambda pi: described_parameters(robot.description, pi, described)


THREE_PRRR = RobotKind(
    name="3prrr", sections=("description", "modes", "stroke", "safety"), truth_key="truth",
    trajectory_kinds=("carriage_sweep", "square", "triangle", "fourier"),
    model=lambda robot: ThreePRRR(cast(Geometry, threeprrr_file(robot).geometry), coulomb_width=robot.coulomb_width),
    initial=lambda robot: threeprrr_file(robot).parameters.copy(),
    truth=lambda robot, sim, model: to_model.inertial_params(sim.truth).as_vector(),
    actuators=lambda robot: (ThreePRRR.actuator_names, ThreePRRR.actuator_kinds),
    validate=_threeprrr_validate, described=_threeprrr_described)


# ---- the Delta
def delta_file(robot) -> FastPath:
    """The Delta of a ``robot`` section (with its gravity, m/s²): the hand model's values read off
    ``robot.description`` and checked against its generic model
    (:func:`ident_hw.model.delta_file.fast_path`); a file that is no Delta is a FieldError on
    ``description``."""
    from ident_hw.model.delta_file import fast_path
    from ident_hw.model.described import DescriptionError
    try:
        return fast_path(robot.description, robot.coulomb_width)
    except DescriptionError as exc:
        raise FieldError("description", str(exc)) from None


def _delta_model(robot) -> Delta:
    fast = delta_file(robot)
    return Delta(cast(DeltaGeometry, fast.geometry), coulomb_width=robot.coulomb_width, gravity=fast.gravity)


def _delta_validate(robot) -> None:
    if robot.description is None:
        raise FieldError("description", "missing key: a Delta needs its description file (e.g. robots/delta.xml)")
    delta_file(robot)


def _delta_described(robot) -> tuple[DescribedRobot, Callable[[np.ndarray], np.ndarray]]:
    from ident_hw.model.delta_file import described_delta, described_parameters
    fast = delta_file(robot)
    described = described_delta(robot.description, cast(DeltaGeometry, fast.geometry), robot.coulomb_width)
    return described, lambda pi: described_parameters(robot.description, pi, described)


DELTA = RobotKind(
    name="delta", sections=("description", "safety"), truth_key="delta_truth",
    trajectory_kinds=("delta_training", "delta_verification", "delta_held_arm"),
    model=_delta_model,
    initial=lambda robot: delta_file(robot).parameters.copy(),
    truth=lambda robot, sim, model: to_model.delta_parameters(sim.delta_truth, delta_file(robot).parameters),
    actuators=lambda robot: (Delta.actuator_names, Delta.actuator_kinds),
    validate=_delta_validate, described=_delta_described)


# ---- any robot from its description file
def described_model(robot, presliding: float | None = None, stribeck: float | None = None) -> DescribedRobot:
    """The :class:`~ident_hw.model.described.DescribedRobot` of a ``described`` robot section, with its friction model
    (:func:`to_model.friction_model`; ``presliding``, ``stribeck``: the Dahl distance and the
    Stribeck velocity where the config leaves them ``auto``)."""
    from ident_hw.model.described import DescribedRobot
    d = robot.described_settings
    return DescribedRobot(robot.description, [a.joint or a.name for a in robot.actuators],
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
    if robot.description is None:
        raise FieldError("description", "missing key: a described robot needs its description file "
                                        "(MJCF .xml or URDF .urdf, e.g. robots/2r.urdf)")
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
        check_parameter_set(robot.described_settings.cad, model)
    except FieldError as exc:
        raise FieldError(f"described.cad.{exc.key}", exc.message) from None


#: the config key (relative to ``robot``) of each :class:`~ident_hw.model.described.DescribedRobot`
#: argument a description error names (:attr:`~ident_hw.model.described.DescriptionError.argument`)
_DESCRIBED_KEYS = {None: "description", "home": "described.home", "home_actuated": "described.home_actuated",
                   "end_effector": "described.end_effector"}


def _described_key(exc, robot) -> str:
    """Where in the ``robot`` section the description error ``exc`` points: the key its argument
    came from; for an actuated joint, that actuator's ``joint`` (its ``name`` where it names none)."""
    if exc.argument == "actuated":
        return f"actuators[{exc.index}].{'joint' if robot.actuators[exc.index].joint else 'name'}"
    return _DESCRIBED_KEYS[exc.argument]


DESCRIBED = RobotKind(
    name="described", sections=("description", "described"), truth_key="parameters", trajectory_kinds=("joint_excitation",),
    model=described_model,
    initial=lambda robot: to_model.described_parameters(robot.described_settings.cad, described_model(robot)),
    truth=lambda robot, sim, model: to_model.described_parameters(sim.parameters, cast("DescribedRobot", model)),
    actuators=lambda robot: (tuple(a.name for a in robot.actuators), tuple(a.kind for a in robot.actuators)),
    validate=_described_validate, friction_models=True,
    described=lambda robot: (described_model(robot), lambda pi: np.asarray(pi, dtype=float)))


#: every robot kind by its ``robot.kind``
KINDS: dict[str, RobotKind] = {k.name: k for k in (THREE_PRRR, DELTA, DESCRIBED)}
#: trajectory kinds any robot can run
COMMON_TRAJECTORY_KINDS = ("file", "standstill", "recorded")


#: the dotted config key of a robot's description file (every kind's): a results folder or a study
#: task rewrites it to the copy it carries under ``description/``
DESCRIPTION_KEY = "robot.description"


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
