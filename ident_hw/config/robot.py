"""The ``robot`` section: which robot, its kind's sections, its safety margins and actuators."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Literal

from .actuators import ActuatorConfig
from .friction import FrictionConfig
from .robot_described import DescribedConfig
from .schema import in_range, positive, spec


def _plus_minus_one(value) -> None:
    if any(v not in (1, -1) for v in value):
        raise ValueError(f"expected +1 or -1 for each chain, got {list(value)}")


@dataclass(frozen=True)
class SafetyConfig:
    """Thresholds of the feasibility check: distance to parallel and serial singularities."""

    max_cond_A: float = field(default=50.0, metadata=spec(positive))
    min_serial_margin: float = field(default=0.1, metadata=spec(in_range(0.0, 1.0),
                                     doc="smallest |sin(beta_i - theta_i)|"))


@dataclass(frozen=True)
class RobotConfig:
    """The rig: which robot (``kind``, a kind of :mod:`ident_hw.config.robots`), its model's
    settings and its actuators.

    ``3prrr``: its ``description`` file (geometry and CAD values, ``configs/robots/3prrr.xml``),
    the chains' assembly ``modes``, carriage ``stroke``, ``safety`` margins and six actuators
    theta1..3, zeta1..3. ``delta``: its ``description`` file (``configs/robots/delta.xml``),
    ``safety`` and three revolute actuators q1..3. ``described``: its ``description`` file (MJCF or
    URDF), the optional ``described`` section (home, end-effector, CAD parameters) and one actuator
    per driven joint. ``friction``: the
    joints' friction model (:class:`~ident_hw.config.friction.FrictionConfig`; other than the
    default Coulomb and viscous terms for described robots only).
    """

    #: keys of earlier versions and what replaced them (the schema's error names it)
    RETIRED_KEYS: ClassVar[dict[str, str]] = {
        "geometry": "the 3PRRR's geometry is read from its description file: write `description: "
                    "robots/3prrr.xml` (the shipped file, relative to configs/; edit its values for another "
                    "geometry) and `modes: [1, 1, 1]` for the chains' elbows",
        "cad": "the 3PRRR's CAD values are the bodies of its description file (`description:`, e.g. "
               "robots/3prrr.xml); CAD friction is its joints' damping and frictionloss",
        "delta": "the Delta is read from its description file: write `description: robots/delta.xml` (geometry "
                 "and bodies; the rotor inertias Jm are its arms' joint armature, CAD friction their damping and "
                 "frictionloss; `factors` of the CAD values: edit the file)"}

    actuators: tuple[ActuatorConfig, ...]
    kind: Literal["3prrr", "delta", "described"] = "3prrr"
    description: str | None = field(default=None, metadata=spec(path=True, doc=(
        "the robot's description file, MJCF (.xml) or URDF (.urdf), relative to this file")))
    modes: tuple[int, int, int] | None = field(default=None, metadata=spec(
        _plus_minus_one, doc="the 3PRRR's working mode (elbow sign) of each chain; default [1, 1, 1]"))
    stroke: float | None = field(default=None, metadata=spec(positive, unit="m", doc="carriage travel +- stroke"))
    described: DescribedConfig | None = None
    safety: SafetyConfig = SafetyConfig()
    coulomb_width: float = field(default=1e-3, metadata=spec(positive, unit="rad/s | m/s"))
    friction: FrictionConfig = FrictionConfig()

    @property
    def described_settings(self) -> DescribedConfig:
        """The ``described`` section, or its defaults where the file leaves it out."""
        return self.described if self.described is not None else DescribedConfig()
