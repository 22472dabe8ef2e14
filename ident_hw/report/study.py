"""A Monte-Carlo study's report: the per-parameter table in the terminal and in ``study.html``,
and two plots: each claimed parameter's z-score histogram ((estimate - truth) / σ over the runs,
against the standard normal an honest σ gives) and every run's ``|error|`` against its %σ.

The table's marks: ``claimed`` parameters are those the campaigns call well identified; among
them ``!`` marks one whose σ does not tell the truth (coverage of each run's 95 % interval below
90 %, or a mean error beyond 0.5 mean σ: :attr:`ParameterSummary.honest`). ``P cover`` is the
chance that a calibrated σ covers the truth that rarely or less in as many runs
(:attr:`ParameterSummary.coverage_chance`): a 90 % target fails now and then by chance alone, and the
verdict says which of the coverages that fail are within it for as many claimed parameters, and how
often exactly calibrated σs fail the bar for at least one of them in a study of as many runs
(:attr:`Study.chance_of_failing`).
"""

from __future__ import annotations

import html
import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ident_hw.results.study import (BIAS_TARGET, CHANCE_LEVEL, COVERAGE_TARGET, Z95, ParameterSummary,
                                       RunOutcome, Study)

PLOTS = "plots"


def _fmt(x: float, digits: int = 3) -> str:
    return "—" if x is None or not math.isfinite(x) else f"{x:.{digits}g}"


def _row(s: ParameterSummary) -> list[str]:
    mark = ("!" if not s.honest else "ok") if s.claimed else ""
    return [s.kind, s.name, f"{100 * s.claimed_share:.0f} %", str(s.runs), _fmt(s.truth, 4),
            _fmt(s.mean_error), _fmt(s.std_error), _fmt(s.mean_sigma), _fmt(s.sigma_ratio, 2),
            f"{100 * s.coverage:.0f} %", f"{s.coverage_chance:.2f}", _fmt(s.bias_sigmas, 2), mark]


HEADER = ["kind", "parameter", "claimed", "runs", "truth", "mean err", "std err", "mean σ", "std/σ",
          "cover 95", "P cover", "err/σ", ""]


def study_lines(study: Study) -> list[str]:
    """The study's table as text lines (terminal), with the verdict on the claimed parameters."""
    rows = [HEADER] + [_row(s) for s in study.summary]
    widths = [max(len(r[i]) for r in rows) for i in range(len(HEADER))]
    head = f"study of {study.config_name}: {len(study.outcomes)} of {study.runs_asked} runs finished"
    lines = [head + (f", {len(study.failed)} failed" if study.failed else "")]
    lines += ["  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths)))
              for r in rows]
    lines.append(verdict_line(study))
    return lines


def verdict_line(study: Study) -> str:
    claimed = [s for s in study.summary if s.claimed]
    dishonest = [s.name for s in claimed if not s.honest]
    if not claimed:
        return "no parameter is called well identified"
    if dishonest:
        return (f"{len(dishonest)} of {len(claimed)} claimed parameters have a σ that does not tell the truth "
                f"(coverage < {100 * COVERAGE_TARGET:.0f} % or |mean error| > {BIAS_TARGET} σ): "
                + ", ".join(dishonest) + _chance_note(claimed) + _family_note(study))
    return (f"all {len(claimed)} claimed parameters: coverage ≥ {100 * COVERAGE_TARGET:.0f} %, "
            f"|mean error| ≤ {BIAS_TARGET} σ" + _family_note(study))


def _family_note(study: Study) -> str:
    """How often exactly calibrated σs fail the bar somewhere in a study like this one
    (:attr:`Study.chance_of_failing`): the bar is one test per claimed parameter."""
    rate = study.chance_of_failing
    if rate is None:
        return ""
    return (f"; exactly calibrated σs fail this bar for at least one of them in {100 * rate:.0f} % of "
            f"{study.estimated_runs}-run studies (their errors correlated as these runs show)")


def _chance_note(claimed: list[ParameterSummary]) -> str:
    """The failing coverages (their mean error within the target) that a calibrated σ gives by
    chance: ``P cover`` at least :data:`CHANCE_LEVEL` shared among the claimed parameters
    (Bonferroni: with thirty of them, a 40-run study of calibrated σs has one or two coverages below
    90 % more often than not); or nothing."""
    level = CHANCE_LEVEL / len(claimed)
    chance = [s for s in claimed if not s.honest and s.unbiased and s.coverage_chance >= level]
    if not chance:
        return ""
    return (f"; within chance for calibrated σs (P cover ≥ {CHANCE_LEVEL:g}/{len(claimed)}): "
            + ", ".join(f"{s.name} ({100 * s.coverage:.1f} % of {s.runs} runs, P cover {s.coverage_chance:.3f})"
                        for s in chance))


def _z_scores(outcomes: tuple[RunOutcome, ...], s: ParameterSummary) -> np.ndarray:
    return np.array([(e.value - e.truth) / e.sigma for o in outcomes for e in o.estimates
                     if (e.kind, e.name) == (s.kind, s.name) and e.sigma])


def plot_z_histograms(study: Study, path: Path) -> Path | None:
    """One small histogram per claimed parameter, the standard normal density over it."""
    claimed = [s for s in study.summary if s.claimed]
    if not claimed:
        return None
    cols = min(6, len(claimed))
    rows = math.ceil(len(claimed) / cols)
    fig = Figure(figsize=(2.4 * cols, 1.9 * rows))
    x = np.linspace(-4, 4, 200)
    for k, s in enumerate(claimed):
        ax = fig.add_subplot(rows, cols, k + 1)
        z = _z_scores(study.outcomes, s)
        ax.hist(np.clip(z, -5, 5), bins=list(np.linspace(-5, 5, 21)), density=True, color="tab:blue" if s.honest else "tab:red")
        ax.plot(x, np.exp(-x ** 2 / 2) / math.sqrt(2 * math.pi), "k", lw=1)
        ax.set_title(s.name if len(s.name) < 28 else s.name[:25] + "…", fontsize=7)
        ax.tick_params(labelsize=6)
    fig.suptitle("z = (estimate − truth) / σ over the runs; black: standard normal", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path


def plot_error_vs_sigma(study: Study, path: Path) -> Path | None:
    """Every run's ``|error|`` (%) against its %σ, on log axes, with the ±1.96σ line."""
    points = [(100 * e.sigma / abs(e.value), 100 * abs(e.value - e.truth) / abs(e.truth))
              for o in study.outcomes for e in o.estimates if e.sigma and e.value and e.truth]
    if not points:
        return None
    rel_sigma, error = np.array(points).T
    fig = Figure(figsize=(5.5, 4.2))
    ax = fig.add_subplot(1, 1, 1)
    ax.loglog(rel_sigma, np.maximum(error, 1e-6), ".", ms=3, alpha=0.5)
    span = np.array([rel_sigma.min(), rel_sigma.max()])
    ax.loglog(span, Z95 * span, "k--", lw=1, label="|error| = 1.96 σ")
    ax.set_xlabel("%σ reported")
    ax.set_ylabel("|error| %")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path


def write_study_report(study: Study) -> Path:
    """``study.html`` and its plots in the study folder; returns the page's path."""
    plots = study.folder / PLOTS
    plots.mkdir(exist_ok=True)
    images = [p for p in (plot_z_histograms(study, plots / "z_scores.png"),
                          plot_error_vs_sigma(study, plots / "error_vs_sigma.png")) if p is not None]
    cells = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in _row(s)) + "</tr>\n"
                    for s in study.summary)
    failed = "".join(f"<li>run {o.index} (seed {o.seed}): {html.escape(o.error or '')}</li>" for o in study.failed)
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>Study of {html.escape(study.config_name)}</title>
<style>body{{font-family:sans-serif;margin:2em}} table{{border-collapse:collapse;font-size:13px}}
td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}} td:nth-child(2){{text-align:left}}</style>
</head><body>
<h1>Monte-Carlo study of {html.escape(study.config_name)}</h1>
<p>{len(study.outcomes)} of {study.runs_asked} runs finished; run i has the noise seed <code>sim.seed + i</code>.
Per parameter over the runs: the mean and the standard deviation of the error (estimate − truth, SI units),
the mean σ the runs reported, their ratio, the coverage of each run's 95 % interval (±1.96σ, wider where
a few encoder draws make much of σ) and the mean error in mean σ.
<em>claimed</em>: the share of the runs that call the parameter well identified.</p>
<p><strong>{html.escape(verdict_line(study))}</strong></p>
<table><tr>{''.join(f'<th>{html.escape(h)}</th>' for h in HEADER)}</tr>
{cells}</table>
{'<h2>Failed runs</h2><ul>' + failed + '</ul>' if failed else ''}
{''.join(f'<p><img src="{PLOTS}/{p.name}"></p>' for p in images)}
</body></html>
"""
    path = study.folder / "study.html"
    path.write_text(page)
    return path
