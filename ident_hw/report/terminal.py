"""The report as terminal lines: the parameter tables, coverage of the recordings, the online
comparison and the quality verdict (printed at the end of ``ident-hw run``/``identify``/``online``)."""

from __future__ import annotations

import math
from pathlib import Path

from ident_hw.identification.model_comparison import EQUATIONS, ModelComparison, ModelFit
from ident_hw.identification.physical import ConsistentSet
from ident_hw.records import DriveGainsFigures, GainsStep, RecordingCoverage, Verdict
from ident_hw.results import (SETTLED, BaseFit, BaseRow, OnlineTrace, ParameterRow, ValidationFigures,
                              estimator_summaries, load_results, metrics, read_status, validation_figures)

from .verdict import axis_table, not_judged_notes, status_line, text_lines


def summary_lines(folder: str | Path) -> list[str]:
    """The numbers printed at the end of a run: a Table-1-like table of the fitted parameters
    (initial, identified, truth, %sigma, error vs truth), the held ones, the validation errors."""
    results = load_results(folder)
    rows = results.parameter_rows()
    truth = results.parameters.truth is not None
    head = f"  {'parameter':>10} {'unit':>9} {'initial':>11} {'identified':>11} {'%sigma':>7}"
    if truth:
        head += f" {'truth':>11} {'error %':>8} {'err/sigma':>9}"
    lines = [f"status: {status_line(read_status(folder), results.quality)}"]
    lines += recording_lines(results)
    if any(r.fitted for r in rows):
        lines.append("physical parameters, step by step (SQP mass fit of the 3PRRR paper):")
        lines.append(head + "  step")
        for row in rows:
            if not row.fitted:
                continue
            text = (f"  {row.name:>10} {row.unit:>9} {row.initial:>11.5g} {row.identified:>11.5g} "
                    f"{percent(row.rel_sigma_percent):>7}")
            if truth:
                text += f" {row.truth:>11.5g} {_or_nan(row.error_percent):>+8.2f} {_or_nan(row.error_sigmas):>+9.2f}"
            lines.append(text + f"  {row.step}" + ("  poorly identified" if row.poorly_identified else ""))
        held = [r.name for r in rows if not r.fitted]
        if held:
            lines.append(f"  held at their initial values (not fitted by any step): {', '.join(held)}")
    else:
        lines.append("physical parameters: none fitted (the steps fit base parameters only)")
    if results.base_fit is not None:
        lines += _base_fit_lines(results.base_fit)
    if results.model_comparison is not None:
        lines += comparison_lines(results.model_comparison)
    if results.consistent is not None:
        lines += consistent_lines(results.consistent)
    lines += [line for r in results.steps if isinstance(r, GainsStep)
              for line in gains_lines(r.name, r.drive_gains, results.actuators)]
    if truth:
        lines.append(accuracy_line(rows, results.base_fit))
    label = results.stepwise_label
    for name, m in metrics(results).items():
        text = (f"  {m.role:>14} {name}: {label} d_tau = {m.stepwise.d_tau_percent:.2f} %, "
                f"J_RMSE = {m.stepwise.j_rmse:.4g}")
        if m.base_fit is not None:
            text += f"; base fit d_tau = {m.base_fit.d_tau_percent:.2f} %"
        lines.append(text)
    for name, figures in validation_figures(results).items():
        lines += rre_lines(name, figures, results.actuators, results.compared_label)
    if results.quality is not None:
        lines += _verdict_lines(results.quality)
    return lines


def recording_lines(results) -> list[str]:
    """What each recording covered (and how one made elsewhere was read), and the friction model
    identified with where it is not the default."""
    lines = ["recordings used:"] if results.trajectories else []
    for name, used in results.trajectories.items():
        lines.append(f"  {name}: {coverage_text(used)}")
        if used.imported is not None:
            lines += [f"    {line}" for line in used.imported.describe()]
    if results.friction is not None:
        lines.append(results.friction.describe())
    return lines


def coverage_text(used: RecordingCoverage) -> str:
    """``107 of 266 cycles (40 % of the trajectory), 99.1 % complete, ...`` for one recording."""
    planned = used.cycles_planned
    text = f"{used.cycles} of {planned} cycles" if planned else f"{used.cycles} cycles"
    if used.coverage is not None and used.coverage < 1.0:
        text += f" ({100 * used.coverage:.0f} % of the trajectory)"
    text += f", {100 * used.valid_fraction:.1f} % complete"
    if used.longest_gap_s:
        text += f", longest gap {used.longest_gap_s:.3g} s"
    if used.skipped_slots:
        text += f", {used.skipped_slots} SYNC slots skipped"
    if used.prepared:
        text += f"; {used.samples_used} samples after decimation fitted"
        if (used.stretches if used.stretches is not None else 1) > 1:
            text += f" from {used.stretches} stretches"
        out = [f"{n} {rule.replace('_', ' ')}" for rule, n in (used.rows_left_out or {}).items() if n]
        if out:
            text += f" (rows left out: {', '.join(out)})"
        for axis, short in used.shortfalls.items():
            parts = ([f"{short.missing} cycles missing"] if short.missing else []) + (
                [f"{short.saturated} rows saturated (up to {short.peak_A:.3g} A, limit {short.limit_A:.3g} A)"]
                if short.saturated else [])
            text += f"; {axis}: {', '.join(parts)}"
        if used.positions_not_in_counts:
            text += (f"; positions of {', '.join(used.positions_not_in_counts)} not in whole encoder counts: no encoder "
                     "draws, sigma without the encoders' resolution")
    status = used.recording_status
    if status.startswith("stopped"):
        text += f"; partial recording ({status})"
    elif status.startswith("running"):
        text += "; checkpoint of a run that did not end (its process died): partial recording"
    elif status not in ("complete", ""):
        text += f"; {status}"
    return text


def online_lines(online: OnlineTrace) -> list[str]:
    """The comparison of the online estimators, for the terminal: J_RMSE and, after a payload
    change, the settling time of each tracked base parameter."""
    summary = estimator_summaries(online)
    settles = bool(summary and summary[0].settling)
    lines = ["online estimators (J_RMSE: a-priori prediction error in units of the output noise"
             + (f"; settling to within {100 * SETTLED:g} % after the payload change at {online.change_time:.1f} s"
                if settles else "") + "):"]
    for s in summary:
        text = f"  {s.label:>10}: J_RMSE {s.j_rmse:8.3g}"
        if s.diverged_at is not None:
            text += f" (diverged at {s.diverged_at:.1f} s)"
        for name, seconds in s.settling:
            text += f"; {name}: " + ("not settled" if seconds is None else f"{seconds:.1f} s")
        lines.append(text)
    if online.unexcited:
        lines.append(f"  SVD-DLS held (not excited at the end): {'; '.join(online.unexcited)}")
    return lines


def accuracy_line(rows: list[ParameterRow], base_fit: BaseFit | None) -> str:
    """Against the simulated truth: the largest error among the well-identified estimates, the
    largest in units of their own sigma, and those off by more than 2 sigma (whose sigma claims an
    accuracy their error does not have)."""
    judged: list[tuple[str, ParameterRow | BaseRow]] = [
        (r.name, r) for r in rows if r.well_identified and r.error_percent is not None]
    parts = [_largest_errors(judged, "physical parameters")]
    if base_fit is not None:
        base: list[tuple[str, ParameterRow | BaseRow]] = [
            (r.base_parameter, r) for r in base_fit.rows() if r.well_identified and r.error_percent is not None]
        parts.append(_largest_errors(base, "base parameters"))
        judged += base
    text = "accuracy vs truth, well identified only: " + ", ".join(parts)
    beyond = [name for name, r in judged if r.error_sigmas is not None and abs(r.error_sigmas) > 2]
    if beyond:
        text += (f"; off by more than 2 sigma (their sigma understates the error): {len(beyond)}, "
                 + ", ".join(beyond))
    else:
        text += "; every one within 2 sigma of the truth"
    return text


def _largest_errors(judged: list[tuple[str, ParameterRow | BaseRow]], what: str) -> str:
    """``13 physical parameters (largest error 1.16 % m_c; largest error/sigma 1.9 I_ee)``: of
    rows with an error (``error_percent`` not None)."""
    text = f"{len(judged)} {what}"
    errors = [(name, r.error_percent) for name, r in judged if r.error_percent is not None]
    if errors:
        worst = max(errors, key=lambda j: abs(j[1]))
        text += f" (largest error {abs(worst[1]):.2f} %, {worst[0]}"
        with_sigma = [(name, r.error_sigmas) for name, r in judged if r.error_sigmas is not None]
        if with_sigma:
            z = max(with_sigma, key=lambda j: abs(j[1]))
            text += f"; largest |error|/sigma {abs(z[1]):.2f}, {z[0]}"
        text += ")"
    return text


def percent(value: float | None) -> str:
    """A %σ for the terminal tables: two decimals, ``>1e4`` beyond, ``nan`` when undefined."""
    if value is None or not math.isfinite(value):
        return "nan"
    return f"{value:.2f}" if value < 1e4 else ">1e4"


def _or_nan(value: float | None) -> float:
    return math.nan if value is None else value


def _verdict_lines(quality: Verdict) -> list[str]:
    """The quality verdict for the terminal: passed, or DEGRADED with one line per reason; the
    checks it could not make (``noise floor: not judged (no standstill)``) beside the thresholds;
    then each judged axis's figures against their limits (:func:`ident_hw.report.verdict.axis_table`)."""
    where = "; ".join(("identification.quality thresholds",) + not_judged_notes(quality))
    if quality.passed:
        lines = [f"quality verdict: passed ({where})"]
    else:
        lines = [f"quality verdict: DEGRADED ({where}):"] + [f"  {r}" for r in quality.reasons]
    table = axis_table(quality)
    return lines + (["per axis, against the limits:"] + text_lines(table) if table.rows else [])


def model_summary(fit: ModelFit) -> str:
    """``tau = Y pi: 1200 rows, rank 9 of 12, cond 12.3`` for one model of a comparison."""
    text = (f"{EQUATIONS[fit.model]}: {fit.equations} rows, rank {fit.rank} of {fit.free}, "
            f"cond {fit.cond:.3g}")
    return text + (f", windows of {fit.window:.3g} s" if fit.window is not None else "")


def comparison_lines(comparison: ModelComparison) -> list[str]:
    """The dynamic, power and energy models' base parameters (the power-model paper's Table 1):
    one line per model (its equation, rows, rank, condition), then model, base parameter,
    estimate, %sigma and, in simulation, the error against the same combination of the truth."""
    lines = [f"dynamic, power and energy models (the power-model paper), base parameters on "
             f"{', '.join(comparison.trajectories)} (step {comparison.step}):"]
    lines += [f"  {fit.model:<8} {model_summary(fit)}" for fit in comparison.fits]
    rows = [row for fit in comparison.fits for row in fit.rows()]
    truth = comparison.has_truth
    width = max((len(r.expression) for r in rows), default=14)
    lines.append(f"  {'model':<8} {'base parameter':<{width}} {'estimate':>11} {'%sigma':>7}"
                 + (f" {'error %':>8}" if truth else ""))
    for r in rows:
        text = f"  {r.model:<8} {r.expression:<{width}} {r.estimate:>11.5g} {percent(r.rel_sigma_percent):>7}"
        if truth:
            text += f" {_or_nan(r.error_percent):>+8.2f}"
        lines.append(text)
    if comparison.held:
        lines.append(f"  held at known values: {', '.join(comparison.held)}")
    return lines


def _base_fit_lines(fit: BaseFit) -> list[str]:
    """The base-parameter table of :func:`summary_lines`."""
    lines = [f"base parameters, {fit.method} on {', '.join(fit.trajectories)} (step {fit.step}; "
             f"well identified: sigma <= {fit.threshold:g} % of max(|estimate|, physical size)):"]
    width = max(len(e) for e in fit.expressions) if fit.expressions else 10
    head = f"  {'base parameter':<{width}} {'initial':>11} {'identified':>11} {'%sigma':>7}"
    lines.append(head + (f" {'truth':>11} {'error %':>8} {'err/sigma':>9}" if fit.truth is not None else ""))
    for row in fit.rows():
        text = (f"  {row.base_parameter:<{width}} {row.initial:>11.5g} {row.identified:>11.5g} "
                f"{percent(row.rel_sigma_percent):>7}")
        if fit.truth is not None:
            text += f" {row.truth:>11.5g} {_or_nan(row.error_percent):>+8.2f} {_or_nan(row.error_sigmas):>+9.2f}"
        lines.append(text + ("" if row.well_identified else "  poorly identified"))
    if fit.held:
        lines.append(f"  held at known values during this fit: {', '.join(fit.held)}")
    if fit.unexcited:
        lines.append(f"  not excited by {', '.join(fit.trajectories)}: {', '.join(fit.unexcited)}")
    return lines


def consistent_lines(c: ConsistentSet, listed: int = 12) -> list[str]:
    """The physically consistent parameters: how well they reproduce the base parameters, each
    body's margin, then every parameter the data decided (alone or with the prior) and the names
    of those the prior alone decided (the first ``listed``)."""
    verdict = "within" if c.reproduces_base else "NOT within"
    lines = [f"physically consistent parameters ({c.metric} prior, {c.prior_relative:g} scale(s) around the CAD "
             f"values): base parameters reproduced {verdict} their covariance (chi2 {c.chi2:.3g}, 95 % "
             f"quantile {c.chi2_limit:.3g} for {c.base_count})",
             "  bodies (mass kg, smallest eigenvalue of the pseudo-inertia; >= 0 physical): "
             + ", ".join(f"{b.body} {b.mass:.4g} {b.margin:.3g}" for b in c.bodies)]
    errors = c.error_percent()
    width = max((len(n) for n in c.names), default=10)
    lines.append(f"  {'parameter':<{width}} {'CAD':>11} {'consistent':>11} {'%sigma':>7} {'prior %':>7}"
                 + (f" {'truth':>11} {'error %':>8}" if errors is not None else "") + "  decided by")
    for i, name in enumerate(c.names):
        if c.decided_by[i] == "prior":
            continue
        text = (f"  {name:<{width}} {c.prior[i]:>11.5g} {c.values[i]:>11.5g} {percent(c.rel_sigma_percent[i]):>7} "
                f"{100 * c.prior_share[i]:>7.0f}")
        if errors is not None and c.truth is not None:
            text += f" {c.truth[i]:>11.5g} {_or_nan(errors[i]):>+8.2f}"
        lines.append(text + f"  {c.decided_by[i]}")
    prior = [n for n, d in zip(c.names, c.decided_by) if d == "prior"]
    if prior:
        more = f" and {len(prior) - listed} more" if len(prior) > listed else ""
        lines.append(f"  decided by the CAD prior alone ({len(prior)}): {', '.join(prior[:listed])}{more}")
    return lines


def rre_lines(name: str, figures: ValidationFigures, actuators: tuple[str, ...], compared: str | None) -> list[str]:
    """Validation trajectory ``name``'s per-actuator ``rre`` (the UR10e dataset's authors' measure,
    :func:`ident_hw.results.relative_residual_percent`): the identified parameters' and, with
    ``identification.compare_with``, the set from elsewhere's, then the same over the samples where
    each actuator moves and where it is at rest, and the share of the residual the rest holds."""
    width = max(len(a) for a in actuators)
    parts = (("", figures.rre_percent), (" moving", figures.rre_moving_percent),
             (" at rest", figures.rre_at_rest_percent), (" rest share", figures.residual_share_at_rest_percent))
    rows = [("identified", [(part, None if pair is None else pair.fit) for part, pair in parts])]
    if figures.rre_percent.compared is not None:
        rows.append((compared or "compared", [(part, None if pair is None else pair.compared) for part, pair in parts]))
    lines = [f"validation {name}: rre = 100 ||tau - tau_predicted|| / ||tau|| per actuator, %"
             + (" (whole; moving; at rest; share of the squared residual at rest)" if figures.rre_moving_percent else "")]
    label = max(len(r[0]) for r in rows)
    lines.append(f"  {'':<{label}}  " + " ".join(f"{a:>{max(width, 6)}}" for a in actuators) + "    mean")
    for who, values_of in rows:
        for part, row in values_of:
            if row is None:
                continue
            values = [math.nan if v is None else v for v in row]
            finite = [v for v in values if math.isfinite(v)]
            mean = f"{sum(finite) / len(finite):7.2f}" if finite and not part else ""
            lines.append(f"  {(who if not part else part):<{label}}  "
                         + " ".join(f"{v:>{max(width, 6)}.2f}" for v in values) + f" {mean}")
    if figures.at_rest_fraction is not None:
        lines.append(f"  {'at rest':<{label}}  " + " ".join(f"{100 * _or_nan(v):>{max(width, 6)}.1f}"
                                                            for v in figures.at_rest_fraction) + "  % of the samples")
    return lines

def gains_lines(step: str, g: DriveGainsFigures, actuators: tuple[str, ...]) -> list[str]:
    """A ``gains`` step's drive gains beside the config's: identified, sigma (jackknife), config,
    difference (% and in sigma), and the currents' residual at each set of gains."""
    lines = [f"drive gains (step {step}: runs with and without the {g.payload_mass:g} kg payload on "
             f"{', '.join(g.payload_trajectories)}; sigma from a {g.blocks}-block jackknife):",
             f"  {'actuator':<10} {'identified':>10} {'sigma':>8} {'config':>10} {'diff %':>7} {'diff/sigma':>10} "
             f"{'residual A':>10} {'with config':>11}"]
    for a, gain, sigma, config, res, res_c in zip(actuators, g.gains, g.sigma, g.configured, g.residual_rms,
                                                  g.residual_rms_configured):
        diff = 100.0 * (gain - config) / config
        lines.append(f"  {a:<10} {gain:>10.4g} {sigma:>8.2g} {config:>10.4g} {diff:>+7.1f} "
                     f"{(gain - config) / sigma if sigma > 0 else math.nan:>+10.1f} {res:>10.3g} {res_c:>11.3g}")
    if g.mass_axes:
        lines.append(f"  the payload's known mass acts on the forces of {', '.join(g.mass_axes)}; the other gains follow "
                     "only from the parameters the axes share")
    return lines
