"""The quality verdict's figures against their limits, as rows of cells: the same for the terminal
(:mod:`.terminal`) and ``report.html`` (:mod:`.html`).

Per judged axis (:func:`axis_table`): its gain against its own model refitted
(``max_axis_gain``), its worst residual over its noise floor (``max_residual_over_floor``),
the lag of its forces (``max_force_lag``, ``min_lag_share``) and its force prediction where it
moves (``max_axis_rre``), each with pass or fail as the verdict judged it
(``AxisFigures.failed``); a check the verdict could not make says so in its column's head, as
``noise floor: not judged (no standstill)``. Per trajectory (:func:`trajectory_table`): what its
recording covers and, where judged, the force prediction error, against their limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ident_hw.records import Thresholds
from ident_hw.records import AxisFigures, TrajectoryVerdict, Verdict


@dataclass(frozen=True)
class Cell:
    """One figure against its limit: its ``text``, and ``ok`` (None: nothing judged)."""

    text: str
    ok: bool | None = None


@dataclass(frozen=True)
class Table:
    """A table of the verdict: column heads (each with its limit), and rows of :class:`Cell`
    (the first names the row); ``notes``: the checks not judged, as ``noise floor: not judged
    (no standstill)``."""

    heads: tuple[str, ...]
    rows: tuple[tuple[Cell, ...], ...]
    notes: tuple[str, ...] = ()


def status_line(status: str, q: Verdict | None) -> str:
    """The folder's ``status`` as the summary shows it: a ``degraded: <reasons>`` that holds the
    verdict ``q``'s reasons becomes ``degraded (the quality verdict's reasons below)``, so that
    each reason is printed once, with the verdict."""
    if q is not None and q.reasons and status == "degraded: " + "; ".join(q.reasons):
        return "degraded (the quality verdict's reasons below)"
    return status


def not_judged_notes(q: Verdict) -> tuple[str, ...]:
    """``noise floor: not judged (no standstill)``, one per check the verdict could not make, then
    the verdict's notes (what it saw and does not fail on)."""
    return tuple(f"{check}: not judged ({why})" for check, why in q.not_judged.items()) + tuple(
        f"note: {note}" for note in q.notes)


def axis_table(q: Verdict) -> Table:
    """Each judged axis's figures against the verdict's limits (:class:`AxisFigures`)."""
    limits = q.thresholds or Thresholds()
    heads = ("axis", f"gain % (|g| ≤ {limits.max_axis_gain:g})",
             f"residual / noise floor (≤ {limits.max_residual_over_floor:g})",
             f"force lag ms (|lag| ≤ {1e3 * limits.max_force_lag:g} or < {100 * limits.min_lag_share:g} % of the residual)",
             f"rre % moving, identified / consistent (≤ {limits.max_axis_rre:g})")
    rows = tuple((Cell(name), _gain(figures), _floor(figures), _lag(figures), _rre(figures))
                 for name, figures in q.axes.items())
    return Table(heads, rows, not_judged_notes(q))


def _gain(f: AxisFigures) -> Cell:
    if f.gain_percent is None:
        return Cell("not judged")
    return Cell(f"{f.gain_percent:+.2f} ± {f.gain_sigma_percent:.2g}", "gain" not in f.failed)


def _floor(f: AxisFigures) -> Cell:
    if f.residual_over_floor is None:
        return Cell("not judged")
    where = f" on {f.floor_trajectory}" if f.floor_trajectory else ""
    amps = (f" ({1e3 * f.residual_A:.3g} / {1e3 * f.floor_A:.3g} mA)"
            if f.residual_A is not None and f.floor_A is not None else "")
    return Cell(f"{f.residual_over_floor:.2f}{where}{amps}", "noise floor" not in f.failed)


def _lag(f: AxisFigures) -> Cell:
    if f.force_lag_s is None:
        return Cell("not judged")
    sigma = f" ± {1e3 * f.force_lag_sigma_s:.2g}" if f.force_lag_sigma_s is not None else ""
    share = f" ({100 * f.force_lag_share:.0f} %)" if f.force_lag_share is not None else ""
    return Cell(f"{1e3 * f.force_lag_s:+.3f}{sigma}{share}", "force lag" not in f.failed)


def _rre(f: AxisFigures) -> Cell:
    if f.rre_percent is None:
        return Cell("not judged")
    consistent = f" / {f.rre_consistent_percent:.2f}" if f.rre_consistent_percent is not None else ""
    return Cell(f"{f.rre_percent:.2f}{consistent} on {f.rre_trajectory}", "prediction" not in f.failed)


def trajectory_table(q: Verdict) -> Table:
    """Per trajectory: its recording's coverage, complete cycles and longest gap, and where the
    predictions are judged their d_tau and how far the two predictions are apart, against the
    verdict's limits."""
    limits = q.thresholds or Thresholds()
    heads = ("trajectory", f"recorded (≥ {100 * limits.min_coverage:g} %)",
             f"complete cycles (≥ {100 * limits.min_valid_fraction:g} %)", f"longest gap s (≤ {limits.max_gap:g})",
             f"d_tau % step by step / base fit (≤ {limits.max_d_tau:g})",
             f"predictions apart % (≤ {limits.max_disagreement:g})")
    rows = []
    for name, t in q.trajectories.items():
        rows.append((Cell(name if t.role is None else f"{name} ({t.role})"),
                     _share(t.coverage, limits.min_coverage, t),
                     _share(t.valid_fraction, limits.min_valid_fraction, t),
                     Cell("—") if t.longest_gap_s is None else Cell(f"{t.longest_gap_s:.3g}",
                                                                     t.longest_gap_s <= limits.max_gap),
                     _d_tau(t, limits), _at_most(t.disagreement_percent, limits.max_disagreement)))
    return Table(heads, tuple(rows))


def _share(value: float | None, least: float, t: TrajectoryVerdict) -> Cell:
    if not t.recorded or value is None:
        return Cell("—")
    return Cell(f"{100 * value:.1f}", value >= least)


def _d_tau(t: TrajectoryVerdict, limits: Thresholds) -> Cell:
    """The step-by-step and base-fit d_tau of a judged trajectory (``—``: none of that kind), both
    against the limit."""
    pair = (t.d_tau_percent, t.base_fit_d_tau_percent)
    values = [v for v in pair if v is not None]
    if not values:
        return Cell("—")
    text = " / ".join("—" if v is None else f"{v:.2f}" for v in pair)
    return Cell(text, all(math.isfinite(v) and v <= limits.max_d_tau for v in values))


def _at_most(value: float | None, limit: float) -> Cell:
    if value is None:
        return Cell("—")
    return Cell(f"{value:.2f}", math.isfinite(value) and value <= limit)


def text_lines(table: Table) -> list[str]:
    """The table as aligned terminal lines, a failed cell marked ``FAIL``."""
    cells = [list(table.heads)] + [[c.text + ("  FAIL" if c.ok is False else "") for c in row] for row in table.rows]
    widths = [max(len(r[k]) for r in cells) for k in range(len(table.heads))]
    return ["  " + "  ".join(text.ljust(w) for text, w in zip(r, widths)).rstrip() for r in cells]
