"""The report as one HTML page (``report.html``), rendered from ``templates/report.html`` with
Jinja2 (every value escaped by the template engine, the page's layout readable in one file)."""

from __future__ import annotations

import math
from pathlib import Path

import jinja2

from ident_hw.identification.model_comparison import EQUATIONS, OUTPUT_UNITS
from ident_hw.records import TrajectoryMetrics
from ident_hw.results import SETTLED, Results, read_status, validation_figures

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
    return _ENV.get_template("report.html").render(
        status=read_status(folder), shown_status=status_line(read_status(folder), results.quality),
        axis_table=axis_table(results.quality) if results.quality is not None else None,
        trajectory_table=trajectory_table(results.quality) if results.quality is not None else None,
        results=results, rows=rows, base_rows=results.base_rows(),
        poor=[r.name for r in rows if r.poorly_identified],
        has_truth=results.parameters.truth is not None,
        accuracy=accuracy_line(rows, results.base_fit) if results.parameters.truth is not None else None,
        coverage={name: coverage_text(u) for name, u in results.trajectories.items()},
        base_list=analysis if analysis is not None and analysis.expressions and results.base_fit is None else None,
        online=results.online, comparison=results.online.comparison() if results.online is not None else [],
        settled_percent=100 * SETTLED, metrics=table, actuators=results.actuators,
        equations=EQUATIONS, output_units=OUTPUT_UNITS, validation=validation_figures(results),
        gains=[(s.name, s.drive_gains) for s in results.steps if s.drive_gains is not None],
        images=[(title, str(path.relative_to(folder))) for title, path in images])
