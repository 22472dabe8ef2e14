"""Recorded rows → the stretches identification may filter and differentiate.

A recording holds one row per SYNC cycle (:class:`drivers.recording.Recording`). Its sample
times are its ``t``, for the simulated rig and for hardware alike: the SYNC count times the
period in lockstep (the simulated time), the SYNC frames' bus time stamps on a periodic SYNC
(drives sample on SYNC and move on their own clock between two). A producer that skipped a
SYNC slot leaves a *gap*: two rows more than :data:`SKIPPED_SLOT` periods apart.

Rows the model cannot explain are left out, each by one rule, counted in
:attr:`Segments.left_out` (rows at the input rate):

* ``incomplete``: an axis' position or current missing, late or not placeable in that cycle
  (the TPDO carrying it invalid; identification uses no other measured value, so a lost
  velocity or statusword frame leaves the row in);
* ``saturated``: a current within :data:`SATURATION` of the drive's limit (clipped);
* ``late_setpoint``: a set-point sequence accelerating faster than :data:`SETPOINT_JUMP` × the
  axis' limit (it was not delivered on time: the drive held the old one, then jumped);
* ``edges``: the filters' support at both ends of every stretch: ``trim`` rows at the
  recording's own first and last row, ``cut_trim`` rows at a cut inside it
  (:class:`ident_hw.filtering.Ends`, :attr:`ident_hw.filtering.FilterSettings.cut_trim`);
* ``short``: stretches too short to filter at all.

The recording is cut at every gap and every left-out row into :attr:`Segments.stretches` of
consecutive good rows; each is filtered and differentiated on its own
(:func:`ident_hw.filtering.prepare_actuated`), so no filter or derivative stencil reaches across a
gap or a row without data, and nothing is interpolated across one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from ident_hw.filtering import Ends

#: two SYNCs further apart than this many periods: the producer skipped a slot
SKIPPED_SLOT = 1.5
#: a set-point sequence accelerating faster than this many times the axis limit was not
#: delivered on time (the drive held a stale set-point, then jumped)
SETPOINT_JUMP = 5.0
#: a current within this fraction of the drive's limit is clipped, not a measurement
SATURATION = 0.98
#: the rules that leave rows out, in the order they are applied and reported
RULES = ("incomplete", "saturated", "late_setpoint", "edges", "short")


def slot_indices(t: np.ndarray, period: float) -> np.ndarray:
    """(N,) the SYNC slot of every row, from 0: consecutive rows one slot apart, rows
    ``SKIPPED_SLOT`` periods or more apart as many slots as the time between them holds."""
    t = np.asarray(t, dtype=float)
    if len(t) < 2:
        return np.zeros(len(t), dtype=np.int64)
    steps = np.diff(t) / period
    steps = np.where(steps > SKIPPED_SLOT, np.rint(steps), 1).astype(np.int64)
    return np.concatenate([[0], np.cumsum(steps)])


@dataclass(frozen=True)
class Stretch:
    """Consecutive good rows of a recording, filtered on their own: ``rows`` (a slice of the
    recording's rows) and where they end (``ends``: at a cut inside the recording, or at its own
    first or last row), which sets the rows the filters take at each end."""

    rows: slice
    ends: Ends


@dataclass(frozen=True)
class Segments:
    """How the rows of one recording are used.

    Attributes:
        t: (N,) sample times of all rows, s (from the first row).
        stretches: the stretches of consecutive good rows, long enough to filter.
        skipped_slots: SYNC slots without a row (gaps).
        gaps: places the recording is cut because slots were skipped.
        left_out: rows left out per rule (:data:`RULES`).
    """

    t: np.ndarray
    stretches: tuple[Stretch, ...]
    skipped_slots: int
    gaps: int
    left_out: Mapping[str, int] = field(default_factory=dict)

    @property
    def slices(self) -> list[slice]:
        """The rows of every stretch."""
        return [s.rows for s in self.stretches]

    def describe(self) -> str:
        """``3 gaps (12 SYNC slots skipped); left out: 40 incomplete, 96 edges`` (or ``""``)."""
        parts = []
        if self.gaps:
            parts.append(f"{self.gaps} gap{'s' if self.gaps > 1 else ''} ({self.skipped_slots} SYNC slots skipped)")
        out = [f"{n} {rule.replace('_', ' ')}" for rule, n in self.left_out.items() if n]
        if out:
            parts.append(f"rows left out: {', '.join(out)}")
        if len(self.slices) > 1:
            parts.append(f"{len(self.slices)} stretches fitted")
        return "; ".join(parts)


def split(t: np.ndarray, period: float, valid: np.ndarray, current: np.ndarray, target: np.ndarray,
          current_limit: np.ndarray, acceleration_limit: np.ndarray, counts_per_unit: np.ndarray,
          trim: int, min_kept: int, cut_trim: int | None = None) -> Segments:
    """Cut a recording into the stretches the filters may use (see the module docstring).

    Args:
        t: (N,) row times, s. period: the SYNC period, s.
        valid: (N, m) per-axis validity of the values the rows are used for (positions and
            currents).
        current: (N, m) motor currents, A (NaN where invalid). target: (N, m) set-points.
        current_limit: (m,) A. acceleration_limit: (m,) rad/s² or m/s².
        counts_per_unit: (m,) encoder counts per rad or m (a set-point is whole counts).
        trim: rows the filters need at the recording's own first and last row.
        min_kept: the fewest rows a stretch must keep beyond the rows trimmed at its two ends
            (shorter ones are left out, ``short``); at least 1.
        cut_trim: rows the filters need at a cut inside the recording (``None``: ``trim``).
    """
    t = np.asarray(t, dtype=float)
    n = len(t)
    slots = slot_indices(t, period)
    cut_before = np.zeros(n, dtype=bool)
    cut_before[1:] = np.diff(slots) > 1
    left_out = dict.fromkeys(RULES, 0)
    bad = ~np.asarray(valid).all(axis=1)
    left_out["incomplete"] = int(bad.sum())
    saturated = ~bad & np.any(np.abs(np.nan_to_num(current)) >= SATURATION * current_limit, axis=1)
    left_out["saturated"] = int(saturated.sum())
    bad |= saturated
    late = np.zeros(n, dtype=bool)
    if n > 2:
        jump = np.abs(np.diff(np.nan_to_num(target), 2, axis=0))
        allowed = SETPOINT_JUMP * acceleration_limit * period**2 + 2.0 / counts_per_unit
        late[1:-1] = np.any(jump > allowed, axis=1) & ~cut_before[1:-1] & ~cut_before[2:]
    late &= ~bad
    left_out["late_setpoint"] = int(late.sum())
    bad |= late
    cut_trim = trim if cut_trim is None else cut_trim
    stretches = []
    start = None
    for i in range(n + 1):
        ends = i == n or bad[i] or cut_before[i]
        if ends and start is not None:
            length = i - start
            where = Ends(head_cut=start > 0, tail_cut=i < n)
            trimmed = sum(where.pick(cut_trim, trim))
            if length >= trimmed + max(min_kept, 1):
                stretches.append(Stretch(slice(start, i), where))
                left_out["edges"] += trimmed
            else:
                left_out["short"] += length
            start = None
        if i < n and not bad[i] and start is None:
            start = i
    return Segments(t=t - t[0] if n else t, stretches=tuple(stretches),
                    skipped_slots=int(slots[-1] + 1 - n) if n else 0, gaps=int(cut_before.sum()),
                    left_out=left_out)


def uniform(t: np.ndarray, *arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """A stretch on the uniform grid its own time stamps span: ``(t_grid, *arrays_on_grid)``.

    Rows sampled on a jittered SYNC (a thread-timed producer) are interpolated onto
    ``linspace(t[0], t[-1], N)`` (the derivatives and filters assume a uniform grid): the first
    array (positions) by a cubic spline, the others (currents) linearly. A grid already
    uniform to 1 ppm is returned as it is."""
    t = np.asarray(t, dtype=float)
    dt = np.diff(t)
    if len(t) < 3 or np.ptp(dt) <= 1e-6 * np.mean(dt):
        return (t, *arrays)
    grid = np.linspace(t[0], t[-1], len(t))
    out = [CubicSpline(t, arrays[0], axis=0)(grid)]
    for a in arrays[1:]:
        out.append(np.column_stack([np.interp(grid, t, a[:, j]) for j in range(a.shape[1])]))
    return (grid, *out)
