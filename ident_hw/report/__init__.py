"""The report of a results folder (:mod:`ident_hw.results`): terminal tables, PNG plots, one HTML
page and a MATLAB export, built from the folder's files alone (``ident-hw report RESULTS``).

Built files::

    metrics.yaml     per trajectory and actuator: RMS, NRMS, d_tau, J_RMSE
    plots/*.png      forces, residuals, trajectories, online estimates
    report.html      the summary and verdict first, then everything above on one page
    results.mat      parameters and fits for MATLAB (scipy.io.savemat)

They are derived from the folder's own files (whose format version they follow) and carry none.

Modules: :mod:`.terminal` (lines printed at the end of a run), :mod:`.verdict` (the quality
verdict's figures against their limits, for both), :mod:`.plots`, :mod:`.html`
(Jinja2 template ``templates/report.html``), :mod:`.matlab`. Imports :mod:`ident_hw.results`,
the model's names and the identification metrics; nothing of the runner or the drivers.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import yaml

from ident_hw.results import load_results, metrics
from ident_hw.storage import to_json

from .terminal import coverage_text, online_lines, summary_lines

__all__ = ["build_report", "coverage_text", "online_lines", "summary_lines"]


def build_report(folder: str | Path) -> Path:
    """(Re)build metrics.yaml, plots, report.html and results.mat from the folder's files;
    returns the page's path."""
    from . import plots  # matplotlib and Jinja2 here, not at import: the terminal lines need neither
    from .html import render_html
    from .matlab import save_mat
    folder = Path(folder)
    results = load_results(folder)
    table = metrics(results)
    (folder / "metrics.yaml").write_text(yaml.safe_dump({name: to_json(m) for name, m in table.items()},
                                                        sort_keys=False))
    folder_plots = folder / "plots"
    folder_plots.mkdir(exist_ok=True)
    jobs: list[tuple[str, Callable[..., Path], tuple]] = []
    actuators = plots.Actuators(results.actuators, results.actuator_kinds)
    for fit in results.fits:
        jobs.append((f"{fit.role}: {fit.name} — measured vs model", plots.plot_forces,
                     (fit, actuators, folder_plots, results.stepwise_label)))
        jobs.append((f"{fit.name}: residuals", plots.plot_residuals, (fit, actuators, folder_plots)))
        jobs.append((f"{fit.name}: motion", plots.plot_motion, (fit, actuators, folder_plots)))
        if fit.tau_compared is not None and fit.role == "validation":
            jobs.append((f"{fit.name}: identified and {results.compared_label}", plots.plot_compared,
                         (fit, actuators, folder_plots, results.compared_label or "compared")))
    if results.online is not None:
        jobs.append(("online estimates", plots.plot_online, (results.online, results.parameters, folder_plots)))
    images = list(zip([title for title, _, _ in jobs], plots.render([(f, a) for _, f, a in jobs])))
    save_mat(folder / "results.mat", results)
    page = folder / "report.html"
    page.write_text(render_html(folder, results, table, images))
    return page
