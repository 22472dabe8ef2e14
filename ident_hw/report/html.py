"""The report as one HTML page (``report.html``), rendered from ``templates/report.html`` with
Jinja2 (every value escaped by the template engine, the page's layout readable in one file)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import jinja2

from ident_hw.identification.model_comparison import EQUATIONS, OUTPUT_UNITS
from ident_hw.records import GainsStep, SkippedStep, TrajectoryMetrics
from ident_hw.storage import to_json
from ident_hw.results import SETTLED, Results, ValidationFigures, estimator_summaries, read_status, validation_figures

from .terminal import accuracy_line, coverage_text
from .verdict import axis_table, status_line, trajectory_table

_ENV = jinja2.Environment(loader=jinja2.PackageLoader("ident_hw.report", "templates"),
                          autoescape=True, undefined=jinja2.StrictUndefined, keep_trailing_newline=True)


def fmt(value, spec: str = ".5g") -> str:
    """A number for a table cell, ``—`` when undefined."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    return format(value, spec)


def fmt_rel(value) -> str:
    """A %σ: two decimals, or ``> 1e4`` for an estimate at zero (its bound)."""
    return "> 1e4" if value is not None and math.isfinite(value) and value > 1e4 else fmt(value, ".2f")


_ENV.filters.update(fmt=fmt, fmt_rel=fmt_rel)


def render_html(folder: Path, results: Results, table: dict[str, TrajectoryMetrics], images: list[tuple[str, Path]]) -> str:
    """The page: summary and verdict first, then the parameter tables (with the dynamic, power and
    energy models' base parameters when the results hold them), the online comparison,
    the force-prediction metrics per trajectory and the plots (``images``: title, PNG path)."""
    rows = results.parameter_rows()
    analysis = results.base_analysis
    validation = validation_figures(results)
    return _ENV.get_template("report.html").render(
        status=read_status(folder), shown_status=status_line(read_status(folder), results.quality),
        axis_table=axis_table(results.quality) if results.quality is not None else None,
        trajectory_table=trajectory_table(results.quality) if results.quality is not None else None,
        results=results, rows=rows, base_rows=results.base_rows(),
        thresholds=to_json(results.quality.thresholds) if results.quality and results.quality.thresholds else {},
        poor=[r.name for r in rows if r.poorly_identified],
        has_truth=results.parameters.truth is not None,
        accuracy=accuracy_line(rows, results.base_fit) if results.parameters.truth is not None else None,
        coverage={name: coverage_text(u) for name, u in results.trajectories.items()},
        base_list=analysis if analysis is not None and analysis.base_parameters and results.base_fit is None else None,
        online=results.online, comparison=estimator_summaries(results.online) if results.online is not None else [],
        settled_percent=100 * SETTLED, metrics=table, actuators=results.actuators,
        equations=EQUATIONS, output_units=OUTPUT_UNITS, validation=validation,
        validation_rows={name: validation_rows(v, results.compared_label) for name, v in validation.items()},
        gains=[(s.name, s.drive_gains) for s in results.steps if isinstance(s, GainsStep)],
        steps=[(s.name, f"not fitted ({s.skipped})" if isinstance(s, SkippedStep) else f"{s.method}; {', '.join(s.free)}")
               for s in results.steps],
        images=[(title, str(path.relative_to(folder))) for title, path in images])


@dataclass(frozen=True)
class ValidationRow:
    """One row of a validation trajectory's table: the ``parameters`` predicting (identified, or
    the set compared), over which ``samples`` (all, moving, at rest, or the share of the residual
    at rest), one figure per actuator (None: none), and the ``mean`` of the whole trajectory's
    row (None: not shown; NaN: a figure missing)."""

    parameters: str
    samples: str
    values: tuple[float | None, ...]
    mean: float | None


def validation_rows(v: ValidationFigures, compared: str | None) -> list[ValidationRow]:
    """The rows of a validation trajectory's table, the identified parameters' then the compared
    set's (:class:`ValidationRow`)."""
    parts = (("all", v.rre_percent), ("moving", v.rre_moving_percent), ("at rest", v.rre_at_rest_percent),
             ("share of the residual at rest", v.residual_share_at_rest_percent))
    out = []
    for label, compared_set in (("identified", False), (compared or "compared", True)):
        for part, pair in parts:
            values = None if pair is None else (pair.compared if compared_set else pair.fit)
            if values is None:
                continue
            mean = None
            if part == "all":
                finite = [x for x in values if x is not None]
                mean = sum(finite) / len(values) if len(finite) == len(values) and values else math.nan
            out.append(ValidationRow(label, part, values, mean))
    return out
