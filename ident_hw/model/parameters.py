"""Geometry and dynamic parameters of the 3PRRR (conventions of ``docs/3prrr-model.md``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Actuated coordinates, in the order of every (N, 6) array of the project.
ACTUATOR_NAMES = ("theta1", "theta2", "theta3", "zeta1", "zeta2", "zeta3")

#: the 3PRRR's seven inertial parameters (kg, kg·m²)
INERTIAL_NAMES = ("m_c", "m_l1", "I_l1", "m_l2", "I_l2", "m_ee", "I_ee")
FRICTION_NAMES = tuple(f"fv_{a}" for a in ACTUATOR_NAMES) + tuple(f"fc_{a}" for a in ACTUATOR_NAMES)


@dataclass(frozen=True)
class Geometry:
    """Geometry of the 3PRRR (lengths in m, angles in rad).

    Args:
        l1, l2: lengths of links ``A_i B_i`` and ``B_i C_i``.
        s1, s2: distance from ``A_i`` (``B_i``) to the centre of mass of link 1 (link 2).
        h: radius of the platform joints ``C_i`` around the end-effector point.
        a: offset of guide ``i`` from the origin along ``gamma_i + pi/2``.
        gamma: direction angles of the three linear guides.
        modes: working mode (elbow) of each chain, ``+1`` or ``-1``: the sign of eq. 6.
    """

    l1: float
    l2: float
    s1: float
    s2: float
    h: float
    a: float
    gamma: tuple[float, float, float]
    modes: tuple[int, int, int] = (1, 1, 1)

    def __post_init__(self) -> None:
        for name in ("l1", "l2", "h", "a"):
            if not getattr(self, name) > 0:
                raise ValueError(f"Geometry.{name} must be positive, got {getattr(self, name)}")
        for name in ("s1", "s2"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"Geometry.{name} must be non-negative, got {getattr(self, name)}")
        if len(self.gamma) != 3:
            raise ValueError(f"Geometry.gamma needs 3 angles, got {self.gamma}")
        if len(self.modes) != 3 or any(m not in (1, -1) for m in self.modes):
            raise ValueError(f"Geometry.modes must be three values of +1 or -1, got {self.modes}")
        object.__setattr__(self, "gamma", tuple(float(g) for g in self.gamma))
        object.__setattr__(self, "modes", tuple(int(m) for m in self.modes))


@dataclass(frozen=True)
class InertialParams:
    """Dynamic parameters: inertial (kg, kg·m²) and per-actuator friction.

    Inertias are about each body's centre of mass. One set of carriage and link values serves
    the three chains (the robot is symmetric). ``m_c`` is the apparent carriage mass, including
    the screw and rotor inertia reflected through ``2 pi / p``.

    Friction, per actuator in the order ``theta1..3, zeta1..3``: viscous ``f_v`` (N·m·s/rad for
    the links, N·s/m for the carriages) and Coulomb ``f_c`` (N·m, N), applied as
    ``f_v qdot + f_c tanh(qdot / w)``.
    """

    m_c: float
    m_l1: float
    I_l1: float
    m_l2: float
    I_l2: float
    m_ee: float
    I_ee: float
    f_v: tuple[float, ...] = field(default=(0.0,) * 6)
    f_c: tuple[float, ...] = field(default=(0.0,) * 6)

    #: the 19 parameters in the order of :meth:`as_vector`
    NAMES = INERTIAL_NAMES + FRICTION_NAMES

    def __post_init__(self) -> None:
        for name in ("f_v", "f_c"):
            value = tuple(float(v) for v in np.broadcast_to(getattr(self, name), (6,)))
            object.__setattr__(self, name, value)

    def as_vector(self) -> np.ndarray:
        """Parameter vector ``pi`` (19,), in the order of :attr:`NAMES`."""
        inertial = [getattr(self, name) for name in INERTIAL_NAMES]
        return np.array(inertial + list(self.f_v) + list(self.f_c), dtype=float)

    @classmethod
    def from_vector(cls, vector) -> InertialParams:
        """Inverse of :meth:`as_vector`; ``vector`` has 19 entries."""
        v = np.asarray(vector, dtype=float)
        if v.shape != (len(cls.NAMES),):
            raise ValueError(f"expected a vector of {len(cls.NAMES)} parameters, got shape {v.shape}")
        return cls(**dict(zip(INERTIAL_NAMES, v[:7])), f_v=tuple(v[7:13]), f_c=tuple(v[13:19]))

    def replace(self, **changes) -> InertialParams:
        """A copy with some fields changed (for example a payload added to ``m_ee``)."""
        values = {name: getattr(self, name) for name in INERTIAL_NAMES + ("f_v", "f_c")}
        values.update(changes)
        return type(self)(**values)
