"""Recordings the tool did not make: a robot controller's or another lab's CSV files, read into
the same :class:`~drivers.recording.Recording` the tool's own runs give.

The ``recordings`` section of the config (:class:`~ident_hw.config.recordings.RecordingsConfig`)
says which column holds what, in which unit; a ``recorded`` trajectory names its file and the
part of it to use (``rows`` or ``window``). Reading a file (:func:`read_external`):

1. the data rows after the header; ``rows`` picks some of them (1-based, inclusive);
2. each row checked (:data:`ident_hw.records.CUT_REASONS`): its number of fields (the file's
   usual number), every field used a finite number, every value within reach of the robot (no
   further outside an actuator's limits than ``recordings.absurd`` times their size), its time
   in order (the rows outside the file's longest run of increasing stamps are not) and near
   another row's (a lone stamp far from every other is a corrupted row's). A row that fails is
   left out, its line and reason in the report, or, with ``recordings.bad_rows: error``, stops
   the reading with that message: never used silently;
3. ``window`` picks a time span; the idle head and tail (no actuator away from its first or last
   position by more than ``recordings.idle_tolerance`` of its range) are left out but for
   :data:`IDLE_MARGIN` s next to the motion, which the filters' ends take;
4. the rows are resampled to an even step, the mean of the file's regular steps: positions by a
   cubic spline, velocities and currents linearly, never across a gap (a step longer than
   ``recordings.gap`` times the median). Every filter and derivative downstream sees even samples;
   a gap is a skipped slot, where the identification cuts the recording as at a skipped SYNC.

What was done is an :class:`~ident_hw.records.ImportSummary`, which the results and the report
carry. Units become SI here; a ``torque`` column becomes the motor current through the actuator's
force per ampere (``torque_constant`` × ``gear_ratio``), as the identification expects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
from scipy.interpolate import CubicSpline

from drivers.errors import RecordingError
from drivers.recording import Recording
from drivers.recording_metadata import RecordingMetadata
from ident_hw.config import Config, TrajectoryConfig
from ident_hw.config.recordings import (CURRENT_UNITS, POSITION_UNITS, TIME_UNITS, TORQUE_UNITS, VELOCITY_UNITS,
                                        RecordingsConfig)
from ident_hw.records import CUT_REASONS, CutRows, ImportSummary

from .inputs import Axes

#: s of rest kept next to the motion where an idle head or tail is left out (the filters' ends)
IDLE_MARGIN = 0.5
#: line numbers named per reason in the report
NAMED_LINES = 5
#: the ``status`` of a recording read from a file made elsewhere (:class:`RecordingMetadata`)
STATUS = "recorded elsewhere"


@dataclass(frozen=True)
class ExternalRecording:
    """A file made elsewhere, read: the recording (even steps, SI) and how it was read."""

    recording: Recording
    summary: ImportSummary


@dataclass(frozen=True)
class _Layout:
    """The file's columns (0-based indices) per quantity, each (a,) but ``time``."""

    time: int
    position: tuple[int, ...]
    velocity: tuple[int, ...] | None
    force: tuple[int, ...]
    force_kind: str

    @property
    def used(self) -> int:
        """The fields a row must have: one past the highest column used."""
        cols = [self.time, *self.position, *(self.velocity or ()), *self.force]
        return max(cols) + 1


def read_external(config: Config, tcfg: TrajectoryConfig, path: str | Path | None = None,
                  use_window: bool = True) -> ExternalRecording:
    """The recording of trajectory ``tcfg`` from its file (``path``: another file of the same
    robot, given on the command line, in its place), read as ``config.recordings`` says (the
    module docstring). ``use_window``: apply the trajectory's ``rows`` or ``window`` (the part of
    the config's own file; a file given in its place is taken whole).

    Raises:
        RecordingError: an unreadable file, a column the header does not name, a row that is no
            data with ``bad_rows: error``, or no row left; the message names the file (and line).
    """
    spec = config.recordings
    if spec is None:
        raise RecordingError(f"{config.source}: recordings: missing section (how a recorded file is read)")
    path = Path(path if path is not None else str(tcfg.path))   # the config's path: already its file's folder joined
    try:
        text = path.read_text(encoding="utf-8", errors="strict")
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"{path}: cannot read the recording of trajectory {tcfg.name!r}: {exc}") from None
    lines = text.splitlines()
    header, body = lines[:spec.header], lines[spec.header:]
    layout = _layout(spec, header, path)
    first_row = 0
    window_text = None
    if use_window and tcfg.rows is not None:
        first, last = tcfg.rows
        if first > len(body):
            raise RecordingError(f"{path}: rows {first}..{last} asked for (trajectory {tcfg.name!r}), the file has "
                                 f"{len(body)} data rows")
        body, first_row = body[first - 1:last], first - 1
        window_text = f"rows {first}..{min(last, first_row + len(body))}"
    axes = Axes.of(config.robot.actuators)
    table, cut = _parse(spec, body, layout, path, spec.header + first_row + 1, axes)
    t = table[:, 0]
    if use_window and tcfg.window is not None:
        start, end = tcfg.window
        inside = (t >= start) & (t <= end)
        table, t = table[inside], t[inside]
        window_text = f"{start:g}..{end:g} s"
    if len(t) < 3:
        raise RecordingError(f"{path}: {len(t)} usable rows for trajectory {tcfg.name!r}: too few to identify from")
    a = len(axes)
    position, force = table[:, 1:1 + a], table[:, 1 + a:1 + 2 * a]
    velocity = table[:, 1 + 2 * a:1 + 3 * a] if layout.velocity is not None else None
    keep = idle_trimmed(t, position, axes, spec.idle_tolerance)
    head_s, tail_s = float(t[keep.start] - t[0]), float(t[-1] - t[keep.stop - 1])
    t, position, force = t[keep], position[keep], force[keep]
    velocity = velocity[keep] if velocity is not None else None
    if len(t) < 3:
        raise RecordingError(f"{path}: trajectory {tcfg.name!r}: nothing moves in the rows used")
    steps = np.diff(t)
    median = float(np.median(steps))
    regular = steps <= spec.gap * median
    period = float(np.mean(steps[regular]))
    force = delayed(t, force, ~regular, spec.current_delay)
    grid, (position, force, velocity) = resample(t, period, ~regular, position, force, velocity)
    current = force / axes.force_per_amp if layout.force_kind == "torque" else force
    summary = ImportSummary(
        data_rows=len(lines) - spec.header, window=window_text, rows_used=len(t), cut=cut,
        idle_head_s=round(head_s, 6), idle_tail_s=round(tail_s, 6), step_min_s=float(steps.min()),
        step_median_s=median, step_max_s=float(steps.max()), period_s=period, gaps=int((~regular).sum()),
        velocity="recorded" if layout.velocity is not None else "differentiated", force=layout.force_kind)
    n = len(grid)
    metadata = RecordingMetadata(trajectory=tcfg.name, file=str(path), status=STATUS, sync_period=period,
                                 n_cycles=n, t0=float(t[0]))
    have_velocity = velocity is not None
    rec = Recording(t=grid - grid[0], cycle=np.rint((grid - grid[0]) / period).astype(np.int64),
                    position=position, velocity=velocity if have_velocity else np.full((n, a), np.nan),
                    current=current, statusword=np.full((n, a), -1, dtype=np.int32),
                    target=np.full((n, a), np.nan), valid=np.ones((n, a), dtype=bool), metadata=metadata,
                    velocity_valid=np.full((n, a), have_velocity))
    return ExternalRecording(rec, summary)


def _layout(spec: RecordingsConfig, header: Sequence[str], path: Path) -> _Layout:
    """The 0-based columns of each quantity: numbers as given (1-based), names looked up in the
    header's last line."""
    names = _split(header[-1], spec.delimiter) if header else []

    def index(column, key: str) -> int:
        if isinstance(column, int):
            if column < 1:
                raise RecordingError(f"recordings.columns.{key}: column {column}: columns count from 1")
            return column - 1
        stripped = [n.strip().strip('"') for n in names]
        if column not in stripped:
            raise RecordingError(f"{path}: recordings.columns.{key}: no column named {column!r} in the header "
                                 f"line {spec.header}" + (f" (it names {stripped})" if stripped else
                                                          " (recordings.header is 0: number the columns instead)"))
        return stripped.index(column)

    c = spec.columns
    force_kind = "current" if c.current is not None else "torque"
    return _Layout(time=index(c.time, "time"),
                   position=tuple(index(v, f"position[{i}]") for i, v in enumerate(c.position)),
                   velocity=None if c.velocity is None else tuple(index(v, f"velocity[{i}]")
                                                                  for i, v in enumerate(c.velocity)),
                   force=tuple(index(v, f"{force_kind}[{i}]") for i, v in enumerate(getattr(c, force_kind))),
                   force_kind=force_kind)


def _split(line: str, delimiter: str) -> list[str]:
    return line.split() if delimiter == " " else line.split(delimiter)


def _scales(spec: RecordingsConfig, layout: _Layout, a: int) -> np.ndarray:
    """(1 + 3a,) the SI factor of each parsed column: time, positions, forces, velocities."""
    units, scale = spec.units, spec.scale

    def per_axis(unit: float, factor) -> np.ndarray:
        return unit * np.broadcast_to(np.asarray(factor, dtype=float), (a,))
    force_unit = (CURRENT_UNITS[units.current] if layout.force_kind == "current" else TORQUE_UNITS[units.torque])
    return np.concatenate([[TIME_UNITS[units.time]], per_axis(POSITION_UNITS[units.position], scale.position),
                           per_axis(force_unit, getattr(scale, layout.force_kind)),
                           per_axis(VELOCITY_UNITS[units.velocity], scale.velocity)])


def _parse(spec: RecordingsConfig, body: Sequence[str], layout: _Layout, path: Path, first_line: int,
           axes: Axes) -> tuple[np.ndarray, tuple[CutRows, ...]]:
    """The data rows as an (N, 1 + 3a) array in SI (time, positions, forces, velocities; NaN
    velocities where the file has none) and the rows cut, per reason, for the robot's ``axes``.
    ``first_line``: the file's line number (1-based) of ``body[0]``."""
    a = len(axes)
    columns = [layout.time, *layout.position, *layout.force, *(layout.velocity or [layout.time] * a)]
    fields_per_row = [len(_split(line, spec.delimiter)) for line in body]
    usual = max(set(fields_per_row), key=fields_per_row.count) if fields_per_row else 0
    if usual < layout.used:
        raise RecordingError(f"{path}: rows have {usual} fields, the columns named in recordings.columns need "
                             f"{layout.used}")
    rejected: dict[str, list[int]] = {reason: [] for reason in CUT_REASONS}
    rows, lines = [], []
    for k, line in enumerate(body):
        number = first_line + k
        if not line.strip():
            continue
        fields = _split(line, spec.delimiter)
        if len(fields) != usual:
            _reject(spec, rejected, "fields", number, path, f"{len(fields)} fields, the file's rows have {usual}")
            continue
        try:
            values = [float(fields[c]) for c in columns]
        except ValueError:
            _reject(spec, rejected, "number", number, path, "a field used is no number")
            continue
        if not all(math.isfinite(v) for v in values):
            _reject(spec, rejected, "number", number, path, "a field used is not finite")
            continue
        rows.append(values)
        lines.append(number)
    table = np.array(rows, dtype=float).reshape(len(rows), len(columns)) * _scales(spec, layout, a)
    if layout.velocity is None:
        table[:, 1 + 2 * a:] = np.nan
    numbers = np.array(lines, dtype=np.int64)
    far = beyond_reach(table, axes, spec.absurd, layout.force_kind)
    for number in numbers[far]:
        _reject(spec, rejected, "absurd", int(number), path, "a value beyond anything the robot can reach")
    table, numbers = table[~far], numbers[~far]
    back = out_of_order(table[:, 0])
    for number in numbers[back]:
        _reject(spec, rejected, "time_back", int(number), path, "its time does not go forward")
    table, numbers = table[~back], numbers[~back]
    alone = isolated(table[:, 0], spec.gap)
    for number in numbers[alone]:
        _reject(spec, rejected, "absurd", int(number), path, "a time stamp far from every other row's")
    table = table[~alone]
    cut = tuple(CutRows(reason, len(found), tuple(sorted(found)[:NAMED_LINES]))
                for reason, found in rejected.items() if found)
    return table, cut


def _reject(spec: RecordingsConfig, rejected: dict[str, list[int]], reason: str, line: int, path: Path,
            why: str) -> None:
    """Record a row that is no data, or stop (``bad_rows: error``) naming its file and line."""
    if spec.bad_rows == "error":
        raise RecordingError(f"{path}, line {line}: not data: {why} (recordings.bad_rows: cut leaves such rows "
                             "out, naming them in the report)")
    rejected[reason].append(line)


def beyond_reach(table: np.ndarray, axes: Axes, absurd: float, force_kind: str) -> np.ndarray:
    """(N,) bool: rows with a value further outside an actuator's limits (of the robot's
    ``axes``) than ``absurd`` times their size: a position beyond ``absurd`` × its range outside
    it, a velocity or current (a torque: through the force per ampere) above ``1 + absurd`` times
    its limit. ``table`` as ``_parse`` builds it (SI)."""
    a = len(axes)
    lo, hi = axes.position_low, axes.position_high
    margin = absurd * (hi - lo)
    position, force, velocity = table[:, 1:1 + a], table[:, 1 + a:1 + 2 * a], table[:, 1 + 2 * a:]
    current_limit = axes.current_limit
    if force_kind == "torque":
        current_limit = current_limit * axes.force_per_amp
    speed_limit = axes.velocity_limit
    with np.errstate(invalid="ignore"):
        far = ((position < lo - margin) | (position > hi + margin)).any(axis=1)
        far |= (np.abs(force) > (1 + absurd) * current_limit).any(axis=1)
        far |= (np.abs(velocity) > (1 + absurd) * speed_limit).any(axis=1)
    return far


def out_of_order(t: np.ndarray) -> np.ndarray:
    """(N,) bool: rows whose time stamp does not go forward: those outside the longest strictly
    increasing run of stamps through the file (its longest increasing subsequence: the most rows in
    time order). A stamp from the past, a repeated one, a lone stamp far ahead (of a corrupted row:
    the rows after it are the ones in order), all fall outside it."""
    import bisect
    tails: list[float] = []          # the smallest last stamp of an increasing run of each length
    ends: list[int] = []             # the row it is
    before = np.full(len(t), -1)     # each row's predecessor in the run it ends
    for k, value in enumerate(t):
        length = bisect.bisect_left(tails, value)
        if length == len(tails):
            tails.append(value)
            ends.append(k)
        else:
            tails[length], ends[length] = value, k
        before[k] = ends[length - 1] if length else -1
    keep = np.zeros(len(t), dtype=bool)
    k = ends[-1] if ends else -1
    while k >= 0:
        keep[k] = True
        k = before[k]
    return ~keep


def isolated(t: np.ndarray, gap: float) -> np.ndarray:
    """(N,) bool: rows of increasing stamps ``t`` with no other row within ``gap`` median steps on
    either side: a stamp of a corrupted row that happens to be in order (a zero among stamps of
    an hour), one row alone, which nothing can be filtered or differentiated with."""
    if len(t) < 3:
        return np.zeros(len(t), dtype=bool)
    steps = np.diff(t)
    far = steps > gap * np.median(steps)
    return np.concatenate([[True], far]) & np.concatenate([far, [True]])


def idle_trimmed(t: np.ndarray, position: np.ndarray, axes: Axes, idle_tolerance: float) -> slice:
    """The rows from the first motion to the last (:data:`IDLE_MARGIN` s of rest kept either
    side): an actuator moves when it leaves the first (last) row's position by more than
    ``idle_tolerance`` (``recordings.idle_tolerance``) of its position range (of the robot's
    ``axes``). The whole span when nothing moves."""
    tolerance = idle_tolerance * (axes.position_high - axes.position_low)
    moved_from_start = np.flatnonzero((np.abs(position - position[0]) > tolerance).any(axis=1))
    moved_to_end = np.flatnonzero((np.abs(position - position[-1]) > tolerance).any(axis=1))
    if not len(moved_from_start):
        return slice(0, len(t))
    start = int(np.searchsorted(t, t[moved_from_start[0]] - IDLE_MARGIN))
    stop = int(np.searchsorted(t, t[moved_to_end[-1]] + IDLE_MARGIN, side="right"))
    return slice(start, max(stop, start + 1))


def delayed(t: np.ndarray, force: np.ndarray, gap_after: np.ndarray, delay) -> np.ndarray:
    """``force`` (N, a) stamped ``delay`` s late (one, or (a,); 0: as it is) moved to its own time:
    each column read at ``t + delay`` by linear interpolation within its stretch between gaps
    (held at a stretch's ends)."""
    delay = np.broadcast_to(np.asarray(delay, dtype=float), (force.shape[1],))
    if not np.any(delay):
        return force
    out = np.array(force, dtype=float)
    bounds = np.concatenate([[0], np.flatnonzero(gap_after) + 1, [len(t)]])
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        for j in np.flatnonzero(delay):
            out[lo:hi, j] = np.interp(t[lo:hi] + delay[j], t[lo:hi], force[lo:hi, j])
    return out


def resample(t: np.ndarray, period: float, gap_after: np.ndarray, position: np.ndarray,
             *others: np.ndarray | None) -> tuple[np.ndarray, tuple]:
    """Rows at uneven times ``t`` (N,) onto the even grid ``t[0] + k period`` (s): ``position``
    (N, a) by a cubic spline, each of ``others`` (N, a; None stays None) linearly, stretch by
    stretch between the gaps (``gap_after`` (N-1,): the step after row k is a gap), so nothing is
    interpolated across one. Returns the grid times (M,) and the arrays on them, ``position``
    first."""
    bounds = np.concatenate([[0], np.flatnonzero(gap_after) + 1, [len(t)]])
    grids, parts = [], []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        tt = t[lo:hi]
        k0, k1 = math.ceil((tt[0] - t[0]) / period - 1e-9), math.floor((tt[-1] - t[0]) / period + 1e-9)
        if k1 < k0:
            continue
        grid = t[0] + period * np.arange(k0, k1 + 1)
        if len(tt) >= 2:
            pos = CubicSpline(tt, position[lo:hi], axis=0)(grid) if len(tt) >= 3 else _linear(tt, position[lo:hi], grid)
        else:
            pos = position[lo:hi]
        rest = tuple(None if x is None else (_linear(tt, x[lo:hi], grid) if len(tt) >= 2 else x[lo:hi])
                     for x in others)
        grids.append(grid)
        parts.append((pos, *rest))
    grid = np.concatenate(grids)
    arrays = tuple(None if parts[0][i] is None else np.concatenate([p[i] for p in parts])
                   for i in range(len(parts[0])))
    return grid, arrays


def _linear(t: np.ndarray, values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(grid, t, values[:, j]) for j in range(values.shape[1])])
