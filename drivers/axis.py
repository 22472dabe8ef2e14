"""Configuration of one drive axis, in SI units (the experiment runner builds it from YAML)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from drivers.cia import is_node_id
from drivers.errors import ConfigError
from drivers.profiles import AVERAGED, CURRENTS, INSTANTANEOUS, DriveProfile, get_profile  # noqa: F401
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
        current: the motor current the master streams, ``"instantaneous"`` or ``"averaged"`` (:data:`drivers.profiles.CURRENTS`)
            (:meth:`drivers.profiles.DriveProfile.streamed_current`).
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
    current: str = INSTANTANEOUS

    def __post_init__(self) -> None:
        where = f"axis {self.name!r}"
        if self.current not in CURRENTS:
            raise ConfigError(f"{where}: current must be one of {CURRENTS}, got {self.current!r}")
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


def outside_position_limits(axes: Sequence[AxisConfig], positions: np.ndarray) -> np.ndarray:
    """``(n, len(axes))`` mask of the ``positions`` (rad | m, one column per axis) outside their
    axis' software position limits ``[position_min, position_max]`` (a limit itself is inside).

    The one test of a set-point against the limits: :meth:`drivers.epos.DriveGroup.run_cyclic`
    applies it (:func:`check_setpoints`) before it streams, and the campaign's check before any
    bus is opened (``ident_hw.experiment.plan``), so that the two cannot disagree."""
    low = np.array([a.position_min for a in axes])
    high = np.array([a.position_max for a in axes])
    return (positions < low) | (positions > high)


def check_setpoints(axes: Sequence[AxisConfig], targets: np.ndarray, what: str) -> None:
    """``targets`` (n, len(axes)) rad | m: n >= 1 rows of finite values, each within its axis'
    limits (:func:`outside_position_limits`); :class:`ConfigError` naming the first axis and
    sample that is not (``what``: what the targets are, for the message)."""
    if targets.ndim != 2 or targets.shape[1] != len(axes) or len(targets) == 0:
        raise ConfigError(f"{what}: expected shape (n, {len(axes)}), got {targets.shape}")
    if not np.all(np.isfinite(targets)):
        row, col = np.argwhere(~np.isfinite(targets))[0]
        raise ConfigError(f"{what}: non-finite value at sample {row}, axis {axes[col].name!r}")
    outside = outside_position_limits(axes, targets)
    for i, a in enumerate(axes):
        bad = np.flatnonzero(outside[:, i])
        if bad.size:
            raise ConfigError(f"{what}: axis {a.name!r} sample {bad[0]} = {targets[bad[0], i]:.6g} "
                              f"outside its limits [{a.position_min:g}, {a.position_max:g}]")
