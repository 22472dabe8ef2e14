"""The position demand of an emulated drive and the operating modes that generate it, as pure
functions of the demand and the period (testable without a bus).

Over each period the demand is a cubic ``q_d(t) = c0 + c1 t + c2 t^2 + c3 t^3`` (counts, ``t`` in
s from the period start): :class:`Demand` holds it. The generators:

- :func:`cyclic_segment`: cyclic synchronous position (EPOS4 CSP, EPOS2 position mode -1): the
  uniform cubic B-spline whose control points are the received targets (see
  :mod:`drivers.sim.drive` for why C2);
- :func:`profile_step`: the trapezoidal profile of a profile-position or homing move;
- :func:`ramp_down`: the quick-stop (and fault-reaction) deceleration to standstill.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple


class Cubic(NamedTuple):
    """A position demand over one period, ``q_d(t) = c0 + c1 t + c2 t^2 + c3 t^3`` (``t`` in s
    from the period start): its coefficients by ascending power (NumPy's polynomial order). A
    named tuple, so that the rig stacks the drives' cubics into one array at once."""

    c0: float     #: position at the period start, counts
    c1: float     #: velocity at the period start, counts/s
    c2: float     #: counts/s²
    c3: float     #: counts/s³


@dataclass
class Demand:
    """``position`` (counts) and ``velocity`` (counts/s) at the period start, ``curve`` = the
    cubic's ``(c2, c3)`` over the period; ``end``: the exact end position of a profile step (the
    demand lands on it instead of the cubic's rounding)."""

    position: float = 0.0
    velocity: float = 0.0
    curve: tuple[float, float] = (0.0, 0.0)
    end: float | None = None

    def coefficients(self) -> Cubic:
        """The cubic over the period (:class:`Cubic`)."""
        c2, c3 = self.curve
        return Cubic(self.position, self.velocity, c2, c3)

    def advance(self, period: float) -> None:
        """To the end of the period."""
        c2, c3 = self.curve
        if self.end is not None:
            self.position, self.end = self.end, None
        else:
            self.position += (self.velocity + (c2 + c3 * period) * period) * period
        self.velocity += (2.0 * c2 + 3.0 * c3 * period) * period


class CyclicTargets(NamedTuple):
    """The last three cyclic targets a drive received (counts), newest first: the B-spline's
    control points before the next target (:func:`cyclic_segment`). A named tuple: immutable as
    a frozen dataclass, made in half its time (a streaming drive makes one every SYNC)."""

    last: float       #: the target of the period just begun, counts
    before: float     #: the one before it, counts
    oldest: float     #: the one before that, counts


def cyclic_segment(demand: Demand, target: float, period: float, history: CyclicTargets | None) -> CyclicTargets:
    """Uniform cubic B-spline segment of the last four targets: ``history`` (the three previous
    ones, or None when streaming starts: the held demand) and ``target`` (counts); sets
    ``demand``'s cubic over the ``period`` (s) and returns the history for the next period."""
    p2, p1, p0 = (history.last, history.before, history.oldest) if history else (demand.position,) * 3
    if period > 0:
        demand.position = (p0 + 4.0 * p1 + p2) / 6.0
        demand.velocity = (p2 - p0) / (2.0 * period)
        demand.curve = ((p0 - 2.0 * p1 + p2) / (2.0 * period**2),
                        (target - 3.0 * p2 + 3.0 * p1 - p0) / (6.0 * period**3))
    return CyclicTargets(target, p2, p1)


def profile_step(demand: Demand, target: float, speed: float, acceleration: float, period: float) -> bool:
    """Advance a trapezoidal move towards ``target`` (counts) at most ``speed`` (counts/s) and
    ``acceleration`` (counts/s²) by one period; True when the demand arrives on the target.

    The demand over the period is the cubic through its start and end positions and velocities
    (a parabola while accelerating, cruising or braking); braking starts where the stopping
    distance at the profile acceleration reaches the remaining travel and then decelerates
    uniformly onto the target, so the demand arrives there at rest.
    """
    start, v = demand.position, demand.velocity
    remaining = target - start
    direction = math.copysign(1.0, remaining)
    new_pos, new_v = float(target), 0.0
    if abs(remaining) >= 1.0:
        if v * direction > 0 and v * v / (2 * acceleration) >= abs(remaining):   # brake onto the target
            new_v = v - direction * v * v / (2 * abs(remaining)) * period
        else:                                                                     # accelerate / cruise
            new_v = max(-speed, min(speed, v + direction * acceleration * period))
        new_pos = start + 0.5 * (v + new_v) * period
        if new_v * direction <= 0 or (target - new_pos) * direction <= 0:
            new_pos, new_v = float(target), 0.0
    travel = new_pos - start
    demand.curve = ((3.0 * travel - (2.0 * v + new_v) * period) / period**2,
                    ((v + new_v) * period - 2.0 * travel) / period**3)
    demand.end = new_pos
    return new_pos == target


def ramp_down(demand: Demand, deceleration: float, period: float) -> None:
    """Decelerate the demand towards standstill at ``deceleration`` (counts/s²) over one period."""
    v = demand.velocity
    if period > 0 and v:
        end = v - math.copysign(min(abs(v), deceleration * period), v)
        demand.curve = (0.5 * (end - v) / period, 0.0)
