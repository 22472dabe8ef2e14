"""What the rest of the project may ask of a robot model: :class:`RobotModel`.

A robot is ``n`` actuated coordinates ``Theta`` (rad or m, in actuator order), a pose (the
end-effector's coordinates, from the forward kinematics) and parameters ``params`` whose meaning
only the model knows (a vector in the order of ``parameter_names`` for the regressor). The
simulated rig's plant (:mod:`drivers.sim.plant`) moves any robot through these members, the
offline identification (:mod:`ident_hw.experiment.offline`) builds its regressor through them;
the 3PRRR (:class:`ident_hw.model.ThreePRRR`) and the Delta (:class:`ident_hw.model.Delta`)
implement them. Everything is SI: rad, m, N·m, N, kg, s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from .base_basis import BaseBasis

#: the kinds of actuated joint, and the SI units of their position and force. The drive side
#: names its axes' kinds with the same two words (:data:`drivers.units.REVOLUTE`): the model
#: imports nothing of the project and the drivers nothing of ident_hw, so each layer keeps its
#: own pair, and tests/test_layers.py checks that the two agree (the config compares them).
REVOLUTE, PRISMATIC = "revolute", "prismatic"
POSITION_UNITS = {REVOLUTE: "rad", PRISMATIC: "m"}
FORCE_UNITS = {REVOLUTE: "N·m", PRISMATIC: "N"}


@dataclass(frozen=True, slots=True, init=False)
class PlantState:
    """The dynamics in the actuated coordinates at one state (:meth:`RobotModel.plant_dynamics`):
    ``M(Theta) Thetadd + bias + friction = tau``. Built once per SYNC period by the simulated
    rig's plant, hence slots, and an ``__init__`` that writes the slots itself.

    Attributes:
        M: ``(n, n)`` the mass matrix (kg, kg·m, kg·m² blocks).
        bias: ``(n,)`` the bias forces, N·m or N: velocity terms and gravity, without friction.
        pose: ``(pose_size,)`` the pose at ``Theta``: the guess the next state starts from.
    """

    M: np.ndarray
    bias: np.ndarray
    pose: np.ndarray

    def __init__(self, M: np.ndarray, bias: np.ndarray, pose: np.ndarray) -> None:
        # each field's slot written by its descriptor: the generated frozen __init__ goes through
        # object.__setattr__ per field, 0.4 µs a record against 0.25 (some 3 % of the 3PRRR's
        # plant_dynamics, issue 49); the record stays frozen (setting a field raises)
        _SET_M(self, M)
        _SET_BIAS(self, bias)
        _SET_POSE(self, pose)


_SET_M, _SET_BIAS, _SET_POSE = (getattr(PlantState, name).__set__ for name in ("M", "bias", "pose"))


@runtime_checkable
class RobotModel(Protocol):
    """A robot as the plant of the simulated rig sees it.

    Attributes:
        actuator_names: one name per actuated coordinate, in actuator order (``n`` of them).
        actuator_kinds: :data:`REVOLUTE` or :data:`PRISMATIC` per actuator.
        parameter_names: the names of the model's parameters, in the order of its regressor.
        pose_size: number of pose coordinates.
        coulomb_width: velocity scale (rad/s, m/s) of the smooth Coulomb sign ``tanh(qd / w)``.
    """

    actuator_names: tuple[str, ...]
    actuator_kinds: tuple[str, ...]
    parameter_names: tuple[str, ...]
    pose_size: int
    coulomb_width: float

    def parameter_unit(self, name: str) -> str:
        """SI unit of parameter ``name`` (one of ``parameter_names``)."""

    def readable_base(self) -> BaseBasis | None:
        """The model's own base parameters (``pi_b = H pi`` over :attr:`parameter_names`) written
        as readable combinations, for data that excites all of them; None: found by SVD from the data."""

    def physical_bodies(self) -> tuple:
        """Where each body's inertial values sit in the parameter vector
        (:class:`~ident_hw.model.pseudo_inertia.PhysicalBody`, for the physical-consistency
        constraints); every parameter outside them is a drive term (friction, rotor inertia)."""

    def home_actuated(self) -> np.ndarray:
        """The actuated coordinates (n,) of the robot's home pose."""

    def pose(self, Theta, guess) -> np.ndarray:
        """The pose (pose_size,) of actuated coordinates ``Theta`` (n,); ``guess`` (pose_size,)
        selects the assembly mode where there are several (the last pose of a series)."""

    def pose_series(self, Theta, start) -> np.ndarray:
        """Poses (N, pose_size) of actuated coordinates ``Theta`` (N, n) along a continuous
        series, starting the assembly-mode choice from ``start`` (pose_size,)."""

    def identification_regressor(self, Theta, Thetad, Thetadd, guess) -> tuple[np.ndarray, np.ndarray]:
        """``Y`` (N, n, len(parameter_names)) with ``tau = Y @ params`` of a measured actuated
        motion (each (N, n)), and the poses (N, pose_size); ``guess`` (N, pose_size) per sample."""

    def plant_dynamics(self, Theta, Thetad, params: Any, guess) -> PlantState:
        """The dynamics in the actuated coordinates at one state: ``M(Theta) Thetadd + bias + friction = tau``
        (a :class:`PlantState`: the mass matrix ``M`` (n, n), the bias forces (n,), the pose
        (pose_size,)).

        Raises:
            KinematicsError: no pose closes the chains at ``Theta``.
        """

    def friction_coefficients(self, params: Any) -> tuple[np.ndarray, np.ndarray]:
        """Viscous ``f_v`` and Coulomb ``f_c`` coefficients (n,) each: the friction force of
        actuator ``j`` is ``f_v[j] Thetad[j] + f_c[j] tanh(Thetad[j] / coulomb_width)``."""

    def with_payload(self, params: Any, mass: float, inertia: float) -> Any:
        """``params`` with a payload added at the end-effector point: ``mass`` kg, ``inertia``
        kg·m² about the axis the robot's end-effector turns about (its vertical axis)."""
