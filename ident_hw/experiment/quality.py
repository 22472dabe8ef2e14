"""The quality verdict of a result: is it good enough to be marked ``complete``?

Computed from the data and the fit of :func:`ident_hw.experiment.offline.identify`, against the
thresholds of ``identification.quality`` (:class:`ident_hw.config.QualityConfig`, judged as the
:class:`ident_hw.records.Thresholds` the verdict stores, :func:`thresholds_of`):

* per trajectory: the share of its set-points the recording holds (a stopped run, a checkpoint,
  a truncated log), the share of complete cycles, the longest stretch without one, and any
  frame the master could not place in its cycle;
* per step: the condition number of its regressor (columns scaled to unit RMS);
* the base parameters: some physically consistent parameter set reproduces them within their
  covariance (:func:`consistency_reasons`);
* the parameters: how many fitted ones are well identified (%σ at most ``rel_sigma_threshold``);
* per axis, each on its own and against nothing but itself (:func:`axis_figures`): its gain,
  the factor its forces stand from its own model with every fitted parameter refitted
  (:func:`ident_hw.identification.axis_gain.axis_gains`: a torque constant, gear ratio or screw
  lead off); its residual over what noise alone leaves it, on the rows the fits used, where the
  campaign recorded a standstill (:func:`floor_figures`); and the delay of its measured forces
  behind the predicted ones (:func:`force_lags`). No axis is compared with a twin: a real
  robot's joints differ in friction, rotor inertia and noise, and the verdict must pass a
  correct model of them. A check that cannot be made (no standstill: no noise floor) is
  listed as not judged, with why;
* per validation trajectory (each identification one when there is none): the force prediction
  error d_τ of the step-by-step parameters (and of the base-parameter fit), and how far the
  two predictions are apart. Not on identification trajectories beside a validation one: on
  excitations of small forces (a carriage-only sweep, the squares) quantisation and noise
  weigh on d_τ, and an ill-conditioned step's two predictions part, however good the fit.

The verdict (a :class:`ident_hw.records.Verdict`, stored in ``parameters.json``) lists every
figure, the thresholds and, when it fails, one reason per missed threshold, each once, the first
causes (what the recordings lack: a stop, saturated currents, incomplete cycles, gaps) before
their consequences (nothing to fit, a step not fitted, the predictions); ``STATUS`` is then
``degraded: <reasons>`` (:func:`ident_hw.results.final_status`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ident_hw.config import QualityConfig
from ident_hw.identification.axis_gain import AxisGains
from ident_hw.identification.metrics import validation_metrics
from ident_hw.records import (AxisFigures, BaseStep, MassFitStep, SkippedStep, StepVerdict, Thresholds,
                              TrajectoryVerdict, Verdict)
from ident_hw.results import Results, relative_residual_percent


#: a lag counts when it exceeds its threshold and this many of its standard errors
LAG_SIGMAS = 5.0


def thresholds_of(quality: QualityConfig) -> Thresholds:
    """The limits of ``identification.quality`` as the verdict stores them (:class:`Thresholds`):
    the one place a config key meets a key of the results format."""
    return Thresholds(min_coverage=quality.min_coverage, min_valid_fraction=quality.min_valid_fraction,
                      max_gap=quality.max_gap, max_condition=quality.max_condition, max_d_tau=quality.max_d_tau,
                      max_disagreement=quality.max_disagreement, min_well_identified=quality.min_well_identified,
                      max_force_lag=quality.max_force_lag, max_axis_gain=quality.max_axis_gain,
                      max_axis_rre=quality.max_axis_rre, min_lag_share=quality.min_lag_share,
                      max_residual_over_floor=quality.max_residual_over_floor)


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
    out = [f"step {r.name}: no physically consistent parameters ({r.consistent})"
           for r in results.steps if isinstance(r, BaseStep) and r.consistent]
    c = results.consistent
    if c is not None and not c.reproduces_base:
        out.append(f"no physically consistent parameters reproduce the {c.base_count} base parameters within their "
                   f"covariance (chi2 {c.chi2:.3g} > {c.chi2_limit:.3g}): the forces are not those of rigid bodies "
                   "(check torque constants, gears, leads, the friction model)")
    return out


@dataclass(frozen=True)
class AxisEvidence:
    """What the per-axis checks judge beside the fits (gathered by
    :func:`ident_hw.experiment.offline.identify`, which holds the regressor).

    ``judged``: the axes some fitted parameter acts on; ``gains``: each axis's gain against its
    own model with every fitted parameter refitted (:func:`ident_hw.identification.axis_gain.axis_gains`;
    None: nothing was fitted); ``floors``: per fitted trajectory, (a,) what noise alone leaves
    each axis on the rows the fits used, in its drive's current, A (NaN: no such row;
    :func:`ident_hw.experiment.evidence.noise_floors`), empty when there is none and
    ``floor_missing`` says why (``"no standstill"``); ``sharing``: per axis, the axes some fitted
    parameter acts on together with it (:func:`ident_hw.identification.axis_gain.sharing_axes`)."""

    judged: tuple[str, ...]
    gains: AxisGains | None = None
    floors: Mapping[str, np.ndarray] = field(default_factory=dict)
    floor_missing: str | None = None
    sharing: Mapping[str, tuple[str, ...]] = field(default_factory=dict)


@dataclass(frozen=True)
class FloorFigure:
    """An axis's worst residual over its noise floor: the ``ratio``, on ``trajectory``, of the
    RMS ``residual`` to the ``floor`` (its drive's current, A), on the rows the fits used."""

    ratio: float
    trajectory: str
    residual: float
    floor: float


def floor_figures(results: Results, force_per_amp: np.ndarray, floors: Mapping[str, np.ndarray],
                  judged: Sequence[str] | None = None) -> dict[str, FloorFigure]:
    """Each judged axis's residual against its own noise floor, at its worst fitted trajectory:
    the RMS of what the fit leaves of its measured forces (``_residual``) over the rows the
    fits used (``TrajectoryFit.moving``: at rest a joint's friction holds whatever the last
    motion left, which no rate-dependent friction model predicts, and the fits leave those rows
    out), in the drive's current, over ``floors`` (per fitted trajectory, (a,) A, on the same
    rows). Needs no twin axis: a model wrong on an axis leaves it a residual far above what its
    drive's noise and its encoders can make, however it differs from the others. Only the axes
    in ``judged`` (None: all) with rows and a floor; ``force_per_amp`` (a,): each actuator's
    force per ampere, N·m/A | N/A."""
    judged = results.actuators if judged is None else tuple(judged)
    per_amp = force_per_amp
    worst: dict[str, FloorFigure] = {}
    for fit in results.fits:
        floor = floors.get(fit.name)
        if floor is None or not len(fit.t):
            continue
        left, used = _residual(fit), fit.used()
        for i, name in enumerate(results.actuators):
            if name not in judged or not used[:, i].any() or not floor[i] > 0:
                continue
            rms = float(np.sqrt(np.mean(left[used[:, i], i] ** 2)) / per_amp[i])
            if name not in worst or rms / floor[i] > worst[name].ratio:
                worst[name] = FloorFigure(rms / float(floor[i]), fit.name, rms, float(floor[i]))
    return worst


def _residual(fit) -> np.ndarray:
    """(N, a) the measured forces of ``fit`` (a TrajectoryFit) minus the base-parameter fit's
    prediction (the step-by-step values' where there is none), force units."""
    predicted = fit.tau_base if fit.tau_base is not None else fit.tau_model
    return fit.tau - predicted


def gain_reasons(gains: AxisGains | None, limits: Thresholds,
                 over_floor: Mapping[str, FloorFigure] = {}) -> list[str]:
    """One reason per axis :func:`ident_hw.identification.axis_gain.axis_gains` names (its gain
    beyond ``limits.max_axis_gain``), with the axes whose gain would fit as well, and, on the
    first, the axes its error leaves above their noise floor (``over_floor``: those beyond
    ``limits.max_residual_over_floor``; the fit spreads one axis's error over the axes sharing
    its parameters, and the gain names the first cause)."""
    reasons = []
    for k, named in enumerate(() if gains is None else gains.named):
        text = (f"{named.axis}: forces {named.percent:+.2f} % (sigma {named.sigma_percent:.2g} %) off the model, every "
                f"fitted parameter refitted with its gain free (> {limits.max_axis_gain:g} %): check {named.axis}'s "
                f"torque constant, gear ratio or screw lead (off by about {named.percent:+.1f} %)")
        if named.alike:
            text += ("; or " + ", ".join(f"{axis}'s (off by about {percent:+.1f} %)" for axis, percent in named.alike)
                     + ": the data fit either as well (every parameter scaled alike moves one's error onto the other)")
        if k == 0 and over_floor:
            text += "; left above the noise floor with it: " + _floor_list(over_floor)
        reasons.append(text)
    return reasons


def floor_reason(over_floor: Mapping[str, FloorFigure], limits: Thresholds,
                 sharing: Mapping[str, tuple[str, ...]] = {}) -> list[str]:
    """The reason naming every axis whose residual is beyond ``limits.max_residual_over_floor``
    times its noise floor (``over_floor``: those axes' :class:`FloorFigure`), or none. Which axis
    it shows on is the fit's doing: an error of one axis can show on the axes it shares
    parameters with (``sharing``), which the reason names."""
    if not over_floor:
        return []
    names = list(over_floor)
    figures = "; ".join(f"{name} {1e3 * f.residual:.3g} mA on {f.trajectory} against {1e3 * f.floor:.3g} mA"
                        for name, f in over_floor.items())
    others = [a for name in names for a in sharing.get(name, ()) if a not in names]
    shared = f", and those of the axes sharing their parameters ({', '.join(dict.fromkeys(others))})" if others else ""
    if len(names) == 1:
        head = f"{names[0]}: residual {over_floor[names[0]].ratio:.1f} times"
        them = names[0]
    else:
        head = f"{', '.join(names)}: residuals " + ", ".join(f"{f.ratio:.1f}" for f in over_floor.values()) + " times"
        them = "them"
    return [f"{head} what noise alone leaves (current noise at standstill and encoders, on the rows fitted: "
            f"{figures}; > {limits.max_residual_over_floor:g}): the model does not fit {them}; check the friction "
            f"model, torque constant, gear ratio or screw lead of {', '.join(names)}{shared}"]


def _floor_list(over_floor: Mapping[str, FloorFigure]) -> str:
    """``theta1 6.1 (square1) and theta2 5.1 (square4) times their noise floor``."""
    parts = [f"{name} {f.ratio:.1f} ({f.trajectory})" for name, f in over_floor.items()]
    return (" and ".join([", ".join(parts[:-1]), parts[-1]] if len(parts) > 1 else parts)
            + (" times their noise floor" if len(parts) > 1 else " times its noise floor"))


@dataclass(frozen=True)
class ForceLag:
    """The delay ``seconds`` of an axis's measured forces behind the predicted ones, and its
    standard error ``sigma`` (s) from the residual left beside it (the decimated samples taken
    as independent)."""

    seconds: float
    sigma: float
    explained: float = 1.0

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
        out[name] = ForceLag(float(lag), float(math.sqrt(left / power[j])),
                             float(lag ** 2 * power[j] / square[j]) if square[j] > 0 else 0.0)
    return out


def recording_reasons(results: Results, limits: Thresholds) -> tuple[dict[str, TrajectoryVerdict], list[str]]:
    """Per trajectory: what its recording covered (``results.trajectories``), and why that is not
    enough, first causes first: a stop or a truncated log (and the cycles it lost), saturated
    currents (more than ``1 - min_valid_fraction`` of the rows, or every usable one: which
    drive, how far beyond its limit), incomplete cycles (which drives' frames are missing), a
    frame not placed, a gap; then, after every trajectory's causes, their consequence: a
    recording with no stretch long enough to filter (what left its rows out)."""
    causes: list[str] = []
    consequences: list[str] = []
    per_traj: dict[str, TrajectoryVerdict] = {}
    for name, used in results.trajectories.items():
        per_traj[name] = TrajectoryVerdict.of(used)
        status = used.recording_status
        if status.startswith(("stopped", "running")):
            causes.append(f"{name}: partial recording ({status})")
        elif "truncated" in status:
            causes.append(f"{name}: truncated raw log")
        cov = used.coverage
        if cov is not None and cov < limits.min_coverage:
            causes.append(f"{name}: {used.cycles} of {used.cycles_planned} cycles recorded "
                          f"({100 * cov:.0f} % < {100 * limits.min_coverage:g} %)")
        saturated = {axis: f for axis, f in used.shortfalls.items() if f.saturated}
        rows = max(used.cycles, 1)
        clipped = sum(f.saturated for f in saturated.values())
        if saturated and (used.stretches == 0 or clipped > (1 - limits.min_valid_fraction) * rows):
            causes.append(f"{name}: currents at their drive's limit, clipped, not measured (rows left out): "
                          + "; ".join(_saturation_text(axis, f, used.cycles) for axis, f in saturated.items()))
        if used.valid_fraction < limits.min_valid_fraction:
            missing = {axis: f.missing for axis, f in used.shortfalls.items() if f.missing}
            which = ("; missing: " + ", ".join(f"{axis} in {n} cycles" for axis, n in missing.items())
                     if missing else "")
            causes.append(f"{name}: {100 * used.valid_fraction:.1f} % of the cycles complete "
                          f"(< {100 * limits.min_valid_fraction:g} %){which}")
        if used.unplaced_frames:
            causes.append(f"{name}: {used.unplaced_frames} frame(s) could not be placed in their SYNC "
                          f"cycle (late by more than the assembler's look-ahead, or sent twice)")
        if used.longest_gap_s > limits.max_gap:
            causes.append(f"{name}: {used.longest_gap_s:.3g} s without a complete cycle (> {limits.max_gap:g} s)")
        if used.stretches == 0:
            out = [f"{n} {rule.replace('_', ' ')}" for rule, n in (used.rows_left_out or {}).items() if n]
            consequences.append(f"{name}: no stretch of consecutive usable rows long enough to filter"
                                + (f" (rows left out: {', '.join(out)})" if out else "")
                                + "; nothing of it was fitted")
    return per_traj, causes + consequences


#: a current this many times its drive's limit was not limited by the drive: the recording's scaling is off
BEYOND_LIMIT = 1.5


def _saturation_text(axis: str, shortfall, cycles: int) -> str:
    """``zeta2 in 1005 of 1005 rows, up to 71 A against its 8 A limit: ...`` with what to check:
    a current far beyond the limit the drive enforces was not measured in A (another drive's log,
    another scaling); one at the limit means the motion asks more than the drive may give."""
    text = (f"{axis} in {shortfall.saturated} of {cycles} rows, up to {shortfall.peak_A:.3g} A against its "
            f"{shortfall.limit_A:.3g} A limit")
    if shortfall.peak_A is not None and shortfall.peak_A > BEYOND_LIMIT * shortfall.limit_A:
        return text + " (beyond what the drive lets through: check the recording's current scaling and drive type)"
    return text + " (slow the trajectory down, or raise limits.current if the motor allows)"


def step_reasons(results: Results, limits: Thresholds) -> tuple[dict[str, StepVerdict], list[str]]:
    """Per identification step: its scaled condition number (None: not fitted), and why the step
    falls short (not fitted, parameters its data do not excite, ill-conditioned)."""
    reasons: list[str] = []
    steps = {}
    for record in results.steps:
        if isinstance(record, SkippedStep):
            reasons.append(f"step {record.name}: not fitted ({record.skipped})")
        if isinstance(record, MassFitStep) and record.unexcited:
            reasons.append(f"step {record.name}: {', '.join(record.unexcited)} not excited by its data "
                           "(held at their previous values)")
        cond = record.cond_scaled if isinstance(record, (MassFitStep, BaseStep)) else None
        steps[record.name] = StepVerdict(cond)
        if cond is not None and not cond <= limits.max_condition:
            reasons.append(f"step {record.name}: condition number {cond:.3g} (> {limits.max_condition:g})")
    return steps, reasons


def well_identified_reasons(results: Results, limits: Thresholds) -> tuple[list[str], list[str]]:
    """The fitted parameters (physical, then base) well identified (%sigma at most the campaign's
    threshold; a base parameter: sigma at most that share of the larger of its estimate and its
    physical size, :mod:`ident_hw.identification.physical_size`), and a reason when fewer than
    ``limits.min_well_identified`` are."""
    fitted: list = [r for r in results.parameter_rows() if r.fitted]
    well = [r.name for r in fitted if r.well_identified]
    base_rows = results.base_rows()
    fitted += base_rows
    well += [r.base_parameter for r in base_rows if r.well_identified]
    if fitted and len(well) < limits.min_well_identified:
        return well, [f"{len(well)} of {len(fitted)} fitted parameters well identified "
                      f"(sigma <= {results.rel_sigma_threshold:g} % of the estimate, or of a base parameter's "
                      f"physical size; at least {limits.min_well_identified} needed)"]
    return well, []


def lag_failed(lag: ForceLag, limits: Thresholds) -> bool:
    """A lag beyond ``limits.max_force_lag`` and :data:`LAG_SIGMAS` standard errors that accounts for
    at least ``limits.min_lag_share`` of its axis's residual: a time misalignment, which the verdict fails."""
    return lag.beyond(limits.max_force_lag) and lag.explained >= limits.min_lag_share


def lag_reasons(lags: dict[str, ForceLag], limits: Thresholds) -> tuple[list[str], list[str]]:
    """One reason naming the axes whose forces lag (or lead) the model's (:func:`lag_failed`), and
    one note naming those whose lag is beyond the limit but a small share of a larger residual (a
    limit of the model, such as an elastic joint's, not a clock's)."""
    late = {name: lag for name, lag in lags.items() if lag_failed(lag, limits)}
    small = {name: lag for name, lag in lags.items() if lag.beyond(limits.max_force_lag) and name not in late}
    reasons = (["the measured forces lag the model's by " + ", ".join(
        f"{1e3 * lag.seconds:.2f} ms (sigma {1e3 * lag.sigma:.2g}, {100 * lag.explained:.0f} % of its residual) on "
        f"{name}" for name, lag in late.items())
        + f" (> {1e3 * limits.max_force_lag:g} ms): currents averaged by the drive but identified as "
          "instantaneous (bus.current), or sample times off"] if late else [])
    notes = (["the measured forces lead or lag the model's by " + ", ".join(
        f"{1e3 * lag.seconds:+.2f} ms on {name} ({100 * lag.explained:.0f} % of its residual)" for name, lag in small.items())
        + f": beyond {1e3 * limits.max_force_lag:g} ms, but less than {100 * limits.min_lag_share:.0f} % of what the "
          "model leaves: a limit of the model beside a larger residual (a real joint's elasticity: the motor's "
          "current leads its link), not a time misalignment"] if small else [])
    return reasons, notes


@dataclass(frozen=True)
class Predictions:
    """The predictions judged (:func:`prediction_reasons`): each trajectory's verdict with the
    figures of its predictions, and the reasons."""

    trajectories: Mapping[str, TrajectoryVerdict]
    reasons: tuple[str, ...]


def prediction_reasons(results: Results, limits: Thresholds,
                       recorded: Mapping[str, TrajectoryVerdict]) -> Predictions:
    """On each validation trajectory (each identification one when there is none): the force
    prediction error d_tau of the step-by-step and the base-parameter values, and how far the two
    predictions are apart; ``recorded``: each trajectory's verdict of its recording, which the
    figures join (a new record each)."""
    reasons: list[str] = []
    per_traj = dict(recorded)
    stepwise = any(r.fitted for r in results.parameter_rows())   # else the table holds the CAD values only
    for fit in [f for f in results.fits if f.role == "validation"] or results.fits:
        figures: dict = {"role": fit.role}
        if len(fit.t):
            predictions = {"step-by-step": fit.tau_model if stepwise else None, "base-fit": fit.tau_base}
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
    return Predictions(per_traj, tuple(reasons))


@dataclass(frozen=True)
class PredictionFigure:
    """An axis's worst relative residual where it moves (%, :func:`prediction_figures`), of the
    identified parameters ``rre`` and of the physically consistent ones ``consistent`` (None:
    none), on ``trajectory``."""

    rre: float
    consistent: float | None
    trajectory: str


def prediction_figures(results: Results, judged: Sequence[str]) -> dict[str, PredictionFigure]:
    """Per judged axis, its worst ``rre = 100 ||tau - tau_predicted|| / ||tau||`` over the samples
    where it moves (not at rest, :attr:`ident_hw.results.TrajectoryFit.at_rest`) on the validation
    trajectories, each identification one when there is none: of the identified parameters and
    of the physically consistent ones. At rest a real joint holds whatever friction its last motion
    left: what a model predicts there is reported (:class:`ident_hw.results.ValidationFigures`),
    not judged."""
    fits = [f for f in results.fits if f.role == "validation" and len(f.t)] or [f for f in results.fits if len(f.t)]
    out: dict[str, PredictionFigure] = {}
    for fit in fits:
        moving = None if fit.at_rest is None else ~fit.at_rest
        own = relative_residual_percent(fit.tau, fit.tau_fit, moving)
        consistent = (None if fit.tau_consistent is None
                      else relative_residual_percent(fit.tau, fit.tau_consistent, moving))
        for j, name in enumerate(results.actuators):
            if name not in judged or not math.isfinite(own[j]):
                continue
            worst = max(own[j], consistent[j] if consistent is not None and math.isfinite(consistent[j]) else 0.0)
            if name not in out or worst > max(out[name].rre, out[name].consistent or 0.0):
                out[name] = PredictionFigure(float(own[j]), None if consistent is None else float(consistent[j]),
                                             fit.name)
    return out


def prediction_reasons_per_axis(figures: Mapping[str, AxisFigures], limits: Thresholds) -> list[str]:
    """A reason per axis whose forces the identified (or the physically consistent) parameters do
    not predict within ``limits.max_axis_rre`` where it moves (its :class:`AxisFigures`)."""
    out = []
    for name, f in figures.items():
        worst = [(label, value) for label, value in (("identified", f.rre_percent),
                                                     ("physically consistent", f.rre_consistent_percent))
                 if value is not None and value > limits.max_axis_rre]
        if worst:
            out.append(f"{name}: the {' and the '.join(label for label, _ in worst)} parameters predict its forces on "
                       f"{f.rre_trajectory} with rre {', '.join(f'{v:.1f}' for _, v in worst)} % where it moves (> "
                       f"{limits.max_axis_rre:g} %): check its current's column, sign and gain, and that its positions "
                       "and currents come from one run")
    return out


@dataclass(frozen=True)
class AxisChecks:
    """What the per-axis checks found (:func:`axis_figures`): the figures per axis, the checks not
    judged (and why), the reasons (a gain first, the cause; the floor's, folded into the gain's
    when a gain was named: it is then that axis's error spread by the fit; the lags) and the
    notes (what is seen and not failed on)."""

    figures: Mapping[str, AxisFigures]
    not_judged: Mapping[str, str]
    reasons: tuple[str, ...]
    notes: tuple[str, ...]


def axis_figures(results: Results, limits: Thresholds, force_per_amp: np.ndarray | None,
                 evidence: AxisEvidence) -> AxisChecks:
    """The per-axis checks: each judged axis's gain against its own model refitted, its
    residual against its own noise floor, the lag of its forces; each axis on its own, none
    against another (:class:`AxisChecks`)."""
    judged = evidence.judged
    over = floor_figures(results, force_per_amp, evidence.floors, judged) if force_per_amp is not None else {}
    beyond = {name: f for name, f in over.items() if f.ratio > limits.max_residual_over_floor}
    gains = evidence.gains
    named = {n.axis for n in gains.named} if gains is not None else set()
    reasons = gain_reasons(gains, limits, beyond)
    if not named:
        reasons += floor_reason(beyond, limits, evidence.sharing)
    lags = {name: lag for name, lag in force_lags(results).items() if name in judged}
    more, notes = lag_reasons(lags, limits)
    reasons += more
    predicted = prediction_figures(results, judged)     # its reasons come with the predictions' (consequences)
    not_judged: dict[str, str] = {}
    if gains is None:
        not_judged["gain"] = "nothing fitted"
    else:
        loose = [name for name in judged if name in gains.gains and not gains.gains[name].determined(limits.max_axis_gain)]
        if loose:
            not_judged["gain"] = (f"not determined on {', '.join(loose)}: the data do not resolve a gain of "
                                  f"{limits.max_axis_gain:g} % there (the axis's own parameters, or the gain of an "
                                  "axis named, take it)")
    if evidence.floor_missing:
        not_judged["noise floor"] = evidence.floor_missing
    figures = {}
    for name in judged:
        gain = gains.gains.get(name) if gains is not None else None
        if gain is not None and not gain.determined(limits.max_axis_gain):
            gain = None
        floor, lag, prediction = over.get(name), lags.get(name), predicted.get(name)
        mispredicted = prediction is not None and max(prediction.rre, prediction.consistent or 0.0) > limits.max_axis_rre
        failed = tuple(check for check, off in (("gain", name in named), ("noise floor", name in beyond),
                                                ("force lag", lag is not None and lag_failed(lag, limits)),
                                                ("prediction", mispredicted))
                       if off)
        figures[name] = AxisFigures(
            gain_percent=None if gain is None else gain.percent, gain_sigma_percent=None if gain is None else gain.sigma_percent,
            residual_over_floor=None if floor is None else floor.ratio, floor_trajectory=None if floor is None else floor.trajectory,
            residual_A=None if floor is None else floor.residual, floor_A=None if floor is None else floor.floor,
            force_lag_s=None if lag is None else lag.seconds, force_lag_sigma_s=None if lag is None else lag.sigma,
            force_lag_share=None if lag is None else lag.explained,
            rre_percent=None if prediction is None else prediction.rre,
            rre_consistent_percent=None if prediction is None else prediction.consistent,
            rre_trajectory=None if prediction is None else prediction.trajectory, failed=failed)
    return AxisChecks(figures, not_judged, tuple(reasons), tuple(notes))


def verdict(results: Results, limits: Thresholds, force_per_amp: np.ndarray | None = None,
            evidence: AxisEvidence | None = None) -> Verdict:
    """The quality verdict of ``results`` (its ``trajectories`` coverage included) against the
    ``limits``; ``force_per_amp`` (a,): each actuator's force per ampere, N·m/A | N/A (it puts
    residuals in each drive's current; None: no floor check); ``evidence``: what the per-axis checks judge (:class:`AxisEvidence`; None: every
    axis, no gains, no floors). The reasons come in order of cause: what the recordings lack,
    the steps, each axis (a drive's data off), then what follows: the parameters, their
    physical consistency, the predictions."""
    per_traj, reasons = recording_reasons(results, limits)
    steps, more = step_reasons(results, limits)
    reasons += more
    if evidence is None:
        evidence = AxisEvidence(judged=tuple(results.actuators), floor_missing="no noise floors given")
    checks = axis_figures(results, limits, force_per_amp, evidence)
    axes, not_judged, notes = checks.figures, dict(checks.not_judged), checks.notes
    reasons += checks.reasons   # an axis's drive data off: the cause of what follows
    well, more = well_identified_reasons(results, limits)
    reasons += more
    noise_only = noise_dominated(axes, limits)
    if noise_only is True or results.consistent is None:
        reasons += consistency_reasons(results)
    else:
        reasons += [r for r in consistency_reasons(results) if r.startswith("step ")]
        c = results.consistent
        if not c.reproduces_base:
            not_judged["physical consistency chi2"] = (
                f"chi2 {c.chi2:.3g} against a {c.chi2_limit:.3g} quantile, but {noise_only}: the base parameters' "
                "covariance describes noise, not the model's own error; the physically consistent parameters' "
                f"prediction is judged instead (rre where each axis moves, <= {limits.max_axis_rre:g} %)")
    reasons += prediction_reasons_per_axis({name: figures for name, figures in axes.items()
                                            if figures.rre_percent is not None}, limits)
    predictions = prediction_reasons(results, limits, per_traj)
    reasons += predictions.reasons
    per_traj = dict(predictions.trajectories)
    return Verdict(passed=not reasons, reasons=tuple(dict.fromkeys(reasons)), thresholds=limits,
                   trajectories=per_traj, steps=steps, well_identified=tuple(well), axes=axes,
                   not_judged=not_judged, axes_judged=tuple(evidence.judged), notes=tuple(notes))


def noise_dominated(axes: Mapping[str, AxisFigures], limits: Thresholds) -> bool | str:
    """True when every judged axis's residual is within ``limits.max_residual_over_floor`` of its
    noise floor (what the fit leaves is noise: the base parameters' covariance, of noise,
    describes it and the consistency's chi2 test means what it says); else why not (no floor, or
    the residual above it: a real robot's model error, correlated over seconds)."""
    ratios = {name: f.residual_over_floor for name, f in axes.items()}
    missing = [name for name, r in ratios.items() if r is None]
    if missing or not ratios:
        return "no noise floor to tell the residual from noise (no standstill)"
    above = {name: r for name, r in ratios.items() if r is not None and r > limits.max_residual_over_floor}
    if above:
        return "the residual is the model's own error, not noise: " + ", ".join(
            f"{name} {r:.1f} times its noise floor" for name, r in above.items())
    return True
