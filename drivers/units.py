"""Conversion between drive units (quadrature counts, rpm, mA) and SI units.

This is the only place where drive units meet SI units. Joint-side SI units are rad, rad/s
for a revolute axis and m, m/s for a prismatic (screw-driven carriage) axis; motor current
is in A. Forces are N·m (revolute, at the link) or N (prismatic, at the carriage).
:class:`AxisScaling` converts one axis; :class:`AxesScaling` the columns of arrays
(samples × axes) of several.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

#: the kinds of axis; the robot model names its actuated joints with the same two words
#: (``ident_hw.model.interface``), which the drivers may not import: tests/test_layers.py checks
#: that the two pairs agree
REVOLUTE = "revolute"
PRISMATIC = "prismatic"
#: drive current unit per A
MA_PER_AMP = 1e3


@dataclass(frozen=True)
class AxisScaling:
    """Scaling of one axis between the motor (drive units) and the joint (SI).

    Args:
        kind: ``"revolute"`` (motor + gearhead on a link) or ``"prismatic"`` (motor on a
            lead screw driving a carriage).
        counts_per_turn: quadrature counts per motor turn (4 × encoder pulses per turn).
        torque_constant: motor torque constant ``K_m`` in N·m/A.
        gear_ratio: motor turns per joint turn (revolute); 1 for a direct screw.
        screw_lead: carriage travel per motor turn in m (prismatic only).
    """

    kind: str
    counts_per_turn: int
    torque_constant: float
    gear_ratio: float = 1.0
    screw_lead: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in (REVOLUTE, PRISMATIC):
            raise ValueError(f"axis kind must be {REVOLUTE!r} or {PRISMATIC!r}, got {self.kind!r}")
        if self.counts_per_turn <= 0:
            raise ValueError(f"counts_per_turn must be positive, got {self.counts_per_turn}")
        if self.torque_constant <= 0:
            raise ValueError(f"torque_constant must be positive, got {self.torque_constant}")
        if self.gear_ratio <= 0:
            raise ValueError(f"gear_ratio must be positive, got {self.gear_ratio}")
        if self.kind == PRISMATIC and not (self.screw_lead and self.screw_lead > 0):
            raise ValueError(f"a prismatic axis needs a positive screw_lead, got {self.screw_lead}")

    @property
    def motor_turns_per_unit(self) -> float:
        """Motor turns per rad (revolute) or per m (prismatic)."""
        if self.kind == REVOLUTE:
            return self.gear_ratio / (2.0 * math.pi)
        assert self.screw_lead is not None      # a prismatic axis has one (__post_init__)
        return self.gear_ratio / self.screw_lead

    @property
    def counts_per_unit(self) -> float:
        """Quadrature counts per rad (revolute) or per m (prismatic)."""
        return self.counts_per_turn * self.motor_turns_per_unit

    @property
    def rpm_per_unit_velocity(self) -> float:
        """Motor rpm per rad/s (revolute) or per m/s (prismatic)."""
        return 60.0 * self.motor_turns_per_unit

    @property
    def force_per_amp(self) -> float:
        """Joint force per motor current: N·m/A (revolute) or N/A (prismatic).

        Revolute: ``K_m · gear``. Prismatic: ``K_m · gear · 2π / p`` (the 3PRRR paper, eqs. 37–38).
        """
        return self.torque_constant * 2.0 * math.pi * self.motor_turns_per_unit

    # drive units -> SI
    def position_from_counts(self, counts):
        return counts / self.counts_per_unit

    def velocity_from_rpm(self, rpm):
        return rpm / self.rpm_per_unit_velocity

    @staticmethod
    def current_from_ma(milliamps):
        return milliamps / MA_PER_AMP

    # SI -> drive units (rounded to the integer the drive takes)
    def counts_from_position(self, position):
        return round(position * self.counts_per_unit)

    def rpm_from_velocity(self, velocity):
        return round(velocity * self.rpm_per_unit_velocity)

    @staticmethod
    def ma_from_current(amps):
        return round(amps * MA_PER_AMP)


class AxesScaling:
    """The scalings of several axes, converting arrays whose last axis runs over them
    (e.g. samples × axes); drive units in, SI out and back (rounded to whole counts, rpm, mA).

    Args:
        scalings: one :class:`AxisScaling` per axis, in column order.
    """

    def __init__(self, scalings: Sequence[AxisScaling]):
        self.scalings = tuple(scalings)
        self.counts_per_unit = np.array([s.counts_per_unit for s in self.scalings])
        self.rpm_per_unit_velocity = np.array([s.rpm_per_unit_velocity for s in self.scalings])
        self.force_per_amp = np.array([s.force_per_amp for s in self.scalings])

    # drive units -> SI (float arrays; NaN stays NaN)
    def position_from_counts(self, counts) -> np.ndarray:
        return np.asarray(counts, dtype=float) / self.counts_per_unit

    def velocity_from_rpm(self, rpm) -> np.ndarray:
        return np.asarray(rpm, dtype=float) / self.rpm_per_unit_velocity

    @staticmethod
    def current_from_ma(milliamps) -> np.ndarray:
        return np.asarray(milliamps, dtype=float) / MA_PER_AMP

    # SI -> drive units (int64 arrays)
    def counts_from_position(self, position) -> np.ndarray:
        return np.rint(np.asarray(position, dtype=float) * self.counts_per_unit).astype(np.int64)

    def rpm_from_velocity(self, velocity) -> np.ndarray:
        return np.rint(np.asarray(velocity, dtype=float) * self.rpm_per_unit_velocity).astype(np.int64)

    @staticmethod
    def ma_from_current(amps) -> np.ndarray:
        return np.rint(np.asarray(amps, dtype=float) * MA_PER_AMP).astype(np.int64)

    # motor current <-> joint force (SI both)
    def force_from_current(self, amps) -> np.ndarray:
        return np.asarray(amps, dtype=float) * self.force_per_amp

    def current_from_force(self, force) -> np.ndarray:
        return np.asarray(force, dtype=float) / self.force_per_amp
