"""The quality verdict of a result: is it good enough to be marked ``complete``?

Computed from the data and the fit of :func:`ident_hw.experiment.offline.identify`, against the
thresholds of ``identification.quality`` (:class:`ident_hw.config.QualityConfig`):

* per trajectory: the share of its set-points the recording holds (a stopped run, a checkpoint,
  a truncated log), the share of complete cycles, the longest stretch without one, and any
  frame the master could not place in its cycle;
* per step: the condition number of its regressor (columns scaled to unit RMS);
* the base parameters: some physically consistent parameter set reproduces them within their
  covariance (:func:`consistency_reasons`);
* the parameters: how many fitted ones are well identified (%σ at most ``rel_sigma_threshold``);
* per axis, against the axes with the same drive (:func:`axis_reasons`): the gain between its
  measured and predicted forces, and its residual; and against its own current noise at
  standstill, where the campaign recorded one (:func:`floor_reasons`). A model the data contradict on one axis (its
  torque constant, say) shows there, whatever the parameters' sigma say; and the delay of its
  measured forces behind the predicted ones (:func:`force_lags`);
* per validation trajectory (each identification one when there is none): the force prediction
  error d_τ of the step-by-step parameters (and of the base-parameter fit), and how far the
  two predictions are apart. Not on identification trajectories beside a validation one: on
  excitations of small forces (a carriage-only sweep, the squares) quantisation and noise
  weigh on d_τ, and an ill-conditioned step's two predictions part, however good the fit.

The verdict (a :class:`ident_hw.records.Verdict`, stored in ``parameters.json``) lists every
figure, the thresholds and, when it fails, one reason per missed threshold; ``STATUS`` is then
``degraded: <reasons>`` (:func:`ident_hw.results.final_status`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ident_hw.config import ActuatorConfig, QualityConfig
from ident_hw.config.to_drivers import axes_scaling
from ident_hw.identification.metrics import validation_metrics
from ident_hw.records import TrajectoryVerdict, Verdict
from ident_hw.results import Results


#: a lag counts when it exceeds its threshold and this many of its standard errors
LAG_SIGMAS = 5.0


def relative_difference(tau: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """``100 × mean_t(||a_t − b_t|| / ||tau_t||)`` (%) over the samples with ``||tau_t|| > 0``:
    two predictions ``a``, ``b`` (N, 6) compared on the scale of the measured forces ``tau``."""
    norm = np.linalg.norm(tau, axis=1)
    ok = norm > 0
    return 100.0 * float(np.mean(np.linalg.norm(a[ok] - b[ok], axis=1) / norm[ok])) if ok.any() else float("nan")


def consistency_reasons(results: Results) -> list[str]:
    """Why the base parameters do not fit a physical robot, if they do not: no consistent set
    (the step's record says why), or none within the base parameters' covariance (χ² above
    its 95 % quantile: rigid bodies cannot produce what was measured)."""
    out = [f"step {r.name}: no physically consistent parameters ({r.consistency_failure})"
           for r in results.steps if r.consistency_failure]
    c = results.consistent
    if c is not None and not c.reproduces_base:
        out.append(f"no physically consistent parameters reproduce the {c.base_count} base parameters within their "
                   f"covariance (chi2 {c.chi2:.3g} > {c.chi2_limit:.3g}): the forces are not those of rigid bodies "
                   "(check torque constants, gears, leads, the friction model)")
    return out


def same_drive_groups(actuators: Sequence[ActuatorConfig]) -> list[tuple[int, ...]]:
    """The actuators (indices, two or more each) whose currents the drives measure alike: same
    joint kind, drive profile and streamed current. The config's torque constants, gears and
    leads do not group them: one of those mistyped is what :func:`axis_reasons` is to find."""
    groups: dict[tuple, list[int]] = {}
    for i, a in enumerate(actuators):
        groups.setdefault((a.kind, a.profile), []).append(i)
    return [tuple(g) for g in groups.values() if len(g) > 1]


def axis_reasons(results: Results, actuators: Sequence[ActuatorConfig], limits: QualityConfig,
                 judged: Sequence[str] | None = None) -> tuple[dict, dict, list[str]]:
    """Each axis against the other axes of its group (:func:`same_drive_groups`), by what the fit
    leaves unexplained: the measured forces against those the base-parameter fit predicts (the
    step-by-step values' where there is none), on every fitted trajectory.

    * its gain: the least-squares factor ``g`` of ``tau = (1 + g) tau_predicted`` over all the
      trajectories, %. A torque constant, gear or lead off by x % on one axis makes its forces
      x % larger or smaller than those of its twins, which share its parameters (the 3PRRR's
      links, its carriages): the spread of the gains shows it when the residual, spread over
      the twins by the fit, does not;
    * its residual, RMS per trajectory, in the drive's current (A, through the config's force per
      ampere, where one drive's noise and quantisation are those of the next): a model wrong on
      one axis leaves it a residual several times its twins' (a drive whose parameters the fit
      cannot bend to it: the Delta's arms share their platform).

    Only the axes in ``judged`` (None: all) are compared.

    Returns ``({axis: gain - the group's median gain, %}, {axis: worst residual ratio}, reasons)``:
    the ratio is the axis's residual over the median of the others', at its worst trajectory; a
    reason names each axis beyond ``limits.max_axis_gain_spread`` or
    ``limits.max_axis_residual_ratio``. Of two axes alone, the one further off the model is named.
    """
    judged = results.actuators if judged is None else tuple(judged)
    groups = [g for g in (tuple(i for i in group if results.actuators[i] in judged)
                          for group in same_drive_groups(actuators)) if len(g) > 1]
    gain, worst = _gains_and_residuals(results, actuators, groups)
    spreads, reasons = {}, []
    for group in groups:
        names = [results.actuators[i] for i in group]
        # the group's gain: its median (of two, the one nearer the model's)
        typical = (float(np.median(gain[list(group)])) if len(group) > 2
                   else float(min(gain[list(group)], key=abs)))
        for i, name in zip(group, names):
            if name not in worst:           # no fitted trajectory
                continue
            spread = float(gain[i] - typical)
            spreads[name] = spread
            reasons += _axis_texts(name, names, gain[i], typical, spread, worst[name], limits)
    return spreads, {name: w[0] for name, w in worst.items()}, reasons


def floor_reasons(results: Results, actuators: Sequence[ActuatorConfig], limits: QualityConfig,
                  floors: Mapping[str, np.ndarray], judged: Sequence[str] | None = None,
                  named: frozenset[str] = frozenset()) -> tuple[dict[str, float], list[str]]:
    """Each axis's residual against its own noise floor: the RMS of what the fit leaves of its
    measured forces (as :func:`axis_reasons`), in the drive's current, over the RMS current at
    rest through the same filter (``floors``: per fitted trajectory, (a,) A,
    :func:`ident_hw.experiment.offline.noise_floors`). Unlike the comparison with the axes of the
    same drive, this needs no twin: a model wrong on an axis leaves a residual far above what
    its drive's noise and its encoders can make. Which axis it shows on is the fit's doing: on
    the 2R arm a torque constant off on the shoulder shows on the elbow (the shoulder's forces
    are all the parameters', the elbow's a part of them; docs/identification.md), so the reason
    names where it shows, and says so. Only the axes in ``judged`` (None: all). Returns ``({axis: worst ratio over the fitted trajectories}, reasons)``, a
    reason for each axis beyond ``limits.max_residual_over_floor``; of the axes with the same
    drive (:func:`same_drive_groups`) beyond it, only the one furthest above its floor: the fit
    spreads one axis's error over the twins that share its parameters (the 3PRRR's third link's
    error can leave the first further above its floor than the third). Where the
    comparison with the same drives already ``named`` an axis of the group (its gain or residual
    off its twins': the more specific diagnosis), only those of its named axes beyond their floor
    are, not a twin it spread the error onto."""
    judged = results.actuators if judged is None else tuple(judged)
    per_amp = axes_scaling(actuators).force_per_amp
    worst: dict[str, tuple[float, str, float, float]] = {}
    for fit in results.fits:
        floor = floors.get(fit.name)
        if floor is None or not len(fit.t):
            continue
        rms = _residual_rms(fit) / per_amp
        for i, name in enumerate(results.actuators):
            if name in judged and floor[i] > 0 and (name not in worst or rms[i] / floor[i] > worst[name][0]):
                worst[name] = (float(rms[i] / floor[i]), fit.name, float(rms[i]), float(floor[i]))
    beyond = {name for name, w in worst.items() if w[0] > limits.max_residual_over_floor}
    for group in same_drive_groups(actuators):
        names = [results.actuators[i] for i in group]
        over = [n for n in names if n in beyond]
        keep = ({n for n in over if n in named} if named.intersection(names)
                else set(sorted(over, key=lambda n: worst[n][0])[-1:]))
        beyond -= set(over) - keep
    reasons = [f"{name}: residual {1e3 * own:.3g} mA on {trajectory}, {ratio:.1f} times its current noise at "
               f"standstill and encoders ({1e3 * floor:.3g} mA in that trajectory's band; > "
               f"{limits.max_residual_over_floor:g}): the model does not fit {name}; check its torque constant, gear "
               f"ratio or screw lead and its friction, and those of the axes whose parameters it shares (a serial "
               f"arm's shoulder error shows on its elbow)"
               for name, (ratio, trajectory, own, floor) in worst.items() if name in beyond]
    return {name: w[0] for name, w in worst.items()}, reasons


def _residual_rms(fit) -> np.ndarray:
    """(a,) RMS of the measured forces of ``fit`` (a TrajectoryFit) minus the base-parameter
    fit's prediction (the step-by-step values' where there is none), force units."""
    predicted = fit.tau_base if fit.tau_base is not None else fit.tau_model
    return np.sqrt(np.mean((fit.tau - predicted) ** 2, axis=0))


def _gains_and_residuals(results: Results, actuators: Sequence[ActuatorConfig], groups: list[tuple[int, ...]]
                         ) -> tuple[np.ndarray, dict[str, tuple[float, str, float, float]]]:
    """The figures :func:`axis_reasons` judges, over the fitted trajectories: each axis's gain
    (n_axes,), %, and, per axis of ``groups``, its worst residual against its twins as ``(ratio,
    trajectory, its RMS residual in A, the median of the twins' in A)``."""
    per_amp = axes_scaling(actuators).force_per_amp
    worst: dict[str, tuple[float, str, float, float]] = {}
    along, power = np.zeros(len(actuators)), np.zeros(len(actuators))
    for fit in results.fits:
        if not len(fit.t):
            continue
        predicted = fit.tau_base if fit.tau_base is not None else fit.tau_model
        along += np.sum((fit.tau - predicted) * predicted, axis=0)
        power += np.sum(predicted ** 2, axis=0)
        rms = _residual_rms(fit) / per_amp
        for group in groups:
            for i in group:
                others = float(np.median([rms[j] for j in group if j != i]))
                ratio = float(rms[i] / others) if others > 0 else (math.inf if rms[i] > 0 else 1.0)
                name = results.actuators[i]
                if name not in worst or ratio > worst[name][0]:
                    worst[name] = (ratio, fit.name, float(rms[i]), others)
    with np.errstate(invalid="ignore", divide="ignore"):
        gain = 100.0 * along / power
    return gain, worst


def _gain_off(spread: float, limits: QualityConfig) -> bool:
    """An axis's gain ``spread`` (%) from its group's beyond the limit: :func:`axis_reasons` names it."""
    return abs(spread) > limits.max_axis_gain_spread


def _residual_off(ratio: float, limits: QualityConfig) -> bool:
    """An axis's residual ``ratio`` to its twins' beyond the limit: :func:`axis_reasons` names it."""
    return ratio > limits.max_axis_residual_ratio


def _named_against_twins(spreads: Mapping[str, float], ratios: Mapping[str, float],
                        limits: QualityConfig) -> frozenset[str]:
    """The axes :func:`axis_reasons` named, from its ``spreads`` and ``ratios``."""
    return frozenset(n for n, spread in spreads.items() if _gain_off(spread, limits)).union(
        n for n, ratio in ratios.items() if _residual_off(ratio, limits))


def _axis_texts(name: str, names: list[str], gain: float, typical: float, spread: float,
                worst: tuple[float, str, float, float], limits: QualityConfig) -> list[str]:
    """The reasons against one axis of a group ``names``: its gain (%) ``spread`` from the
    group's ``typical`` one beyond ``limits.max_axis_gain_spread``, its ``worst`` residual ratio
    (as in :func:`_gains_and_residuals`) beyond ``limits.max_axis_residual_ratio``."""
    reasons = []
    twins = ", ".join(n for n in names if n != name)
    if _gain_off(spread, limits):
        reasons.append(
            f"{name}: forces {gain:+.2f} % off what the model predicts, against {typical:+.2f} % on the "
            f"same drives ({twins}; {spread:+.2f} % apart, > {limits.max_axis_gain_spread:g} %): check "
            f"{name}'s torque constant, gear ratio or screw lead (off by about {spread:+.1f} %)")
    ratio, trajectory, own, twins_rms = worst
    if _residual_off(ratio, limits):
        reasons.append(
            f"{name}: residual {1e3 * own:.3g} mA on {trajectory}, {ratio:.1f} times that of the same "
            f"drives ({twins}: {1e3 * twins_rms:.3g} mA; > {limits.max_axis_residual_ratio:g}): the model "
            f"does not fit {name}; check its torque constant, gear ratio or screw lead, and its friction")
    return reasons


@dataclass(frozen=True)
class ForceLag:
    """The delay ``seconds`` of an axis's measured forces behind the predicted ones, and its
    standard error ``sigma`` (s) from the residual left beside it (the decimated samples taken
    as independent)."""

    seconds: float
    sigma: float

    def beyond(self, limit: float, sigmas: float = LAG_SIGMAS) -> bool:
        """Larger than ``limit`` and than ``sigmas`` standard errors: a delay the data show."""
        return abs(self.seconds) > limit and abs(self.seconds) > sigmas * self.sigma


def force_lags(results: Results) -> dict[str, ForceLag]:
    """Per axis, the delay ``T`` (s) of the measured forces behind the predicted ones: the
    least-squares ``T`` of ``tau - tau_predicted = -T d(tau_predicted)/dt`` over all fitted
    trajectories (``tau(t) = tau_predicted(t - T)`` to first order), the derivative by central
    differences within each stretch of regular sample times. A model right in time leaves ~0; a
    current filtered by the drive (the averaged current, a first-order 50 Hz low-pass, whose delay
    is 1/(2π·50 Hz) ≈ 3.2 ms) and identified as an instantaneous one leaves that filter's delay on
    every axis.
    On an axis whose forces are small beside its noise (a link on a carriage-heavy excitation)
    ``T`` scatters: its ``sigma`` says by how much."""
    a = len(results.actuators)
    along, power, square, count = np.zeros(a), np.zeros(a), np.zeros(a), 0
    for fit in results.fits:
        if len(fit.t) < 3:
            continue
        predicted = fit.tau_base if fit.tau_base is not None else fit.tau_model
        dt = np.diff(fit.t)
        regular = np.abs(dt - np.median(dt)) <= 0.01 * np.median(dt)
        inner = np.flatnonzero(regular[:-1] & regular[1:]) + 1      # both neighbours a regular step away
        rate = (predicted[inner + 1] - predicted[inner - 1]) / (fit.t[inner + 1] - fit.t[inner - 1])[:, None]
        residual = fit.tau[inner] - predicted[inner]
        along += np.sum(residual * rate, axis=0)
        power += np.sum(rate ** 2, axis=0)
        square += np.sum(residual ** 2, axis=0)
        count += len(inner)
    out = {}
    for j, name in enumerate(results.actuators):
        if count < 3 or not power[j] > 0:
            continue
        lag = -along[j] / power[j]
        left = max(square[j] - lag ** 2 * power[j], 0.0) / (count - 1)    # the residual beside the lag
        out[name] = ForceLag(float(lag), float(math.sqrt(left / power[j])))
    return out


def recording_reasons(results: Results, limits: QualityConfig) -> tuple[dict[str, TrajectoryVerdict], list[str]]:
    """Per trajectory: what its recording covered (``results.trajectories``), and why that is not
    enough (partial or truncated, too few cycles, too few complete, a gap, a frame not placed)."""
    reasons: list[str] = []
    per_traj: dict[str, TrajectoryVerdict] = {}
    for name, used in results.trajectories.items():
        per_traj[name] = TrajectoryVerdict.of(used)
        status = used.recording_status
        if status.startswith(("stopped", "running")):
            reasons.append(f"{name}: partial recording ({status})")
        elif "truncated" in status:
            reasons.append(f"{name}: truncated raw log")
        cov = used.planned_fraction
        if cov is not None and cov < limits.min_coverage:
            reasons.append(f"{name}: {used.cycles} of {used.cycles_planned} cycles recorded "
                           f"({100 * cov:.0f} % < {100 * limits.min_coverage:g} %)")
        if used.valid_fraction < limits.min_valid_fraction:
            reasons.append(f"{name}: {100 * used.valid_fraction:.1f} % of the cycles complete "
                           f"(< {100 * limits.min_valid_fraction:g} %)")
        if used.stretches == 0:
            reasons.append(f"{name}: no stretch of consecutive complete cycles long enough to filter; "
                           f"nothing of it was fitted")
        if used.unplaced_frames:
            reasons.append(f"{name}: {used.unplaced_frames} frame(s) could not be placed in their SYNC "
                           f"cycle (late by more than the assembler's look-ahead, or sent twice)")
        if used.longest_gap_s > limits.max_gap:
            reasons.append(f"{name}: {used.longest_gap_s:.3g} s without a complete cycle (> {limits.max_gap:g} s)")
    return per_traj, reasons


def step_reasons(results: Results, limits: QualityConfig) -> tuple[dict[str, float | None], list[str]]:
    """Per identification step: its scaled condition number (None: not fitted), and why the step
    falls short (not fitted, parameters its data do not excite, ill-conditioned)."""
    reasons: list[str] = []
    steps = {}
    for record in results.steps:
        if record.skipped:
            reasons.append(f"step {record.name}: not fitted ({record.skipped})")
        if record.unexcited:
            reasons.append(f"step {record.name}: {', '.join(record.unexcited)} not excited by its data "
                           "(held at their previous values)")
        cond = record.cond_scaled
        steps[record.name] = cond
        if cond is not None and not cond <= limits.max_condition:
            reasons.append(f"step {record.name}: condition number {cond:.3g} (> {limits.max_condition:g})")
    return steps, reasons


def well_identified_reasons(results: Results, limits: QualityConfig) -> tuple[list[str], list[str]]:
    """The fitted parameters (physical, then base) with %sigma at most the campaign's threshold,
    and a reason when fewer than ``limits.min_well_identified`` are."""
    fitted: list = [r for r in results.parameter_rows() if r.fitted]
    well = [r.name for r in fitted if r.well_identified]
    base_rows = results.base_rows()
    fitted += base_rows
    well += [r.expression for r in base_rows if r.well_identified]
    if fitted and len(well) < limits.min_well_identified:
        return well, [f"{len(well)} of {len(fitted)} fitted parameters well identified "
                      f"(%sigma <= {results.rel_sigma_threshold:g}; at least {limits.min_well_identified} needed)"]
    return well, []


def lag_reasons(lags: dict[str, ForceLag], limits: QualityConfig) -> list[str]:
    """One reason naming the axes whose forces lag (or lead) the model's beyond ``limits.max_force_lag``
    and beyond :data:`LAG_SIGMAS` standard errors."""
    late = {name: lag for name, lag in lags.items() if lag.beyond(limits.max_force_lag)}
    if not late:
        return []
    return ["the measured forces lag the model's by " + ", ".join(
        f"{1e3 * lag.seconds:.2f} ms (sigma {1e3 * lag.sigma:.2g}) on {name}" for name, lag in late.items())
            + f" (> {1e3 * limits.max_force_lag:g} ms): currents averaged by the drive but identified as "
              "instantaneous (bus.current), or sample times off"]


def prediction_reasons(results: Results, limits: QualityConfig,
                       per_traj: dict[str, TrajectoryVerdict]) -> list[str]:
    """On each validation trajectory (each identification one when there is none): the force
    prediction error d_tau of the step-by-step and the base-parameter values, and how far the two
    predictions are apart; the figures go into ``per_traj`` (updated in place)."""
    reasons: list[str] = []
    stepwise = any(r.fitted for r in results.parameter_rows())   # else the table holds the CAD values only
    for fit in [f for f in results.fits if f.role == "validation"] or results.fits:
        figures: dict = {"role": fit.role}
        if len(fit.t):
            predictions = {"step-by-step": fit.tau_model if stepwise else None, "base-parameter": fit.tau_base}
            for label, tau_hat in predictions.items():
                if tau_hat is None:
                    continue
                d_tau = validation_metrics(fit.tau, tau_hat).d_tau_percent
                figures["d_tau_percent" if label == "step-by-step" else "base_fit_d_tau_percent"] = d_tau
                if not d_tau <= limits.max_d_tau:
                    reasons.append(f"{fit.name} ({fit.role}): force prediction error d_tau {d_tau:.1f} % of the "
                                   f"{label} parameters (> {limits.max_d_tau:g} %)")
            if stepwise and fit.tau_base is not None:
                apart = relative_difference(fit.tau, fit.tau_model, fit.tau_base)
                figures["disagreement_percent"] = apart
                if not apart <= limits.max_disagreement:
                    reasons.append(f"{fit.name}: step-by-step and base-parameter predictions {apart:.1f} % apart "
                                   f"(> {limits.max_disagreement:g} %)")
        per_traj[fit.name] = dataclasses.replace(per_traj.get(fit.name, TrajectoryVerdict()), **figures)
    return reasons


def verdict(results: Results, limits: QualityConfig, actuators: Sequence[ActuatorConfig] = (),
            judged_axes: Sequence[str] | None = None, floors: Mapping[str, np.ndarray] | None = None) -> Verdict:
    """The quality verdict of ``results`` (its ``trajectories`` coverage included); ``actuators``:
    the config's, whose drives say which axes :func:`axis_reasons` compares (none: no comparison);
    ``judged_axes``: the axes whose forces the fitted parameters act on, which the axis checks and
    :func:`force_lags` judge (None: every axis); ``floors``: per fitted trajectory, each axis's
    current noise at standstill (:func:`floor_reasons`; None or empty: no such check).
    """
    per_traj, reasons = recording_reasons(results, limits)
    steps, more = step_reasons(results, limits)
    reasons += more
    well, more = well_identified_reasons(results, limits)
    reasons += more
    reasons += consistency_reasons(results)
    axes = results.actuators if judged_axes is None else tuple(judged_axes)
    spreads, ratios, more = axis_reasons(results, actuators, limits, axes)
    reasons += more
    named = _named_against_twins(spreads, ratios, limits)
    over_floor, more = (floor_reasons(results, actuators, limits, floors or {}, axes, named) if actuators
                        else ({}, []))
    reasons += more
    lags = {name: lag for name, lag in force_lags(results).items() if name in axes}
    reasons += lag_reasons(lags, limits)
    reasons += prediction_reasons(results, limits, per_traj)
    return Verdict(passed=not reasons, reasons=tuple(reasons), thresholds=limits,
                   trajectories=per_traj, cond_scaled=steps, well_identified=tuple(well),
                   axis_gain_spread_percent=spreads, axis_residual_ratio=ratios, axis_residual_over_floor=over_floor,
                   force_lag_s={name: lag.seconds for name, lag in lags.items()},
                   force_lag_sigma_s={name: lag.sigma for name, lag in lags.items()}, axes_judged=tuple(axes))
