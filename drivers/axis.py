"""Configuration of one drive axis, in SI units (the experiment runner builds it from YAML)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from drivers.cia import is_node_id
from drivers.errors import ConfigError
from drivers.profiles import DriveProfile, get_profile
from drivers.units import AxisScaling


@dataclass(frozen=True)
class HomingConfig:
    """CiA 402 homing of one axis, joint side (also the ``homing:`` section of a config file:
    the field metadata gives each key's SI unit).

    Args:
        method: homing method (0x6098, I8), e.g. 35/37 "actual position", 17/18 limit switches.
        offset: joint position at home in rad or m (the maxon "home position", 0x2081 on
            the EPOS2, 0x30B0 on the EPOS4, which the drive assigns when homing completes).
        switch_speed: speed of the switch search in rad/s or m/s.
        zero_speed: speed of the zero search in rad/s or m/s.
        acceleration: homing acceleration in rad/s² or m/s².
        timeout: s to wait for "homing attained".
    """

    method: int
    offset: float = field(default=0.0, metadata={"unit": "rad | m"})
    switch_speed: float = field(default=0.1, metadata={"unit": "rad/s | m/s"})
    zero_speed: float = field(default=0.01, metadata={"unit": "rad/s | m/s"})
    acceleration: float = field(default=1.0, metadata={"unit": "rad/s^2 | m/s^2"})
    timeout: float = field(default=30.0, metadata={"unit": "s"})

    def __post_init__(self) -> None:
        if not -128 <= self.method <= 127:
            raise ConfigError(f"homing method: expected an I8 (-128..127), got {self.method}")
        for name in ("switch_speed", "zero_speed", "acceleration", "timeout"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"homing {name}: expected a positive value, got {getattr(self, name)}")


@dataclass(frozen=True)
class AxisConfig:
    """One drive: where it is on the bus, what it is, how it scales and its limits (SI).

    Args:
        name: axis name used in messages and recordings (``"theta1"``, ``"zeta2"``, ...).
        node_id: CANopen node-ID 1..127.
        profile: drive generation, ``"epos2"`` or ``"epos4"``.
        scaling: drive units <-> SI of this axis.
        position_min, position_max: software position limits in rad or m.
        max_velocity: max profile velocity in rad/s or m/s.
        max_current: output current limit in A.
        following_error_window: max following error in rad or m.
        product_code: expected 0x1018:02; ``None`` accepts any maxon product of the generation.
        homing: homing settings, ``None`` if the axis is not homed.
        object_dictionary: the drive's EDS or DCF file, whose dictionary the master then uses
            (``None``: the built-in one of ``profile``).
    """

    name: str
    node_id: int
    profile: str
    scaling: AxisScaling
    position_min: float
    position_max: float
    max_velocity: float
    max_current: float
    following_error_window: float
    product_code: int | None = None
    homing: HomingConfig | None = None
    object_dictionary: str | None = None

    def __post_init__(self) -> None:
        where = f"axis {self.name!r}"
        if not is_node_id(self.node_id):
            raise ConfigError(f"{where}: node_id must be an integer in 1..127, got {self.node_id!r}")
        try:
            get_profile(self.profile)
        except ValueError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        if not (math.isfinite(self.position_min) and math.isfinite(self.position_max)
                and self.position_min < self.position_max):
            raise ConfigError(f"{where}: need position_min < position_max, got "
                              f"{self.position_min!r}, {self.position_max!r}")
        for key in ("max_velocity", "max_current", "following_error_window"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{where}: {key} must be positive, got {value!r}")

    @property
    def drive_profile(self) -> DriveProfile:
        return get_profile(self.profile)

    @property
    def label(self) -> str:
        """``"node 3 (theta1)"``: how messages name this drive."""
        return f"node {self.node_id} ({self.name})"
