"""The sections of one actuator of ``robot.actuators``: a motor and its drive, its joint-side
limits and its homing (the drive driver's :class:`drivers.axis.HomingConfig`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from drivers.axis import HomingConfig
from drivers.cia import NODE_ID_MAX, NODE_ID_MIN

from .schema import in_range, non_negative, ordered_pair, positive, spec

__all__ = ["ActuatorConfig", "HomingConfig", "LimitsConfig"]


@dataclass(frozen=True)
class LimitsConfig:
    """Joint-side limits of one actuator: rad / m, rad/s / m/s, rad/s² / m/s², motor current A."""

    position: tuple[float, float] = field(metadata=spec(ordered_pair, unit="rad | m"))
    velocity: float = field(metadata=spec(positive, unit="rad/s | m/s"))
    acceleration: float = field(metadata=spec(positive, unit="rad/s^2 | m/s^2"))
    current: float = field(metadata=spec(positive, unit="A"))
    following_error: float = field(metadata=spec(positive, unit="rad | m"))


@dataclass(frozen=True)
class ActuatorConfig:
    """One motor + drive, in the robot's actuator order (the 3PRRR: theta1..3, zeta1..3).

    ``node_id``, ``profile`` and ``homing`` describe the drive on the bus: a config with a
    ``bus`` section needs the first two (its check says so); a config that only identifies
    recordings made elsewhere (a robot whose drives the tool does not talk to) may leave them
    out. ``torque_constant`` × ``gear_ratio`` is then the joint force per motor ampere of the
    recordings (a drive gain), ``counts_per_turn`` the resolution their positions were read at."""

    name: str
    kind: Literal["revolute", "prismatic"]
    torque_constant: float = field(metadata=spec(positive, unit="N m/A"))
    counts_per_turn: int = field(metadata=spec(positive, doc="quadrature counts per motor turn"))
    limits: LimitsConfig
    node_id: int | None = field(default=None, metadata=spec(in_range(NODE_ID_MIN, NODE_ID_MAX)))
    profile: Literal["epos2", "epos4"] | None = None
    homing: HomingConfig | None = None
    gear_ratio: float = field(default=1.0, metadata=spec(positive, doc="motor turns per joint turn"))
    screw_lead: float | None = field(default=None, metadata=spec(positive, unit="m per motor turn"))
    product_code: int | None = field(default=None, metadata=spec(non_negative, doc="expected 0x1018:02"))
    object_dictionary: str | None = field(default=None, metadata=spec(
        doc="the drive's EDS or DCF (maxon's, or saved from the drive), relative to the config file; "
            "default: the built-in dictionary of the profile"))
    joint: str | None = field(default=None, metadata=spec(
        doc="a described robot's joint this actuator drives (default: its name)"))
