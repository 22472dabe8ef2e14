"""Any robot from its description file: pinocchio for the tree, a closure layer for the loops.

A robot is described by an MJCF file (closed chains: each loop closure an ``<equality>``
``<connect>``, a point joint, or ``<weld>``, a rigid joint, between two bodies of the tree) or a
URDF file (serial robots). pinocchio builds the kinematic *tree* (its MJCF parser reads the
first body under ``<worldbody>`` only: the whole robot sits under one root body) and computes its
kinematics, Jacobians, mass matrix and joint-torque regressor. This module adds what a closed
chain needs on top (:class:`DescribedRobot`):

- the tree configuration ``q`` (nq,) from the actuated coordinates ``Theta`` (n,): Newton on the
  closure residuals ``r(q) = 0`` over the passive joints, started from a guess that selects the
  assembly mode (the last configuration of a series, else the home configuration);
- the passive rates from the closure Jacobian ``J = [J_a, J_p]`` (m, nv) and its drift
  ``gamma = Jdot v``: ``v = W Thetad`` with ``W_a = I``, ``W_p = -J_p^+ J_a``, and
  ``a = W Thetadd + a0`` with ``a0_p = -J_p^+ gamma``. A planar loop written in 3-D gives
  redundant rows (``m > rank``): the pseudo-inverse ``J_p^+`` takes the rank ``nv - n`` that a
  mobile closed chain has, and a smaller rank is a singularity (an error, never a NaN);
- the actuator forces ``tau = W^T Y_tree(q, v, a) pi + friction + rotor inertia``: the constraint
  forces do no work along ``W`` (``J W = 0``), so the virtual-work projection of the tree's
  inverse dynamics is the actuated one;
- the plant's dynamics in the actuated coordinates: ``M = W^T M_tree W + diag(Jm)`` and
  ``bias = W^T (M_tree a0 + h_tree(q, v))`` (velocity terms and gravity).

Parameters are a vector: ten per body of the tree (:data:`BODY_PARAMS`, pinocchio's dynamic
parameters: mass, first moment ``m c`` and inertia about the *joint frame origin*, in the joint
frame), then per actuator ``fv_<name>`` (viscous), ``fc_<name>`` (Coulomb) and ``Jm_<name>``
(rotor inertia reflected through the gear). Which joints are actuated, and their names, come from
the caller (the config), not from the file. Only one-degree-of-freedom joints are accepted
(hinge, slide; URDF revolute and prismatic; a ball joint is written as three hinges), so the
tree configuration is a plain vector and its Newton steps are additive.

The *pose* of a described robot (``pose_size = nq``) is its whole tree configuration: the guess
that carries the assembly mode from sample to sample. Everything is SI: rad, m, N·m, N, kg, s.

Model and data, as pinocchio splits them: no call changes a :class:`DescribedRobot` (parameters
are arguments; its pinocchio model keeps the file's inertias, its compiled tree is read-only).
What calls write, the closure state that starts the next call's Newton, is a
:class:`DescribedData` (:meth:`DescribedRobot.create_data`) that each user owns and passes as
``data=``; a call given none writes the robot's own (:attr:`DescribedRobot.data`).
"""

from __future__ import annotations

import copy
import hashlib
import threading
import warnings
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import pinocchio as pin

from .base_basis import BaseBasis
from .errors import KinematicsError, SingularityError
from .friction import FrictionModel
from .interface import PRISMATIC, REVOLUTE, PlantState
from .motion import TreeMotion
from .pseudo_inertia import SPATIAL, PhysicalBody
from .tree_kernels import (OK, PRISMATIC_JOINT, REVOLUTE_JOINT, SINGULAR, Workspace, closure_at, motion_batch,
                           tree_arrays, workspace)
from .tree_kernels import plant_dynamics as tree_plant_dynamics

#: the ten inertial parameters of a body, pinocchio's order: mass (kg), first moment ``m c``
#: (kg·m) and inertia about the joint frame's origin (kg·m²), in the joint frame
BODY_PARAMS = SPATIAL
#: the drive terms, one of each per actuator, after the bodies (then the friction model's
#: :attr:`~ident_hw.model.friction.FrictionModel.extra_terms`, ``fs`` and ``f0``, where it has them)
DRIVE_PARAMS = ("fv", "fc", "Jm")
#: SI units of the drive terms: (revolute, prismatic)
_DRIVE_UNITS = {"fv": ("N·m·s/rad", "N·s/m"), "fc": ("N·m", "N"), "Jm": ("kg·m²", "kg"), "fs": ("N·m", "N"),
                "f0": ("N·m", "N")}
#: the motions whose tree regressor a robot keeps (``DescribedRobot._tree_regressor``)
TREE_ROWS_KEPT = 4
#: ``cond(J_p)`` of the passive joints' closure Jacobian beyond which a pose is a parallel singularity
SINGULAR_CONDITION = 1e10
_UNITS = {"m": "kg", "mx": "kg·m", "my": "kg·m", "mz": "kg·m"}


class DescriptionError(ValueError):
    """A description file the tool cannot use (names the file and what is wrong in it).

    ``argument``: the :class:`DescribedRobot` argument the file does not fit (``home``,
    ``home_actuated``, ``end_effector``, ``actuated``), None for the file itself; ``index``:
    which of ``actuated``. A caller that took them from a config names its key with them."""

    def __init__(self, message: str, argument: str | None = None, index: int | None = None):
        super().__init__(message)
        self.argument, self.index = argument, index


@dataclass(frozen=True)
class Closure:
    """One loop closure: frame ``frame1`` (of one branch) and ``frame2`` (of another) coincide,
    in position (``rigid`` False: a point joint, 3 rows) or in position and orientation (``rigid``
    True: a weld, 6 rows). Frame ids are those of :attr:`DescribedRobot.model`."""

    name: str
    frame1: int
    frame2: int
    rigid: bool

    @property
    def rows(self) -> int:
        return 6 if self.rigid else 3


@dataclass(frozen=True)
class DescribedData:
    """What the calls of one user of a :class:`DescribedRobot` write, as pinocchio's ``Data`` is
    to its ``Model``: the robot itself is never changed by a call, and two users (the simulated
    plant and the identification in one process, two threads) that each hold their own data share
    no state. Made by :meth:`DescribedRobot.create_data`, passed as ``data=`` to the calls that
    solve the closures; a call given none writes the robot's own (:attr:`DescribedRobot.data`).

    ``motion``: the closure state (``q``, ``W``, the QR of ``J_p``) of the last sample a motion
    call solved (:meth:`~DescribedRobot.identification_regressor`, :meth:`~DescribedRobot.pose_series`,
    :meth:`~DescribedRobot.tree_configuration`...): Newton's warm start for the next call;
    ``plant``: the same for :meth:`~DescribedRobot.plant_dynamics`, carried from period to period.
    (pinocchio's own data, scratch of :meth:`~DescribedRobot.energy_regressor`, is made per call.)"""

    motion: Workspace
    plant: Workspace


@dataclass(frozen=True)
class Description:
    """A description file as pinocchio reads it (:func:`load_description`): the kinematic tree
    (``model``, its gravity the file's) and its closure constraints, pinocchio's constraint models
    of the MJCF ``<equality>`` elements: ``points`` (``<connect>``: a point held to a point) and
    ``frames`` (``<weld>``: a frame held to a frame); a URDF has none."""

    model: pin.Model
    points: tuple = ()
    frames: tuple = ()


def load_description(path: str | Path) -> Description:
    """The tree and closure constraints of an MJCF (``.xml``, ``.mjcf``) or URDF (``.urdf``, no
    closures) file.

    Raises:
        DescriptionError: an unknown suffix, or a file pinocchio cannot read.
    """
    path = Path(path)
    if not path.is_file():
        raise DescriptionError(f"{path}: no such description file")
    suffix = path.suffix.lower()
    try:
        if suffix in (".xml", ".mjcf"):
            model, points, frames = pin.buildModelAndConstraintsFromMJCF(str(path))
            model.gravity.linear = mjcf_gravity(path)
            return Description(model, tuple(points), tuple(frames))
        if suffix == ".urdf":
            return Description(pin.buildModelFromUrdf(str(path)))
    except (RuntimeError, ValueError) as exc:
        raise DescriptionError(f"{path}: pinocchio cannot read it: {exc}") from exc
    raise DescriptionError(f"{path}: unknown description format {suffix!r}; expected MJCF (.xml, .mjcf) or URDF (.urdf)")


def mjcf_gravity(path: str | Path) -> np.ndarray:
    """The gravity vector (3,) (m/s², world axes) of an MJCF file: its ``<option gravity>``,
    MuJoCo's default ``0 0 -9.81`` where it has none (pinocchio's MJCF reader ignores it).

    Raises:
        DescriptionError: a gravity that is not three numbers, naming the file.
    """
    from xml.etree import ElementTree

    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as exc:
        raise DescriptionError(f"{path}: not XML: {exc}") from exc
    gravity = np.array([0.0, 0.0, -9.81])
    for option in root.iter("option"):
        text = option.get("gravity")
        if text is None:
            continue
        try:
            value = np.array([float(x) for x in text.split()])
        except ValueError:
            value = np.zeros(0)
        if value.shape != (3,) or not np.all(np.isfinite(value)):
            raise DescriptionError(f"{path}: <option gravity={text!r}>: expected three numbers (m/s²)")
        gravity = value
    return gravity


class MasslessBodyWarning(UserWarning):
    """A description whose moving bodies have no mass (MuJoCo refuses such a file, unless its
    ``<compiler boundmass>`` puts a mass of its own in their place)."""


def _joint_kind(joint: pin.JointModel) -> str | None:
    """:data:`REVOLUTE`, :data:`PRISMATIC`, or None for a joint that is not one-degree-of-freedom."""
    if joint.nq != 1 or joint.nv != 1:
        return None
    short = joint.shortname()
    if short.startswith("JointModelP"):
        return PRISMATIC
    if short.startswith(("JointModelR", "JointModelRevolute")):
        return REVOLUTE
    return None


def _joint_kinds(model: pin.Model, where: str) -> dict[str, str]:
    """Joint name → :data:`REVOLUTE` or :data:`PRISMATIC` for every joint of the tree; raises
    :class:`DescriptionError` at the first joint that is not one-degree-of-freedom."""
    kinds = {}
    for j in range(1, model.njoints):
        kind = _joint_kind(model.joints[j])
        if kind is None:
            raise DescriptionError(f"{where}: joint {model.names[j]!r} is a {model.joints[j].shortname()} "
                                   f"(nq {model.joints[j].nq}, nv {model.joints[j].nv}); only one-degree-of-"
                                   "freedom joints are supported (hinge, slide; a ball joint as three hinges)")
        kinds[model.names[j]] = kind
    return kinds


class DescribedRobot:
    """A robot from its description file (see the module docstring): implements
    :class:`~ident_hw.model.interface.RobotModel`.

    Args:
        path: the MJCF or URDF file.
        actuated: the names of the actuated joints in the file, in actuator order (n).
        actuator_names: the actuators' names (default: the joint names).
        home: tree joint values (rad, m) by joint name of an assembled configuration near the
            robot's home: the default guess, whose assembly mode the Newton iterations keep;
            joints not named start at 0.
        home_actuated: the actuated coordinates (n,) of the home pose (default: those of ``home``).
        end_effector: the body that takes a payload (:meth:`with_payload`).
        coulomb_width: velocity scale (rad/s, m/s) of the smooth Coulomb sign ``tanh(qd / w)``.
        tolerance: closure residual (m, rad) at which Newton stops.
        friction: the joints' friction model (:class:`~ident_hw.model.friction.FrictionModel`;
            default: Coulomb ``tanh(qd / coulomb_width)`` and viscous, no offset).

    Raises:
        DescriptionError: a joint that is not hinge or slide, an unknown actuated joint or body,
            a closure between unknown bodies, or a mobility other than ``n``.

    Attributes:
        model: the description's kinematic tree as pinocchio reads it (each loop cut at its
            closure), with two frames added per closure (:class:`Closure`'s frame ids).
        body_names: the body moved by each tree joint, in the tree's joint order.
        parameter_names: ten inertial values per body of :attr:`body_names`
            (``<body>.<value>``), then each drive term for every actuator (``fv_<actuator>``, ...): the
            regressor's columns.
    """

    def __init__(self, path: str | Path, actuated: Sequence[str], *, actuator_names: Sequence[str] | None = None,
                 home: Mapping[str, float] | None = None, home_actuated: Sequence[float] | None = None,
                 end_effector: str | None = None, coulomb_width: float = 1e-3, tolerance: float = 1e-12,
                 friction: FrictionModel | None = None):
        if not coulomb_width > 0:
            raise ValueError(f"coulomb_width must be positive, got {coulomb_width}")
        self.path = Path(path)
        self.coulomb_width = float(coulomb_width)
        self.friction = FrictionModel(width=self.coulomb_width) if friction is None else friction
        self.tolerance = float(tolerance)
        description = load_description(self.path)
        self.model = model = description.model
        where = str(self.path)
        kinds = _joint_kinds(model, where)
        self.joint_names = tuple(model.names[j] for j in range(1, model.njoints))
        self.body_names = tuple(self._body_of(j) for j in range(1, model.njoints))
        actuated = tuple(actuated)
        self._set_actuated(actuated, actuator_names, kinds, where)

        self.closures = tuple(self._closures(description.points, description.frames))
        self._rows = sum(c.rows for c in self.closures)
        n = len(actuated)
        self.pose_size = model.nq
        self._n_body = 10 * (model.njoints - 1)
        self._set_parameter_names()
        # the tree's part of the regressor of the motions last asked for, kept once a copy with
        # another friction model is made (:meth:`with_friction`), which shares it (and its lock):
        # the friction choice prepares one motion with many models
        self._tree_rows: OrderedDict | None = None
        self._tree_rows_lock = threading.Lock()

        self._set_home(home, home_actuated, kinds, where, n)
        self.end_effector = end_effector
        if end_effector is not None and not model.existFrame(end_effector):
            raise DescriptionError(f"{where}: no body or site {end_effector!r} to carry a payload", "end_effector")
        # the compiled model of the tree and its closures, immutable; what calls write is in a
        # DescribedData: the caller's, else the robot's own (``data``)
        self.tree = tree_arrays(model, [(c.frame1, c.frame2, c.rigid) for c in self.closures], self._act_v,
                                self._pas_v, self._home_q, self.tolerance, SINGULAR_CONDITION,
                                [REVOLUTE_JOINT if kinds[name] == REVOLUTE else PRISMATIC_JOINT
                                 for name in self.joint_names])
        #: the data of the calls given none (:class:`DescribedData`): the robot's own user's
        self.data = self.create_data()
        bodies = [model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)]
        self._nominal = np.concatenate([*bodies, self.drive_parameters()])
        self._mobility_check()
        if self.massless_bodies:
            warnings.warn(MasslessBodyWarning(
                f"{self.path}: moving bodies without mass: {', '.join(self.massless_bodies)} (MuJoCo refuses "
                "them unless a <compiler boundmass/boundinertia> gives them one, which its simulation then "
                "uses in place of the file's: give each its real mass and inertia, e.g. a universal joint's "
                "cross; pinocchio and the identification take them as they are)"), stacklevel=2)

    def create_data(self) -> DescribedData:
        """A fresh :class:`DescribedData` for this robot (no closure state yet): one per user
        (the plant, the identification, a thread) that calls it beside others."""
        return DescribedData(workspace(self.tree), workspace(self.tree))

    @property
    def massless_bodies(self) -> tuple[str, ...]:
        """The bodies that move (every body of the tree does) and have no mass in the file."""
        return tuple(name for name, j in zip(self.body_names, range(1, self.model.njoints))
                     if not self.model.inertias[j].mass > 0.0)

    def _set_parameter_names(self) -> None:
        """The parameter vector's names: the bodies' ten, then the drive terms of the friction model."""
        self.parameter_names = tuple(f"{b}.{p}" for b in self.body_names for p in BODY_PARAMS) + tuple(
            f"{d}_{a}" for d in (*DRIVE_PARAMS, *self.friction.extra_terms) for a in self.actuator_names)

    def with_friction(self, friction: FrictionModel) -> DescribedRobot:
        """This robot with another friction model: the same tree (shared, with the tree's
        regressor of the motions already computed), the parameters of the new model's terms."""
        if self._tree_rows is None:
            self._tree_rows = OrderedDict()
        other = copy.copy(self)
        other.data = self.create_data()
        other.friction = friction
        other._set_parameter_names()
        bodies = self._nominal[:self._n_body]
        other._nominal = np.concatenate([bodies, other.drive_parameters()])
        other.__dict__.pop("_base", None)           # numerical base parameters: of the new columns
        return other

    def _set_actuated(self, actuated: tuple[str, ...], actuator_names: Sequence[str] | None,
                      kinds: Mapping[str, str], where: str) -> None:
        """Checks the actuated joints against the tree's (``kinds``: joint name → kind) and sets
        their names and kinds, the actuators' names, and the indices of the actuated coordinates
        in ``q`` and ``v`` (n,) and of the passive ones (nv − n,)."""
        model = self.model
        for i, name in enumerate(actuated):
            if name not in kinds:
                raise DescriptionError(f"{where}: no joint {name!r} to actuate; joints: {list(self.joint_names)}",
                                       "actuated", i)
            if name in actuated[:i]:
                raise DescriptionError(f"{where}: a joint is actuated twice: {list(actuated)}", "actuated", i)
        self.actuated_joints = actuated
        self.actuator_names = tuple(actuator_names) if actuator_names is not None else actuated
        if len(self.actuator_names) != len(actuated):
            raise DescriptionError(f"{where}: {len(self.actuator_names)} actuator names for {len(actuated)} joints")
        self.actuator_kinds = tuple(kinds[name] for name in actuated)
        ids = [model.getJointId(name) for name in actuated]
        self._act_q = np.array([model.joints[i].idx_q for i in ids])
        self._act_v = np.array([model.joints[i].idx_v for i in ids])
        self._pas_v = np.setdiff1d(np.arange(model.nv), self._act_v)
        self._pas_q = np.array([model.joints[j].idx_q for j in range(1, model.njoints)
                                if model.joints[j].idx_v in set(self._pas_v.tolist())])

    def _set_home(self, home: Mapping[str, float] | None, home_actuated: Sequence[float] | None,
                  kinds: Mapping[str, str], where: str, n: int) -> None:
        """The home guess: the tree configuration ``_home_q`` (nq,) from the joint values ``home``
        (rad, m; 0 for the joints not named) and its actuated coordinates ``_home_actuated`` (n,)."""
        model = self.model
        self._home_q = pin.neutral(model)
        for name, value in (home or {}).items():
            if name not in kinds:
                raise DescriptionError(f"{where}: home names no joint {name!r}; joints: {list(self.joint_names)}",
                                       "home")
            self._home_q[model.joints[model.getJointId(name)].idx_q] = float(value)
        self._home_actuated = (self._home_q[self._act_q].copy() if home_actuated is None
                               else np.asarray(home_actuated, dtype=float))
        if self._home_actuated.shape != (n,):
            raise DescriptionError(f"{where}: home_actuated needs {n} values, got {self._home_actuated.shape}",
                                   "home_actuated")

    # ------------------------------------------------------------------ description
    @property
    def actuated_q(self) -> np.ndarray:
        """The indices (n,) of the actuated joints in a tree configuration ``q``."""
        return self._act_q.copy()

    def _body_of(self, joint: int) -> str:
        """The name of the body a joint moves: the first body frame on it (the joint's own name
        where the file names no body, as a URDF's child link is named)."""
        for frame in self.model.frames:
            if frame.parentJoint == joint and frame.type == pin.FrameType.BODY:
                return frame.name
        return self.model.names[joint]

    def _closures(self, points, frames) -> list[Closure]:
        out = []
        for k, (constraint, rigid) in enumerate([(c, False) for c in points] + [(c, True) for c in frames]):
            name = f"closure{k + 1}"
            f1 = self.model.addFrame(pin.Frame(f"{name}_a", constraint.joint1_id, constraint.joint1_placement,
                                               pin.FrameType.OP_FRAME))
            f2 = self.model.addFrame(pin.Frame(f"{name}_b", constraint.joint2_id, constraint.joint2_placement,
                                               pin.FrameType.OP_FRAME))
            out.append(Closure(name, f1, f2, rigid))
        return out

    def _mobility_check(self) -> None:
        """The closures leave exactly ``n`` degrees of freedom at home (raises otherwise)."""
        n = len(self.actuated_joints)
        try:       # in data of its own: the robot's own data starts empty, as create_data's
            q = self.tree_configuration(self._home_actuated, self._home_q, data=self.create_data())
        except KinematicsError as exc:
            raise DescriptionError(f"{self.path}: home does not assemble ({exc}); give robot.described.home, "
                                   "the tree joint values of a configuration near it", "home") from None
        J, _ = self.closure_jacobian(q)
        rank = np.linalg.matrix_rank(J, tol=1e-9 * max(1.0, np.abs(J).max())) if J.size else 0
        if self.model.nv - rank != n:
            raise DescriptionError(f"{self.path}: the tree has {self.model.nv} joints and its closures "
                                   f"{rank} independent rows: {self.model.nv - rank} degrees of freedom at home, "
                                   f"but {n} actuated joints")

    @staticmethod
    def parameter_unit(name: str) -> str:
        """SI unit of a parameter of :attr:`parameter_names` (friction of a joint: its kind's)."""
        if "." in name:
            return _UNITS.get(name.split(".")[-1], "kg·m²")
        return " | ".join(_DRIVE_UNITS[_term(name)])

    def unit_of(self, name: str) -> str:
        """SI unit of a parameter, for this robot's actuator kinds."""
        if "." in name:
            return self.parameter_unit(name)
        actuator = name.split("_", 1)[1]
        revolute = self.actuator_kinds[self.actuator_names.index(actuator)] == REVOLUTE
        return _DRIVE_UNITS[_term(name)][0 if revolute else 1]

    def nominal_parameters(self) -> np.ndarray:
        """The description's inertias and drive terms (P,) in the order of :attr:`parameter_names`
        (:meth:`drive_parameters`: 0 where the file gives none)."""
        return self._nominal.copy()

    def drive_parameters(self) -> np.ndarray:
        """The description's drive terms of the actuated joints, the parameter vector's tail: fv,
        fc, Jm (3n,) as pinocchio reads them (MJCF joint ``damping``, ``frictionloss``,
        ``armature``; URDF ``<dynamics damping friction>``, and no armature: URDF has none), then
        0 for each of the friction model's extra terms (n each)."""
        model, v = self.model, self._act_v
        extra = np.zeros(len(self.friction.extra_terms) * len(v))
        return np.concatenate([model.damping[v], model.friction[v], model.armature[v], extra]).astype(float)

    # ------------------------------------------------------------------ closure layer
    def _batch(self, Theta, Thetad, Thetadd, guess, has_guess, want_rows: bool, data: DescribedData | None = None,
               max_iterations: int = 50, rows_out: np.ndarray | None = None):
        """The compiled closure layer over a motion (:func:`~ident_hw.model.tree_kernels.motion_batch`):
        ``(Q (N, nq), V, A (N, nv), W (N, nv, n), rows (N, n, 10 nb) or None)``. Sample ``k``
        starts Newton from ``guess[k]`` where ``has_guess[k]``, else from sample ``k - 1``.
        ``rows_out`` (N, n, P >= 10 nb, C-contiguous), if given, receives the rows in its first
        ``10 nb`` columns (the whole regressor's array: no second array of rows to copy) and is
        returned as ``rows``. ``data``: whose ``motion`` workspace carries the closure state
        (None: the robot's own).

        Raises:
            KinematicsError: a sample no assembly closes (``sample`` its index).
            SingularityError: a sample at a parallel singularity.
        """
        ws = (self.data if data is None else data).motion
        N, n, nq = len(Theta), len(self._act_v), self.model.nq
        Q, V, A, Ws = np.empty((N, nq)), np.empty((N, nq)), np.empty((N, nq)), np.empty((N, nq, n))
        if rows_out is not None:
            rows = rows_out
        else:
            rows = np.empty((N, n, self._n_body)) if want_rows else np.empty((0, n, self._n_body))
        motion_batch(self.tree.ints, self.tree.floats, ws.floats, ws.ints, np.ascontiguousarray(Theta, dtype=float), np.ascontiguousarray(Thetad, dtype=float),
                     np.ascontiguousarray(Thetadd, dtype=float), np.ascontiguousarray(guess, dtype=float),
                     np.ascontiguousarray(has_guess, dtype=np.bool_), want_rows, max_iterations, Q, V, A, Ws, rows)
        self._raise_status(ws, Theta, N > 1)
        return Q, V, A, Ws, (rows if want_rows else None)

    def _raise_status(self, ws, Theta, batch: bool) -> None:
        """Raises the error a kernel's status in ``ws`` says (nothing where it solved)."""
        code, k = ws.status
        if code == OK:
            return
        where = np.round(np.asarray(Theta, float).reshape(-1, len(self._act_v))[k], 6).tolist()
        sample = k if batch else None
        if code == SINGULAR:
            raise SingularityError(f"{self.path.name}: the closures lose rank at Theta = {where} "
                                   "(a parallel singularity)", sample=sample)
        raise KinematicsError(f"{self.path.name}: no assembly closes the loops at Theta = {where} "
                              f"(residual {ws.views(self.tree).residual[0]:.3g})", sample=sample)

    def _guesses(self, N: int, guess) -> tuple[np.ndarray, np.ndarray]:
        """Per-sample Newton starts (N, nq) and whether each is given: a row of ``guess`` that is
        all zeros (or ``guess`` None) continues from the previous sample, the first from home."""
        nq = self.model.nq
        if guess is None:
            G, has = np.zeros((N, nq)), np.zeros(N, dtype=bool)
        else:
            G = np.array(np.broadcast_to(np.asarray(guess, dtype=float), (N, nq)))
            has = np.any(G != 0.0, axis=1)
        if N and not has[0]:
            G[0], has[0] = self._home_q, True
        return G, has

    def closure_jacobian(self, q) -> tuple[np.ndarray, np.ndarray]:
        """``J`` (m, nv) of the closure residuals and the residuals (m,) at a tree configuration
        ``q`` (nq,): per closure, frame 1's Jacobian minus frame 2's (the linear velocity of its
        origin, then for a weld the angular velocity; world axes), and the position (m) and
        orientation (``-R1 log3(R1^T R2)``, rad) mismatch."""
        ws = workspace(self.tree)
        closure_at(self.tree.ints, self.tree.floats, ws.floats, ws.ints, np.ascontiguousarray(q, dtype=float))
        views = ws.views(self.tree)
        return views.J.copy(), views.r.copy()

    def tree_configuration(self, Theta, guess=None, max_iterations: int = 50, *,
                           data: DescribedData | None = None) -> np.ndarray:
        """The tree configuration ``q`` (nq,) that closes every loop at actuated coordinates
        ``Theta`` (n,), by Newton from ``guess`` (nq,; None or all zeros: the home
        configuration), which selects the assembly mode. ``data``: the caller's
        (:meth:`create_data`; None: the robot's own).

        Raises:
            KinematicsError: no configuration closes the loops from this guess (out of reach).
            SingularityError: the passive joints lose rank (a parallel singularity).
        """
        Theta = np.asarray(Theta, dtype=float).reshape(1, -1)
        G, has = self._guesses(1, None if guess is None else np.asarray(guess, dtype=float)[None])
        zero = np.zeros_like(Theta)
        return self._batch(Theta, zero, zero, G, has, False, data, max_iterations=max_iterations)[0][0]

    def _condition_at(self, J) -> float:
        """``cond(J_p)`` (2-norm) of a closure Jacobian; infinite at a parallel singularity."""
        if not self.closures:
            return 1.0
        s = np.linalg.svd(J[:, self._pas_v], compute_uv=False)
        return float(s[0] / s[-1]) if s[-1] * SINGULAR_CONDITION > s[0] else np.inf

    def tree_motion(self, Theta, Thetad, Thetadd, guess=None, *, data: DescribedData | None = None) -> TreeMotion:
        """The :class:`~ident_hw.model.motion.TreeMotion` ``(q, v, a, W)`` of one sample: the
        tree's configuration (nq,), rates (nv,) and accelerations (nv,) of an actuated motion
        (each (n,)), and ``W`` (nv, n). Newton starts
        from ``guess`` carried to ``Theta`` by the last sample's velocity map where it is near
        (``data``'s: the caller's, None: the robot's own)."""
        Theta, Thetad, Thetadd = (np.asarray(x, dtype=float).reshape(1, -1) for x in (Theta, Thetad, Thetadd))
        G, has = self._guesses(1, None if guess is None else np.asarray(guess, dtype=float)[None])
        Q, V, A, Ws, _ = self._batch(Theta, Thetad, Thetadd, G, has, False, data)
        return TreeMotion(Q[0], V[0], A[0], Ws[0])

    def condition(self, Theta, guess=None, *, data: DescribedData | None = None) -> float:
        """``cond(J_p)`` of the passive joints' closure Jacobian at ``Theta`` (1 for a serial
        robot; infinite at a parallel singularity): the distance to a singularity. ``data``: the
        caller's (None: the robot's own)."""
        try:
            q = self.tree_configuration(Theta, guess, data=data)
        except SingularityError:
            return np.inf
        return self._condition_at(self.closure_jacobian(q)[0])

    def conditions(self, poses) -> np.ndarray:
        """:meth:`condition` (N,) at closed tree configurations ``poses`` (N, nq), e.g. those of
        :meth:`pose_series` (no Newton iterations)."""
        return self.closed_conditions(poses)[1]

    def closed_conditions(self, poses) -> tuple[np.ndarray, np.ndarray]:
        """The largest closure residual (N,) (m, rad) of tree configurations ``poses`` (N, nq) and
        :meth:`condition` (N,) at each: one Jacobian per configuration, no Newton iterations (a
        trajectory's own poses checked without solving them again)."""
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        residual, cond = np.zeros(len(poses)), np.ones(len(poses))
        if not self.closures:
            return residual, cond
        ws = workspace(self.tree)
        views = ws.views(self.tree)
        Jp = np.empty((len(poses), views.J.shape[0], len(self._pas_v)))
        r = np.empty((len(poses), len(views.r)))
        for k, q in enumerate(poses):
            closure_at(self.tree.ints, self.tree.floats, ws.floats, ws.ints, np.ascontiguousarray(q))
            r[k] = views.r
            Jp[k] = views.J[:, self._pas_v]
        residual = np.max(np.abs(r), axis=1)
        s = np.linalg.svd(Jp, compute_uv=False)            # one call for the stack (same values)
        with np.errstate(divide="ignore"):
            cond = np.where(s[:, -1] * SINGULAR_CONDITION > s[:, 0], s[:, 0] / s[:, -1], np.inf)
        return residual, cond

    # ------------------------------------------------------------------ the robot interface
    def home_actuated(self) -> np.ndarray:
        """The actuated coordinates (n,) of the home pose."""
        return self._home_actuated.copy()

    def readable_base(self) -> BaseBasis:
        """The base parameters found numerically on random states (:func:`numerical_base`)."""
        if not hasattr(self, "_base"):
            self._base = numerical_base(self)
        return self._base

    def physical_bodies(self) -> tuple[PhysicalBody, ...]:
        """Each tree joint's body (:attr:`body_names`), its ten values about the joint frame."""
        return tuple(PhysicalBody(name, tuple(range(10 * k, 10 * k + 10))) for k, name in enumerate(self.body_names))

    def pose(self, Theta, guess, *, data: DescribedData | None = None) -> np.ndarray:
        """The tree configuration (nq,) of ``Theta`` (n,), from ``guess`` (nq,); ``data``: the
        caller's (None: the robot's own)."""
        return self.tree_configuration(np.asarray(Theta, dtype=float), guess, data=data)

    def pose_series(self, Theta, start, *, data: DescribedData | None = None) -> np.ndarray:
        """Tree configurations (N, nq) of ``Theta`` (N, n), each Newton started from the last
        carried to its ``Theta`` by the last velocity map (the first from ``start``); ``data``:
        the caller's (None: the robot's own)."""
        Theta = np.atleast_2d(np.asarray(Theta, dtype=float))
        G, has = self._guesses(len(Theta), None)
        if start is not None and np.any(start):
            G[0] = start
        zero = np.zeros_like(Theta)
        return self._batch(Theta, zero, zero, G, has, False, data)[0]

    def identification_regressor(self, Theta, Thetad, Thetadd, guess, *, data: DescribedData | None = None):
        """``Y`` (N, n, P) with ``tau = Y @ pi`` and the tree configurations (N, nq). The rows are
        consecutive samples of one motion where the friction model has a memory
        (:attr:`~ident_hw.model.friction.FrictionModel.history`). ``data``: the caller's (None:
        the robot's own)."""
        Theta, Thetad, Thetadd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (Theta, Thetad, Thetadd))
        N, n = Theta.shape
        guess = np.broadcast_to(np.zeros(self.model.nq) if guess is None else guess, (N, self.model.nq))
        Y = np.zeros((N, n, len(self.parameter_names)))
        poses = self._tree_regressor(Theta, Thetad, Thetadd, guess, Y, data)
        b, idx = self._n_body, np.arange(n)
        friction = self.friction.columns(Theta, Thetad)
        Y[:, idx, b + idx] = friction["fv"]
        Y[:, idx, b + n + idx] = friction["fc"]
        Y[:, idx, b + 2 * n + idx] = Thetadd
        for k, term in enumerate(self.friction.extra_terms):
            Y[:, idx, b + (3 + k) * n + idx] = friction[term]
        return Y, poses

    def _tree_regressor(self, Theta, Thetad, Thetadd, guess, Y: np.ndarray,
                        data: DescribedData | None = None) -> np.ndarray:
        """The tree's part ``W^T Y_tree`` (N, n, 10 bodies) of the regressor written into the
        first columns of ``Y`` (N, n, P, C-contiguous) and the tree configurations (N, nq) of a
        motion returned, from the cache of the motions last asked for (the same arrays give the
        same rows; a copy with another friction model shares it, under its lock)."""
        kept, key = self._tree_rows, None
        if kept is not None:
            key = hashlib.sha1(b"".join(np.ascontiguousarray(x).tobytes()
                                        for x in (Theta, Thetad, Thetadd, guess))).digest()
            with self._tree_rows_lock:
                hit = kept.get(key)
                if hit is not None:
                    kept.move_to_end(key)
            if hit is not None:
                rows, poses = hit
                Y[:, :, :self._n_body] = rows
                return poses.copy()
        G, has = self._guesses(len(Theta), guess)
        poses, _, _, _, _ = self._batch(Theta, Thetad, Thetadd, G, has, True, data, rows_out=Y)
        if kept is None:
            return poses
        with self._tree_rows_lock:
            kept[key] = (Y[:, :, :self._n_body].copy(), poses)
            while len(kept) > TREE_ROWS_KEPT:
                kept.popitem(last=False)
        return poses.copy()

    def energy_regressor(self, Theta, Thetad, guess=None, *, data: DescribedData | None = None) -> np.ndarray:
        """``H`` (N, P) with the robot's energy ``E = H @ pi``: the tree's kinetic plus potential
        energy of the bodies (J) and the rotors' ``Jm Thetad² / 2``; the friction columns are zero.
        ``data``: the caller's (None: the robot's own)."""
        Theta, Thetad = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (Theta, Thetad))
        N, n = Theta.shape
        H = np.zeros((N, len(self.parameter_names)))
        Q, V, _, _, _ = self._batch(Theta, Thetad, np.zeros_like(Theta), *self._guesses(N, guess), False, data)
        scratch = self.model.createData()           # pinocchio's data of this call only
        for k, (q, v) in enumerate(zip(Q, V)):
            H[k, :self._n_body] = (pin.computeKineticEnergyRegressor(self.model, scratch, q, v)
                                   + pin.computePotentialEnergyRegressor(self.model, scratch, q))
        H[:, self._n_body + 2 * n:self._n_body + 3 * n] = 0.5 * Thetad**2
        return H

    def plant_dynamics(self, Theta, Thetad, params, guess, *, data: DescribedData | None = None) -> PlantState:
        """``M`` (n, n) (rotor inertias included), the bias forces (n,) (velocity terms and
        gravity, no friction) and the tree configuration (nq,) of one state (a
        :class:`~ident_hw.model.interface.PlantState`, its pose the tree configuration), compiled
        (:func:`~ident_hw.model.tree_kernels.plant_dynamics`): Newton starts from ``guess`` (the
        plant's last pose) carried to ``Theta`` by the plant's last velocity map (``data``'s
        ``plant`` workspace: the caller's, None: the robot's own). ``params`` (P,) are read,
        never stored: the robot keeps its nominal ones."""
        pi = np.asarray(params, dtype=float)
        n, b = len(self._act_v), self._n_body
        ws = (self.data if data is None else data).plant
        guess = np.zeros(self.model.nq) if guess is None else np.ascontiguousarray(guess, dtype=float)
        has = bool(np.any(guess))
        if not has and not ws.last_valid:
            guess, has = self._home_q, True
        q, M, bias = np.empty(self.model.nq), np.empty((n, n)), np.empty(n)
        tree = self.tree
        tree_plant_dynamics(tree.ints, tree.floats, ws.floats, ws.ints, np.ascontiguousarray(Theta, dtype=float),
                            np.ascontiguousarray(Thetad, dtype=float), guess, has, np.ascontiguousarray(pi[:b]),
                            np.ascontiguousarray(pi[b + 2 * n:b + 3 * n]), 50, q, M, bias)
        self._raise_status(ws, Theta, False)
        return PlantState(M, bias, q)

    def friction_coefficients(self, params):
        """``f_v``, ``f_c`` (n,) each from the parameter vector."""
        pi, b, n = np.asarray(params, dtype=float), self._n_body, len(self._act_v)
        return pi[b:b + n].copy(), pi[b + n:b + 2 * n].copy()

    def payload_indices(self) -> tuple[int, ...]:
        """The ten parameter indices (:data:`BODY_PARAMS` order) of the body that carries the
        end-effector: a payload's inertial values add to them (about that body's joint frame)."""
        if self.end_effector is None:
            raise ValueError(f"{self.path.name}: a payload needs the robot's end_effector (a body or site)")
        joint = self.model.frames[self.model.getFrameId(self.end_effector)].parentJoint
        return tuple(range(10 * (joint - 1), 10 * joint))

    def with_payload(self, params, mass: float, inertia: float = 0.0) -> np.ndarray:
        """``params`` with a payload on the end-effector (a body or a site of the description):
        ``mass`` kg at its origin and ``inertia`` kg·m² about its z axis, added to the parameters
        of the body that carries it."""
        if self.end_effector is None:
            raise ValueError(f"{self.path.name}: a payload needs the robot's end_effector (a body or site)")
        frame = self.model.frames[self.model.getFrameId(self.end_effector)]
        c, R = frame.placement.translation, frame.placement.rotation
        payload = pin.Inertia(mass, c, R @ np.diag([0.0, 0.0, inertia]) @ R.T).toDynamicParameters()
        pi = np.array(params, dtype=float)
        start = 10 * (frame.parentJoint - 1)
        pi[start:start + 10] += payload
        return pi


def _term(name: str) -> str:
    """The drive term of a drive parameter's name (``fc3_elbow``: a Maxwell-slip element's Coulomb
    force, ``fc``)."""
    head = name.split("_", 1)[0]
    return "fc" if head.startswith("fc") else head


def random_states(robot: DescribedRobot, samples: int, spread: float = 0.15, seed: int = 0):
    """``(Theta, Thetad, Thetadd)`` (each (N, n)) of ``samples`` random assembled states about
    home: positions within ``spread`` (rad or m) of it, rates of order one; states that do not
    assemble are drawn again (each from home, in data of its own: the robot's is left as it was)."""
    rng = np.random.default_rng(seed)
    data = robot.create_data()
    home = robot.home_actuated()
    n = len(home)
    rows = []
    for _ in range(50 * samples):
        Theta = home + spread * rng.uniform(-1, 1, n)
        try:
            if not np.isfinite(robot.condition(Theta, data=data)):     # assembles, away from a singularity
                continue
        except KinematicsError:
            continue
        rows.append((Theta, rng.normal(size=n), rng.normal(size=n)))
        if len(rows) == samples:
            break
    if len(rows) < samples:
        raise KinematicsError(f"{robot.path.name}: only {len(rows)} of {samples} random states about home assemble")
    return tuple(np.array(x) for x in zip(*rows))


def numerical_base(robot: DescribedRobot, samples: int = 60, seed: int = 0, rtol: float = 1e-5) -> BaseBasis:
    """The base parameters of ``robot``: QR with column pivoting of its regressor on
    ``samples`` random states (:func:`random_states`), columns scaled to unit norm; the
    independent columns are kept, each dependent one is regrouped into them
    (``pi_b = pi_1 + R11^-1 R12 pi_2``). Combinations are rounded to 1e-10 of their scale.

    ``rtol``: a column whose part independent of the kept ones is below this fraction of the
    first pivot is dependent. Such a direction moves the forces by less than any drive
    measures: the Delta's universal-joint crosses give three at 2e-6 (their first moments,
    which the hand model, without crosses, does not have); kept, they would take rod parameters
    into combinations no data can separate."""
    from scipy.linalg import qr, solve_triangular

    Theta, Thetad, Thetadd = random_states(robot, samples, seed=seed)
    data = robot.create_data()              # its own: the robot's data is left as it was
    home = robot.pose(robot.home_actuated(), None, data=data)
    Y, _ = robot.identification_regressor(Theta, Thetad, Thetadd, np.tile(home, (samples, 1)), data=data)
    A = Y.reshape(-1, Y.shape[-1])
    norms = np.linalg.norm(A, axis=0)
    used = norms > 1e-12 * norms.max()             # a column of rounding errors: a parameter nothing moves
    cols = np.flatnonzero(used)
    As = A[:, cols] / norms[cols]
    # columns equal to rounding (a rotor's inertia and its link's, one link's inertia and the next
    # one's mass times a length squared) tie: the earlier parameter in the vector is kept, whatever
    # the last bits of the regressor, so that a combination keeps its name from one build to the next
    tie_break = 1.0 + 1e-9 * (len(cols) - np.arange(len(cols))) / len(cols)
    _, _, perm = qr(As * tie_break, mode="economic", pivoting=True)
    R = qr(As[:, perm], mode="r")[0][:len(cols)]
    diag = np.abs(np.diag(R))
    rank = int(np.sum(diag > rtol * diag[0]))
    independent, dependent = cols[perm[:rank]], cols[perm[rank:]]
    beta = solve_triangular(R[:rank, :rank], R[:rank, rank:])          # scaled columns
    kept_columns = As[:, perm[:rank]]
    for j in range(beta.shape[1]):
        # the regrouping written with the kept columns it needs: a column dependent only to rtol
        # (not exactly) gets least-squares coefficients on every kept column, most of them fits of
        # its 1e-6 remainder; refitted on those above 1e-3 of its largest, if that fits as well
        b = beta[:, j]
        support = np.abs(b) >= 1e-3 * np.abs(b).max()
        target = As[:, perm[rank + j]]
        sparse = np.linalg.lstsq(kept_columns[:, support], target, rcond=None)[0]
        full_fit = np.linalg.norm(kept_columns @ b - target)
        if np.linalg.norm(kept_columns[:, support] @ sparse - target) <= 2 * full_fit + 1e-12:
            beta[:, j] = 0.0
            beta[support, j] = sparse
    beta = beta * norms[dependent][None, :] / norms[independent][:, None]
    beta[np.abs(beta) < 1e-10 * max(1.0, np.abs(beta).max())] = 0.0
    order = np.argsort(independent)
    H = np.zeros((rank, Y.shape[-1]))
    for row, i in enumerate(order):
        H[row, independent[i]] = 1.0
        H[row, dependent] = beta[i]
    kept = tuple(robot.parameter_names[independent[i]] for i in order)
    return BaseBasis(tuple(robot.parameter_names), kept, H)

