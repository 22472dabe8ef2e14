"""The ``robot`` section: which robot, its kind's sections, its safety margins and actuators."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from .actuators import ActuatorConfig
from .friction import FrictionConfig
from .robot_3prrr import GeometryConfig, InertialConfig
from .robot_delta import DeltaConfig
from .robot_described import DescribedConfig
from .schema import in_range, positive, spec


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

    ``3prrr``: ``geometry``, carriage ``stroke``, ``cad`` values, ``safety`` margins and six
    actuators theta1..3, zeta1..3. ``delta``: the ``delta`` section (geometry, CAD parameters)
    and three revolute actuators q1..3. ``described``: the ``described`` section (the
    description file, home, CAD parameters) and one actuator per driven joint. ``friction``: the
    joints' friction model (:class:`~ident_hw.config.friction.FrictionConfig`; other than the
    default Coulomb and viscous terms for described robots only).
    """

    actuators: tuple[ActuatorConfig, ...]
    kind: Literal["3prrr", "delta", "described"] = "3prrr"
    geometry: GeometryConfig | None = None
    stroke: float | None = field(default=None, metadata=spec(positive, unit="m", doc="carriage travel +- stroke"))
    cad: InertialConfig | None = None
    delta: DeltaConfig | None = None
    described: DescribedConfig | None = None
    safety: SafetyConfig = SafetyConfig()
    coulomb_width: float = field(default=1e-3, metadata=spec(positive, unit="rad/s | m/s"))
    friction: FrictionConfig = FrictionConfig()
