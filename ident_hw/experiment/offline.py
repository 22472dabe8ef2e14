"""Identification from recorded samples: the config's steps, then validation (no bus involved).

Each recording (positions and motor currents of the six axes at the SYNC rate, SI) goes through
the same preparation (:func:`ident_hw.filtering.prepare_actuated`, then the parallel filter and
decimation of forces and regressor). The steps of ``identification.steps`` run in order, each
an SQP fit of its parameters with the others held at their current values (CAD at the start),
so the sweep's ``m_c`` is used by the squares' step. A ``wls``/``ols`` step instead fits the
base parameters of its parameters (:func:`fit_base`), reported beside the physical ones with
its own prediction of every trajectory. The result is a :class:`ident_hw.results.Results` with
standard deviations from the weighted least-squares statistics of each step, a
base-parameter analysis of all identification data, what each recording covered
(:func:`coverage`) and the quality verdict (:func:`ident_hw.experiment.quality.verdict`). With
``identification.compare_models``, the least-squares step's recordings also give the power and
energy models' rows (:func:`prepare`), and :func:`comparison` fits the three models' base
parameters side by side (:mod:`ident_hw.identification.model_comparison`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Mapping, Sequence

import numpy as np

from drivers.axis import AVERAGED
from drivers.errors import RecordingError
from drivers.profiles import AveragingFilter, get_profile
from drivers.recording import Recording
from ident_hw.config import Config
from ident_hw.config.identification import IdentificationConfig
from ident_hw.config.robots import initial_parameters, true_parameters
from ident_hw.config.scales import drive_term
from ident_hw.config.schema import FieldError
from ident_hw.config.to_drivers import axes_scaling
from ident_hw.config.trajectory import STANDSTILL_SETTLE
from ident_hw.config.to_identification import filter_settings, physical_scales, step_parameters
from ident_hw.identification.axis_gain import axis_gains, sharing_axes
from ident_hw.identification.base_params import (base_parameters, column_scale, identify_base, on_kept,
                                                  scaled_condition)
from ident_hw.identification.least_squares import check_regression_data, compensated, ols, stack, wls
from ident_hw.identification.drive_gains import GainsRun, fit_gains
from ident_hw.identification.mass_fit import sqp_fit
from ident_hw.identification.physical import ConsistencyError, ConsistentSet, consistent_parameters
from ident_hw.identification.model_comparison import (ModelComparison, ModelRows, compare_models,
                                                       power_energy_rows)
from ident_hw.model.friction import FrictionModel
from ident_hw.model.interface import RobotModel
from ident_hw.records import (AxisShortfall, BaseAnalysis, DriveGainsFigures, ImportSummary, LeastSquaresFigures,
                              MassFitFigures, RecordingCoverage, StepRecord)
from ident_hw.report import coverage_text
from ident_hw.results import BaseFit, ParameterTable, Results, TrajectoryFit
from ident_hw.segments import SATURATION, Segments, slot_indices, split, uniform
from ident_hw.filtering import (FilterSettings, kept_samples, near_rest, parallel_decimate, prepare_actuated,
                               running_average, through_position_lowpass)

from .compared import compared_set, predicted_forces
from .encoder import count_shifts, reread, smoothed_positions, spread_covariance, uncounted_axes
from .friction_choice import friction_robot
from .plan import motion_bandwidth, position_margin
from .quality import AxisEvidence, verdict
from .recordings import identification_valid, planned_cycles, recorded_currents, require_trajectories

#: rows a stretch needs beyond the filters' support at its two ends
MIN_FILTERED = 8


@dataclass
class Prepared:
    """One trajectory after preparation and decimation: t (M,), Theta (M, a), X (M, pose size),
    regressor Y (M, a, n), forces tau (M, a) (``a`` actuators, ``n`` parameters);
    ``moving`` (M, a) marks the rows the fits use (:attr:`tau_fit`); ``segments``: how the
    recording's rows were used (cuts, rows left out per rule); ``power``, ``energy``: the power
    and energy models' rows of the same stretches (only when asked for, see :func:`prepare`);
    ``Thetad`` (M, a): the filtered rates of the rows."""

    name: str
    t: np.ndarray
    Theta: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    tau: np.ndarray
    moving: np.ndarray
    segments: Segments | None = None
    power: ModelRows | None = None
    energy: ModelRows | None = None
    Thetad: np.ndarray | None = None

    @property
    def tau_fit(self) -> np.ndarray:
        """``tau`` with NaN in the rows of axes near rest (left out of the fits, see
        :mod:`ident_hw.identification.least_squares`)."""
        return np.where(self.moving, self.tau, np.nan)


def recording_period(rec: Recording) -> float:
    """The SYNC period of a recording, s: its ``sync_period``, else the median row interval."""
    period = rec.metadata.sync_period
    if period:
        return float(period)
    if len(rec.t) < 2:
        raise RecordingError(f"{rec.metadata.file or 'recording'}: {len(rec.t)} rows and no SYNC period")
    return float(np.median(np.diff(rec.t)))


#: the running average's step ``(A, B0, B1)`` of an axis with an instantaneous current: none
UNFILTERED = (0.0, 0.0, 1.0)


def current_averaging(config: Config, rec: Recording) -> list[AveragingFilter | None] | None:
    """Each actuator's running average when ``rec`` holds its drive's averaged current, None for an
    axis with the instantaneous one; None when no axis has an averaged one. Both come from the
    recording (per axis, :func:`~ident_hw.experiment.recordings.recorded_currents`; its filter the
    recorded one, ``metadata.axes[i].current_filter``), the drive generation's filter where a
    recording made before did not keep it."""
    acts = config.robot.actuators
    kinds = recorded_currents(rec, len(acts))
    if AVERAGED not in kinds:
        return None
    kept = [a.current_filter for a in rec.metadata.axes] if rec.metadata.axes else [None] * len(acts)
    return [None if kind != AVERAGED else own or get_profile(a.profile).current_averaging
            for a, kind, own in zip(acts, kinds, kept)]


def segments_of(config: Config, rec: Recording, trim: int = 0, min_kept: int = 1,
                cut_trim: int | None = None) -> Segments:
    """The rows of ``rec`` the identification may use (:func:`ident_hw.segments.split`: a row
    whose positions and currents all arrived, :func:`identification_valid`)."""
    acts = config.robot.actuators
    return split(rec.t, recording_period(rec), identification_valid(rec), rec.current, rec.target,
                 current_limit=np.array([a.limits.current for a in acts]),
                 acceleration_limit=np.array([a.limits.acceleration for a in acts]),
                 counts_per_unit=axes_scaling(acts).counts_per_unit,
                 trim=trim, min_kept=min_kept, cut_trim=cut_trim)


def coverage(config: Config, name: str, rec: Recording, imported: ImportSummary | None = None) -> RecordingCoverage:
    """What the recording of trajectory ``name`` holds, for the report and the quality verdict.

    The cycles planned are the trajectory's set-points: the recording's ``n_targets``, else the
    config's trajectory of that name; frames not placed in their cycle are counted by
    :class:`drivers.acquisition.CycleAssembler`. ``imported``: how a recording made elsewhere
    was read (its rows are all it holds: nothing was planned).
    """
    meta = rec.metadata
    planned = meta.n_targets or planned_cycles(config, name)
    status = meta.status or "unknown"
    if status == "decoded":
        status = "raw log, truncated" if meta.log_truncated else "raw log"
    complete = rec.valid.all(axis=1)
    gap, fraction, skipped = 0.0, 0.0, 0
    if len(rec.t) > 1:
        period = recording_period(rec)
        slots = slot_indices(rec.t, period)
        skipped = int(slots[-1] + 1 - len(slots))
        fraction = float(complete.sum()) / (slots[-1] + 1)
        edges = np.concatenate([[-1], slots[complete], [slots[-1] + 1]])
        gap = round(float(np.max(np.diff(edges)) - 1) * period, 6)
    elif len(rec.t):
        fraction = float(complete.mean())
    return RecordingCoverage(file=meta.file, recording_status=status, cycles=len(rec.t),
                             cycles_planned=None if planned is None else int(planned),
                             planned_fraction=None if not planned else min(1.0, len(rec.t) / planned),
                             valid_fraction=fraction, longest_gap_s=gap, skipped_slots=skipped,
                             unplaced_frames=int(meta.books.unplaced_frames), imported=imported,
                             shortfalls=shortfalls(config, rec))


def shortfalls(config: Config, rec: Recording) -> dict[str, AxisShortfall]:
    """Per actuator that lacks something in ``rec``: the cycles without its position or current,
    the rows whose current is at its drive's limit (:data:`ident_hw.segments.SATURATION` of
    ``limits.current``, as :func:`ident_hw.segments.split` leaves them out), its largest current
    and that limit. The verdict names these as the cause of what follows (rows left out, no
    stretch to fit)."""
    measured = identification_valid(rec)
    out = {}
    for j, act in enumerate(config.robot.actuators):
        current = np.abs(rec.current[measured[:, j], j])
        missing = int((~measured[:, j]).sum())
        saturated = int(np.sum(current >= SATURATION * act.limits.current))
        if missing or saturated:
            out[act.name] = AxisShortfall(missing=missing, saturated=saturated,
                                          peak_A=float(current.max()) if len(current) else None,
                                          limit_A=float(act.limits.current))
    return out


def _bridged(t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` (N, m) with the NaN rows linearly interpolated (for start guesses only)."""
    out = np.array(values, dtype=float)
    for j in range(out.shape[1]):
        bad = ~np.isfinite(out[:, j])
        if bad.any():
            out[bad, j] = np.interp(t[bad], t[~bad], out[~bad, j])
    return out


def trajectory_filter(config: Config, name: str, sample_rate: float) -> FilterSettings:
    """The identification filter of trajectory ``name``'s recording sampled at ``sample_rate`` (Hz):
    its motion's bandwidth (:func:`motion_bandwidth`) and position margin (:func:`position_margin`).
    Raises :class:`RecordingError` naming the trajectory, its rate and the config's filter where
    they do not fit (a cut-off above the recording's Nyquist frequency: recorded at another rate
    than the config's ``bus.sync_rate``, which the config check holds the cut-off to)."""
    try:
        return filter_settings(config.identification.filter, sample_rate, motion_bandwidth(config, name),
                               position_margin(config, name))
    except ValueError as exc:
        raise RecordingError(f"trajectory {name!r} recorded at {sample_rate:g} Hz: identification.filter: {exc}") from exc


def usable_segments(config: Config, name: str, rec: Recording) -> tuple[FilterSettings, Segments]:
    """Trajectory ``name``'s filter at its recording's rate, and the stretches of the recording
    it filters (:func:`segments_of`, trimmed as the filter needs)."""
    settings = trajectory_filter(config, name, 1.0 / recording_period(rec))
    return settings, segments_of(config, rec, settings.trim, MIN_FILTERED, settings.cut_trim)


def kinematics_starts(robot: RobotModel, rec: Recording, segments: Segments) -> np.ndarray:
    """Start poses (len(segments.t), pose_size) for the kinematics of the usable rows: a
    continuation from the home pose along the whole recording, across its gaps (a Newton start
    only, never data: it picks the assembly mode)."""
    return robot.pose_series(_bridged(segments.t, rec.position), np.zeros(robot.pose_size))


def prepare(config: Config, robot: RobotModel, name: str, rec: Recording, scalar_models: bool = False,
            starts: np.ndarray | None = None) -> Prepared:
    """Recording → filtered motion, regressor and forces, decimated in parallel, stretch by
    stretch (:func:`segments_of`: cut at gaps and at rows left out, each stretch filtered on
    its own and trimmed at both ends: ``trim`` rows at the recording's own ends, ``cut_trim``
    at a cut, :class:`ident_hw.filtering.Ends`); from averaged currents (:func:`current_averaging`), the
    regressor goes through the drives' running average too. ``scalar_models``: also the power
    and energy models' rows of every stretch, from the same filtered motion and forces
    (:func:`ident_hw.identification.model_comparison.power_energy_rows`; not matched to averaged
    currents, whose average does not commute with the product of force and velocity).
    ``starts``: the kinematics' start poses of the usable rows (:func:`kinematics_starts`), when
    the caller has them (the encoder draws start from the recording's own poses)."""
    where = f"{rec.metadata.file or 'recording'} (trajectory {name!r})"
    if len(rec.t) < 3:
        raise RecordingError(f"{where}: {len(rec.t)} samples, too few to identify from")
    empty = [f"node {a.node_id} ({a.name})"
             for a, ok in zip(config.robot.actuators, identification_valid(rec).any(axis=0)) if not ok]
    if empty:
        raise RecordingError(f"{where}: no valid sample of {', '.join(empty)}")
    settings, segments = usable_segments(config, name, rec)
    if not segments.slices:      # nothing to fit; the quality verdict says why
        a, m = len(robot.actuator_names), len(robot.parameter_names)
        return Prepared(name, np.zeros(0), np.zeros((0, a)), np.zeros((0, robot.pose_size)), np.zeros((0, a, m)),
                        np.zeros((0, a)), np.zeros((0, a), bool), segments=segments, Thetad=np.zeros((0, a)))
    force_per_amp = axes_scaling(config.robot.actuators).force_per_amp
    speed_limit = np.array([a.limits.velocity for a in config.robot.actuators])
    guess = kinematics_starts(robot, rec, segments) if starts is None else starts
    averaging = current_averaging(config, rec)
    # the friction columns that are not linear in the motion (a sign, a presliding state) pass the
    # positions' low-pass as the forces do
    coulomb = [i for i, p in enumerate(robot.parameter_names) if drive_term(p) in ("fc", "fs")]
    friction = friction_of(robot)
    parts, scalar = [], []
    for stretch in segments.stretches:
        rows, ends = stretch.rows, stretch.ends
        t, Theta, current = uniform(segments.t[rows], rec.position[rows], rec.current[rows])
        samples = prepare_actuated(t, Theta, current, force_per_amp, settings, ends)
        regressor, X = robot.identification_regressor(samples.Theta, samples.Thetad, samples.Thetadd, guess[rows])
        if averaging is not None:   # forces from averaged currents: the regressor through the same average
            period = (t[-1] - t[0]) / (len(t) - 1)
            regressor = running_average(regressor, [UNFILTERED if f is None else f.over_period(period)
                                                    for f in averaging])
        regressor, tau = through_position_lowpass(settings, samples.tau, regressor, coulomb, ends)
        Y, tau = parallel_decimate(settings, regressor, tau, ends=ends)
        kept = kept_samples(settings, len(t), ends)
        slow = np.abs(samples.Thetad) < config.identification.min_speed * speed_limit
        if friction is not None:    # an axis whose friction state its motion has not yet set
            slow |= ~friction.state_known(samples.Theta, samples.Thetad)
        parts.append((t[kept], samples.Theta[kept], X[kept], Y, tau, ~near_rest(slow, settings)[kept],
                      samples.Thetad[kept]))
        if scalar_models and len(t) > 2 * settings.trim:    # they trim ``trim`` at both ends
            scalar.append(power_energy_rows(robot, t, samples.Theta, samples.Thetad, samples.tau, guess[rows],
                                            settings))
    t, Theta, X, Y, tau, moving, Thetad = (np.concatenate(column) for column in zip(*parts))
    if scalar:
        power, energy = (ModelRows.concatenate(column) for column in zip(*scalar))
        return Prepared(name, t, Theta, X, Y, tau, moving, segments=segments, power=power, energy=energy,
                        Thetad=Thetad)
    return Prepared(name, t, Theta, X, Y, tau, moving, segments=segments, Thetad=Thetad)


def fit_base(step, free_names: tuple[str, ...], names: tuple[str, ...], Y: np.ndarray, tau: np.ndarray,
             coef: np.ndarray, initial: np.ndarray, truth: np.ndarray | None, threshold: float,
             basis: tuple | None = None, draws: Sequence[tuple[np.ndarray, np.ndarray]] = ()
             ) -> tuple[BaseFit, np.ndarray, StepRecord]:
    """Least squares (``step.method`` ``wls``/``ols``) of the base parameters of ``free_names``
    on ``Y`` (N, a, n), ``tau`` (N, a), the other parameters (``names``, n) held at ``coef``;
    ``basis``: the model's readable base parameters (``RobotModel.readable_base``), used when
    every parameter is free and the data identifies them all. ``draws``: the same data with the
    encoders read again (:mod:`ident_hw.experiment.encoder`), each fitted on the same columns
    with the same weights; the covariance of their estimates joins the least-squares one, and
    the spread of their regressors corrects the estimate for the encoders' noise in the
    regressor (:func:`ident_hw.identification.least_squares.compensated`; the record's
    ``encoder_shift``).

    Returns the :class:`BaseFit`, the physical vector (n,) that predicts the same forces (each
    kept parameter carries its base value, the eliminated ones 0, the held ones ``coef``) and the
    step's record for the results.
    """
    free = [names.index(p) for p in free_names]
    held = [i for i in range(len(names)) if i not in free]
    Yf = Y[:, :, free]
    tau_free = tau - Y[:, :, held] @ coef[held]       # the forces the free parameters must explain
    base, fit = identify_base(Yf, tau_free, free_names, scale=column_scale(Yf),
                              weighted=step.method == "wls", basis=None if held else basis)
    H = np.zeros((base.rank, len(names)))
    H[:, free] = np.where(np.abs(base.H) > 1e-10, base.H, 0.0)   # rounding of N1 N2^-1, not a coefficient
    kept = [free[list(free_names).index(k)] for k in base.kept]
    plain = fit.coef
    fit = compensated(fit, Y[:, :, kept], tau_free, [Yk[:, :, kept] for Yk, _ in draws])
    equivalent = coef.copy()
    equivalent[free] = on_kept(free_names, base.kept, fit.coef)
    encoder = spread_covariance([_refit(fit, Yk[:, :, kept], tauk - Yk[:, :, held] @ coef[held])
                                 for Yk, tauk in draws], len(kept))
    covariance = fit.covariance + encoder
    result = BaseFit(step=step.name, method=fit.method, trajectories=tuple(step.trajectories),
                     expressions=base.expressions, H=H, coef=fit.coef, sigma=np.sqrt(np.diag(covariance)),
                     initial=H @ initial, truth=None if truth is None else H @ truth,
                     held=tuple(names[i] for i in held), unexcited=base.unexcited, threshold=threshold,
                     covariance=covariance)
    record = StepRecord(name=step.name, trajectories=tuple(step.trajectories), method=fit.method,
                        free=tuple(free_names), eliminated=tuple(base.eliminated),
                        figures=LeastSquaresFigures.of(fit),   # the estimates are the BaseFit's
                        cond_scaled=scaled_condition(Y[:, :, kept], tau), **_encoder_fields(draws, encoder),
                        encoder_shift=tuple((fit.coef - plain).tolist()) if len(draws) > 1 else ())
    return result, equivalent, record


def _refit(fit, Y: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """The estimate of ``fit``'s method on ``Y`` (N, a, m), ``tau`` (N, a): WLS with ``fit``'s
    output weights, else OLS."""
    if fit.output_std is not None:
        return wls(Y, tau, fit.names, output_std=fit.output_std).coef
    return ols(Y, tau, fit.names).coef


def _encoder_fields(draws: Sequence, covariance: np.ndarray) -> dict:
    """The :class:`StepRecord` fields of the encoder draws: how many, each estimate's sigma from them."""
    if not len(draws):
        return {}
    return {"encoder_draws": len(draws), "encoder_sigma": tuple(np.sqrt(np.diag(covariance)).tolist())}


def comparison(step, free_names: tuple[str, ...], names: tuple[str, ...], Y: np.ndarray, tau: np.ndarray,
               prepared: Mapping[str, Prepared], coef: np.ndarray, truth: np.ndarray | None, weighted: bool,
               threshold: float, basis: tuple | None = None) -> ModelComparison:
    """The dynamic, power and energy models' base parameters of the least-squares ``step``
    (:func:`ident_hw.identification.model_comparison.compare_models`): the dynamic model on the
    step's own rows ``Y`` (N, a, n), ``tau`` (N, a), the power and energy models on the rows
    :func:`prepare` made of the same stretches; parameters outside ``free_names`` held at
    ``coef`` (n,), as in :func:`fit_base`."""
    rows = [ModelRows("dynamic", Y, tau)]
    for model in ("power", "energy"):
        parts = [getattr(prepared[t], model) for t in step.trajectories if getattr(prepared[t], model) is not None]
        if parts:
            rows.append(ModelRows.concatenate(parts))
    return compare_models(names, rows, free=free_names, values=coef, truth=truth, weighted=weighted,
                          basis=basis, step=step.name, trajectories=step.trajectories, threshold=threshold)


@dataclass
class _Estimates:
    """The physical parameters as the steps leave them (arrays (n,)): values, sigma (NaN: none),
    bounds, and which step and method fitted each ("" : held at its initial value)."""

    coef: np.ndarray
    sigma: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    step_of: list[str]
    method_of: list[str]

    @classmethod
    def initial(cls, values: np.ndarray) -> _Estimates:
        n = len(values)
        return cls(values.copy(), np.full(n, np.nan), np.full(n, -np.inf), np.full(n, np.inf), [""] * n, [""] * n)


def noise_floors(config: Config, recordings: Mapping[str, Recording], fitted: Sequence[str],
                 draws: Sequence[Mapping[str, Prepared]] = (), coef: np.ndarray | None = None,
                 moving: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Per fitted trajectory (``fitted``), the residual (a,) that noise alone leaves each axis, in
    the drive's current (A): the current's noise at rest and, with ``draws``, the encoders'.

    The current's: the RMS about its mean of the current of the config's ``standstill``
    recordings after their first :data:`~ident_hw.config.trajectory.STANDSTILL_SETTLE` s, through that trajectory's parallel filter
    (:func:`ident_hw.filtering.parallel_decimate` with its band, not decimated: the same
    variance, more samples), as its fitted forces are; the longest stretch of complete rows of
    each standstill counts, one shorter than the filter's two trims gives nothing. The
    encoders': the positions' rounding, differentiated twice, moves the regressor and so the
    predicted forces (its friction included: a Coulomb term switching with a count near zero
    speed): the RMS over the rows of their spread over the draws (the recordings read again,
    :func:`reread_draws`) at the parameters ``coef``; with ``moving`` (per trajectory (rows, a)
    bool, :attr:`Prepared.moving`), over each axis's rows the fits use (NaN for an axis
    without one), as the verdict takes the residual. The two add in squares. ``{}``
    without a standstill recording, or without draws (on a fine trajectory the encoders' part
    can be most of the floor): the verdict then has no floor (:func:`floor_missing` says why)."""
    if len(draws) < 2 or coef is None:
        return {}
    stills = []                 # (sample rate, the current about its mean over the longest complete stretch)
    for t in config.trajectories:
        if t.kind == "standstill" and t.name in recordings:
            rec = recordings[t.name]
            settled = rec.t >= rec.t[0] + STANDSTILL_SETTLE if len(rec.t) else np.zeros(0, bool)
            rows = _longest_run(identification_valid(rec).all(axis=1) & settled)
            if rows.stop > rows.start:
                stills.append((1.0 / recording_period(rec), rec.current[rows] - rec.current[rows].mean(axis=0)))
    floors = {}
    per_amp = axes_scaling(config.robot.actuators).force_per_amp
    for name in fitted:
        squares, count = np.zeros(len(per_amp)), 0
        for rate, current in stills:
            settings = trajectory_filter(config, name, rate)
            band = replace(settings, cutoff_hz=settings.decimation_cutoff_hz, decimation=1)
            if len(current) <= 2 * band.trim + 1:
                continue
            (filtered,) = parallel_decimate(band, current)
            squares, count = squares + np.sum(filtered ** 2, axis=0), count + len(filtered)
        if count:
            rows = None if moving is None else moving.get(name)
            floors[name] = np.sqrt(squares / count + _encoder_spread(draws, name, coef, rows) ** 2 / per_amp ** 2)
    return floors


def floor_missing(config: Config, recordings: Mapping[str, Recording], fitted: Sequence[str],
                  floors: Mapping[str, np.ndarray], draws: Sequence) -> str | None:
    """Why :func:`noise_floors` gave no floor for some of the ``fitted`` trajectories (None: it
    gave every one): no standstill recorded, one too short for a trajectory's filter, or no
    encoder draws."""
    if all(name in floors for name in fitted):
        return None
    if not any(t.kind == "standstill" and t.name in recordings for t in config.trajectories):
        return "no standstill"
    if len(draws) < 2:
        return "no encoder draws"
    short = [name for name in fitted if name not in floors]
    return f"the standstill is too short for the filter of {', '.join(short)}"


def axis_evidence(config: Config, robot: RobotModel, recordings: Mapping[str, Recording],
                  prepared: Mapping[str, Prepared], fitted_trajectories: Sequence[str], fitted: set[str],
                  draws: Sequence[Mapping[str, Prepared]], coef: np.ndarray) -> AxisEvidence:
    """What the verdict's per-axis checks judge, from the fitted trajectories' regressor and
    forces at the fit's parameters ``coef`` (n,): the axes the ``fitted`` parameters act on
    (:func:`acting_axes`), each axis's gain against its own model refitted
    (:func:`ident_hw.identification.axis_gain.axis_gains`, over the rows the fits use), its noise
    floors on those rows (:func:`noise_floors`) or why there are none, and the axes sharing
    parameters (:func:`ident_hw.identification.axis_gain.sharing_axes`)."""
    names = robot.parameter_names
    judged = acting_axes(robot, prepared, fitted_trajectories, fitted)
    free = [names.index(p) for p in names if p in fitted]
    gains, sharing = None, {}
    if free and fitted_trajectories:
        Y = np.concatenate([prepared[t].Y for t in fitted_trajectories])
        tau = np.concatenate([prepared[t].tau_fit for t in fitted_trajectories])
        gains = axis_gains(Y, tau, coef, free, robot.actuator_names, config.identification.quality.max_axis_gain,
                           judged)
        sharing = sharing_axes(Y, free, robot.actuator_names)
    floors = noise_floors(config, recordings, fitted_trajectories, draws, coef,
                          {t: prepared[t].moving for t in fitted_trajectories})
    return AxisEvidence(judged=judged, gains=gains, floors=floors, sharing=sharing,
                        floor_missing=floor_missing(config, recordings, fitted_trajectories, floors, draws))


def _encoder_spread(draws: Sequence[Mapping[str, Prepared]], name: str, coef: np.ndarray,
                    rows: np.ndarray | None = None) -> np.ndarray:
    """(a,) RMS over the rows of trajectory ``name`` (``rows``: (N, a) bool, each axis's own;
    None: all) of the spread over ``draws`` (at least two) of the forces predicted at ``coef``
    (force units); NaN for an axis without a row."""
    predicted = np.array([d[name].Y @ coef for d in draws])          # (draws, rows, a)
    variance = np.var(predicted, axis=0, ddof=1)
    if rows is None or rows.shape != variance.shape:
        return np.sqrt(np.mean(variance, axis=0))
    counts = rows.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(np.where(counts > 0, np.sum(np.where(rows, variance, 0.0), axis=0) / counts, np.nan))


def _longest_run(mask: np.ndarray) -> slice:
    """The longest stretch of consecutive True in ``mask`` (N,), as a slice (empty: none)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    if not len(edges):
        return slice(0, 0)
    starts, stops = edges[::2], edges[1::2]
    k = int(np.argmax(stops - starts))
    return slice(int(starts[k]), int(stops[k]))


def encoder_draws(config: Config, robot: RobotModel, recordings: Mapping[str, Recording], names: Sequence[str],
                  progress: Callable[[str], None] | None = None
                  ) -> tuple[list[dict[str, Prepared]], dict[str, tuple[str, ...]]]:
    """The config's ``identification.encoder_draws`` of the recordings ``names``
    (:func:`reread_draws`), none if an axis of one of them is not in whole encoder counts
    (:func:`ident_hw.experiment.encoder.uncounted_axes`); and per recording those axes' names."""
    wanted = config.identification.encoder_draws
    counts_per_unit = axes_scaling(config.robot.actuators).counts_per_unit
    uncounted = {name: tuple(robot.actuator_names[j] for j in uncounted_axes(recordings[name], counts_per_unit))
                 for name in names}
    taken = wanted if not any(uncounted.values()) else 0
    if progress and wanted:
        progress(f"the encoders read again, count edges moved: {taken} draws" if taken else
                 "no encoder draws: the positions of " + "; ".join(
                     f"{name} ({', '.join(axes)})" for name, axes in uncounted.items() if axes)
                 + " are not whole encoder counts")
    return reread_draws(config, robot, recordings, names, taken), uncounted


def reread_draws(config: Config, robot: RobotModel, recordings: Mapping[str, Recording], names: Sequence[str],
                 draws: int) -> list[dict[str, Prepared]]:
    """``draws`` versions of the recordings ``names`` read again by encoders whose count edges are
    moved (:mod:`ident_hw.experiment.encoder`), each prepared as the recording was: one dict
    (trajectory name -> :class:`Prepared`) per draw."""
    counts_per_unit = axes_scaling(config.robot.actuators).counts_per_unit
    smooth, starts = {}, {}
    for name in names if draws else ():  # once per recording: the motion the draws read again, and
        rec = recordings[name]           # the poses their kinematics start from (a count away at most)
        settings, segments = usable_segments(config, name, rec)
        smooth[name] = smoothed_positions(rec, settings.sample_rate, settings.cutoff_hz, settings.order)
        starts[name] = kinematics_starts(robot, rec, segments)
    return [{name: prepare(config, robot, name, reread(recordings[name], smooth[name], counts_per_unit, shift),
                           starts=starts[name])
             for name in names}
            for shift in count_shifts(draws, len(counts_per_unit))]


def prepare_all(config: Config, robot: RobotModel, recordings: Mapping[str, Recording], needed: Sequence[str],
                compared: Sequence[str], progress: Callable[[str], None] | None,
                imported: Mapping[str, ImportSummary] | None = None
                ) -> tuple[dict[str, RecordingCoverage], dict[str, Prepared]]:
    """Each needed trajectory's coverage (what its recording holds; ``imported``: how those made
    elsewhere were read) and its :func:`prepare`."""
    imported = imported or {}
    used = {name: coverage(config, name, recordings[name], imported.get(name)) for name in needed}
    if progress:
        for name, u in used.items():
            progress(f"  {name}: {coverage_text(u)}")
    prepared: dict[str, Prepared] = {}
    for name in needed:
        if progress:
            progress(f"preparing {name}")
        prepared[name] = prepare(config, robot, name, recordings[name], scalar_models=name in compared)
        if progress and prepared[name].segments.describe():
            progress(f"  {name}: {prepared[name].segments.describe()}")
    return used, prepared


def excited_parameters(free_names: Sequence[str], names: tuple[str, ...], Y: np.ndarray, tau: np.ndarray) -> list[str]:
    """The parameters of ``free_names`` whose regressor column is not zero throughout the rows
    the fit uses (``Y`` (N, a, n), ``tau`` (N, a), NaN where an axis is left out)."""
    rows, _ = stack(*check_regression_data(Y, tau))
    return [p for p in free_names if np.any(rows[:, names.index(p)] != 0)]


def fit_sqp_step(step, free_names: Sequence[str], names: tuple[str, ...], Y: np.ndarray, tau: np.ndarray,
                 estimates: _Estimates, all_bounds: Mapping[str, tuple[float, float]],
                 prepared: Mapping[str, Prepared], draws: Sequence[tuple[np.ndarray, np.ndarray]] = (),
                 held_std: np.ndarray | None = None) -> tuple[StepRecord, list[str]]:
    """The paper's bounded SQP mass fit of one step's parameters on its data (``Y`` (N, a, n),
    ``tau`` (N, a)), the others held at their current values; ``estimates`` updated in place.
    ``draws``: the step's data with the encoders read again (:func:`fit_base`); the spread of
    their estimates joins each sigma. ``held_std`` (n,): what each value the step holds is worth
    (:func:`held_value_std`); what they are worth in each estimate (:func:`held_value_sigma`)
    joins its sigma too. A parameter its rows do not excite at all (a carriage whose every
    stretch was left out) is held, and the record says so. Returns the step's record and the
    parameters it fitted."""
    excited = excited_parameters(free_names, names, Y, tau)
    unexcited = [p for p in free_names if p not in excited]
    if not excited:
        return StepRecord(step.name, tuple(step.trajectories),
                          skipped=f"none of {', '.join(step.parameters)} excited by its data"), []
    bounds = {p: all_bounds[p] for p in excited if p in all_bounds}
    fit = sqp_fit(Y, tau, names, estimates.coef, free=excited, bounds=bounds)
    estimates.coef = coef = fit.coef
    idx = [names.index(p) for p in excited]
    held = [i for i in range(len(names)) if i not in idx]
    statistics: dict = {}
    # sigma of the free parameters: WLS statistics of the same weighted problem
    try:
        stats = wls(Y[:, :, idx], tau - Y[:, :, held] @ coef[held], excited, output_std=fit.output_std)
    except ValueError as exc:  # rank deficient: the fit is bounded, but has no covariance
        statistics["statistics_missing"] = str(exc)
    else:
        encoder = spread_covariance([_refit(stats, Yk[:, :, idx], tauk - Yk[:, :, held] @ coef[held])
                                     for Yk, tauk in draws], len(idx))
        from_held = (held_value_sigma(stats, Y, tau, idx, held, held_std[held]) if held_std is not None
                     else np.zeros(len(idx)))
        estimates.sigma[idx] = np.sqrt(stats.std ** 2 + np.diag(encoder) + from_held ** 2)
        statistics.update(_encoder_fields(draws, encoder), cond_W=stats.cond)
        if held_std is not None:
            statistics["held_sigma"] = tuple(from_held.tolist())
    record = StepRecord(name=step.name, trajectories=tuple(step.trajectories), method=fit.method,
                        free=tuple(fit.free), figures=MassFitFigures.of(fit),
                        rows_left_out={t: prepared[t].segments.left_out for t in step.trajectories},
                        cond_scaled=scaled_condition(Y[:, :, idx], tau), unexcited=tuple(unexcited), **statistics)
    for i, p in zip(idx, excited):
        estimates.lower[i], estimates.upper[i] = bounds.get(p, (0.0, np.inf))
        estimates.step_of[i], estimates.method_of[i] = step.name, step.method
    return record, excited


def acting_axes(robot: RobotModel, prepared: Mapping[str, Prepared], trajectories: Sequence[str],
                fitted: set[str]) -> tuple[str, ...]:
    """The axes whose forces some of the ``fitted`` parameters act on in ``trajectories`` (a non-zero
    regressor column): a carriage sweep's links, moved by their held CAD values only, are not."""
    acting = [robot.parameter_names.index(p) for p in fitted]
    return tuple(name for j, name in enumerate(robot.actuator_names)
                 if acting and any(np.any(prepared[t].Y[:, j, acting] != 0) for t in trajectories))


def identify(config: Config, recordings: Mapping[str, Recording],
             progress: Callable[[str], None] | None = None,
             imported: Mapping[str, ImportSummary] | None = None) -> Results:
    """Run the config's identification steps and validation on ``recordings`` (name → samples);
    ``imported``: how the recordings made elsewhere were read (:mod:`ident_hw.experiment.external`)."""
    ident = config.identification
    if ident is None:
        raise ValueError(f"{config.source}: identification: missing section")
    needed = list(dict.fromkeys([n for s in ident.steps for n in s.trajectories] + list(ident.validation)))
    require_trajectories(config, recordings)
    robot, friction = friction_robot(config, recordings, _base_step_trajectories(ident), prepare, progress)
    names = robot.parameter_names
    compared: tuple[str, ...] = ()
    if ident.compare_models:            # the config check made sure there is such a step
        compared = next(s for s in ident.steps if s.method in ("wls", "ols")).trajectories
    used, prepared = prepare_all(config, robot, recordings, needed, compared, progress, imported)
    id_names = list(dict.fromkeys(t for s in ident.steps for t in s.trajectories))
    draws, uncounted = encoder_draws(config, robot, recordings, id_names, progress)

    initial = initial_parameters(config.robot)
    estimates = _Estimates.initial(initial)
    truth = true_parameters(config, robot)
    steps, base_fit, base_equivalent, model_comparison, fitted = _run_steps(
        ident, robot, prepared, compared, estimates, initial, truth, progress, draws,
        axes_scaling(config.robot.actuators).force_per_amp)

    coef = estimates.coef
    W, _ = stack(*check_regression_data(np.concatenate([prepared[t].Y for t in id_names]),
                                        np.concatenate([prepared[t].tau_fit for t in id_names])))
    analysis = BaseAnalysis.of(base_parameters(W, names, scale=np.maximum(np.abs(initial), 1e-3)))

    compared = compared_forces(config, recordings, prepared, progress, robot)
    rest = rest_speeds(config, robot)
    fits = []
    # a trajectory only a gains step uses (a payload run) is no fit of the model: the gains' figures say it all
    payload_only = set(id_names) - {t for s in ident.steps if s.method != "gains" for t in s.trajectories}
    for name, p in prepared.items():
        if name in payload_only and name not in ident.validation:
            continue
        role = "validation" if name in ident.validation and name not in id_names else "identification"
        fits.append(TrajectoryFit(name, role, p.t, p.tau, p.Y @ coef, p.Theta, p.X,
                                  tau_base=None if base_fit is None else p.Y @ base_equivalent, moving=p.moving,
                                  tau_compared=compared.get(name), at_rest=np.abs(p.Thetad) < rest))
    table = ParameterTable(names=names, units=tuple(robot.parameter_unit(p) for p in names), initial=initial,
                           identified=coef, sigma=estimates.sigma, lower=estimates.lower, upper=estimates.upper,
                           step=tuple(estimates.step_of), method=tuple(estimates.method_of), truth=truth)
    for name, p in prepared.items():
        used[name] = used[name].with_use(samples_used=len(p.t), rows_left_out=p.segments.left_out,
                                         gaps=p.segments.gaps, stretches=len(p.segments.slices),
                                         uncounted_axes=uncounted.get(name, ()))
    results = Results(parameters=table, actuators=robot.actuator_names, actuator_kinds=robot.actuator_kinds,
                      fits=fits, steps=steps, base_analysis=analysis, base_fit=base_fit,
                      rel_sigma_threshold=ident.rel_sigma_threshold, trajectories=used,
                      model_comparison=model_comparison,
                      compared_label=None if ident.compare_with is None else ident.compare_with.label,
                      friction=friction)
    if base_fit is not None and ident.physical.enabled:
        if progress:
            progress(f"step {base_fit.step}: the physically consistent parameters nearest the CAD values")
        results.consistent, failure = consistent(config, robot, base_fit, base_equivalent, initial, truth)
        if failure is not None:         # the base step's record says why there is none
            results.steps = [replace(s, consistency_failure=failure) if s.name == base_fit.step else s
                             for s in results.steps]
        else:                           # its forces beside the base fit's, on every trajectory
            results.fits = [replace(f, tau_consistent=prepared[f.name].Y @ results.consistent.values)
                            for f in results.fits]
    results.quality = verdict(results, ident.quality, config.robot.actuators,
                              axis_evidence(config, robot, recordings, prepared, id_names, fitted, draws,
                                            coef if base_fit is None else base_equivalent))
    return results


def friction_of(robot: RobotModel) -> FrictionModel | None:
    """The robot's friction model where it has one (a described robot's,
    :class:`ident_hw.model.friction.FrictionModel`); None: the hand models' Coulomb and viscous terms."""
    friction = getattr(robot, "friction", None)
    return friction if isinstance(friction, FrictionModel) else None


def _base_step_trajectories(ident: IdentificationConfig) -> tuple[str, ...]:
    """The trajectories of the least-squares step, else of every step: what a friction constant
    is chosen on (:mod:`ident_hw.experiment.friction_choice`)."""
    least_squares = [s for s in ident.steps if s.method in ("wls", "ols")]
    steps = least_squares or ident.steps
    return tuple(dict.fromkeys(t for s in steps for t in s.trajectories))


def rest_speeds(config: Config, robot: RobotModel) -> np.ndarray:
    """(a,) rad/s | m/s: an actuator slower than this is at rest (the validation's moving / at-rest
    split): its friction model's rest speed (a described robot's), else the identification's
    ``min_speed`` fraction of its velocity limit."""
    friction = friction_of(robot)
    if friction is not None:
        return np.full(len(robot.actuator_names), friction.rest_speed)
    return config.identification.min_speed * np.array([a.limits.velocity for a in config.robot.actuators])


def compared_forces(config: Config, recordings: Mapping[str, Recording], prepared: Mapping[str, Prepared],
                    progress: Callable[[str], None] | None = None, robot: RobotModel | None = None
                    ) -> dict[str, np.ndarray]:
    """Per prepared trajectory, the forces (N, a) the parameter set of ``identification.compare_with``
    predicts on its rows, with its own friction model, in the config's measure
    (:mod:`ident_hw.experiment.compared`; ``robot``: the identified robot, whose tree its model
    shares); ``{}`` without one."""
    spec = config.identification.compare_with
    if spec is None:
        return {}
    if progress:
        progress(f"predicting with the parameters of {spec.label} ({spec.path})")
    other = compared_set(config, spec, robot)
    out = {}
    for name, own in prepared.items():
        theirs = prepare(config, other.model, name, recordings[name])
        if len(theirs.t) != len(own.t):
            raise RecordingError(f"{name}: the compared model's rows ({len(theirs.t)}) are not the identified "
                                 f"model's ({len(own.t)})")
        out[name] = predicted_forces(other, theirs.Y, config)
    return out


def held_value_sensitivity(fit, Y: np.ndarray, tau: np.ndarray, free: Sequence[int], held: Sequence[int]
                           ) -> np.ndarray:
    """(len(free), len(held)) how a mass-fit step's estimates move per unit of each value it
    holds: ``d z_i / d h_j``, for the step's weighted least squares (``fit``'s output weights)
    on ``Y`` (N, a, n) and the rows ``tau`` (N, a) leaves in (NaN: an axis left out).

    With ``A`` the free columns, ``B`` the held ones and ``Wt`` the weights, the estimate is
    ``z = (A' Wt A)^-1 A' Wt (tau - B h)``: column j is minus the fit of ``A`` to ``B_j`` (0 for a
    column that acts on no row). Exact for a fit whose bounds are not active: the model is
    linear in its parameters and the mass fit's weights do not depend on the held values."""
    out = np.zeros((len(free), len(held)))
    A, left_out = Y[:, :, list(free)], np.isnan(tau)
    for k, j in enumerate(held):
        column = np.where(left_out, np.nan, Y[:, :, j])
        if np.any(np.nan_to_num(column) != 0):
            out[:, k] = -_refit(fit, A, column)
    return out


def held_value_sigma(fit, Y: np.ndarray, tau: np.ndarray, free: Sequence[int], held: Sequence[int],
                     held_std: np.ndarray) -> np.ndarray:
    """(len(free),) what the values a mass-fit step holds are worth in each of its estimates, in
    their units: their uncertainties ``held_std`` (len(held),) through
    :func:`held_value_sensitivity`, taken as independent: ``sigma_i^2 = sum_j (S_ij std_j)^2``."""
    return np.sqrt(((held_value_sensitivity(fit, Y, tau, free, held) * np.asarray(held_std)) ** 2).sum(axis=1))


def held_value_std(estimates: _Estimates, prior_std: np.ndarray) -> np.ndarray:
    """(n,) what each parameter is worth as a value a mass-fit step holds: the sigma of the step
    that fitted it, else (its initial, CAD value, still) ``prior_std`` (n,), the CAD prior of
    the config (``identification.physical.prior`` scales)."""
    fitted = np.array([bool(s) for s in estimates.step_of]) & np.isfinite(estimates.sigma)
    return np.where(fitted, estimates.sigma, prior_std)


def _run_steps(ident: IdentificationConfig, robot: RobotModel, prepared: Mapping[str, Prepared],
               compared: tuple[str, ...], estimates: _Estimates, initial: np.ndarray, truth: np.ndarray | None,
               progress: Callable[[str], None] | None, draws: Sequence[Mapping[str, Prepared]] = (),
               force_per_amp: np.ndarray | None = None):
    """Runs the identification steps in their order, each on the parameters the ones before left
    in ``estimates`` (updated in place), and the model comparison on the base step's data when
    ``compared`` names its trajectories; ``draws``: the recordings with the encoders read again
    (:func:`reread_draws`), whose spread joins each step's sigma. A mass-fit step's sigma has
    also what the values it holds are worth: an earlier step's sigma, else the CAD prior
    (``identification.physical.prior`` scales of each parameter, :func:`held_value_std`).

    Returns the steps' records, the last base step's :class:`BaseFit` and its equivalent physical
    parameters (n,) (None, None without a base step), the model comparison (or None) and the set
    of the parameters some step fitted.
    """
    names = robot.parameter_names
    steps: list[StepRecord] = []
    base_fit, base_equivalent, model_comparison = None, None, None
    fitted: set[str] = set()            # every parameter some step fitted
    prior_std = None
    if any(s.method == "sqp" for s in ident.steps):
        prior_std = ident.physical.prior * np.array(physical_scales(ident.physical, names, initial))
    for step in ident.steps:
        free_names = step_parameters(step, names)
        if progress:
            progress(f"step {step.name}: fitting "
                     + ("all parameters" if step.parameters == ("all",) else ", ".join(free_names))
                     + (f" (base parameters, {step.method.upper()})" if step.method != "sqp" else ""))
        Y = np.concatenate([prepared[t].Y for t in step.trajectories])
        tau = np.concatenate([prepared[t].tau_fit for t in step.trajectories])
        if not len(Y):
            steps.append(StepRecord(step.name, tuple(step.trajectories),
                                    skipped="no stretch of its recordings could be filtered"))
            continue
        step_draws = [(np.concatenate([d[t].Y for t in step.trajectories]),
                       np.concatenate([d[t].tau_fit for t in step.trajectories])) for d in draws]
        if step.method == "gains":
            steps.append(fit_gains_step(step, robot, prepared, force_per_amp, progress))
            continue
        if step.method == "sqp":
            record, excited = fit_sqp_step(step, free_names, names, Y, tau, estimates, ident.bounds, prepared,
                                           step_draws, held_value_std(estimates, prior_std))
            steps.append(record)
            fitted.update(excited)
            continue
        base_fit, base_equivalent, record = fit_base(step, free_names, names, Y, tau, estimates.coef, initial, truth,
                                                     ident.rel_sigma_threshold, robot.readable_base(), step_draws)
        steps.append(record)
        fitted.update(free_names)
        if compared:
            if progress:
                progress(f"step {step.name}: the dynamic, power and energy models' base parameters")
            model_comparison = comparison(step, free_names, names, Y, tau, prepared, estimates.coef, truth,
                                          step.method == "wls", ident.rel_sigma_threshold, robot.readable_base())
    return steps, base_fit, base_equivalent, model_comparison, fitted


def fit_gains_step(step, robot: RobotModel, prepared: Mapping[str, Prepared], configured: np.ndarray,
                   progress: Callable[[str], None] | None = None) -> StepRecord:
    """A ``gains`` step: the drive gains of every actuator with the base parameters of all the
    model's, from the step's runs with and without its payload (:mod:`ident_hw.identification.drive_gains`),
    started from (and reported beside) the config's force per ampere ``configured`` (a,). The
    estimates of the other steps are not changed: a gain the user trusts goes into the config."""
    per_amp = np.asarray(configured, dtype=float)
    payload = list(robot.payload_indices())
    runs = [GainsRun(prepared[t].Y, prepared[t].tau_fit / per_amp,
                     prepared[t].Y[:, :, payload] if t in step.payload.trajectories else None)
            for t in step.trajectories]
    fit = fit_gains(runs, step.payload.mass, per_amp)
    mass = np.concatenate([run.payload[:, :, 0] for run in runs if run.payload is not None])
    reach = np.sqrt(np.mean(mass ** 2, axis=0))           # N·m (N) per kg of payload, RMS
    figures = DriveGainsFigures(gains=tuple(fit.gains.tolist()), sigma=tuple(fit.sigma.tolist()),
                                configured=tuple(per_amp.tolist()), residual_rms=tuple(fit.residual_rms.tolist()),
                                residual_rms_configured=tuple(fit.residual_rms_start.tolist()),
                                payload_mass=step.payload.mass, payload_trajectories=tuple(step.payload.trajectories),
                                rank=fit.rank, blocks=fit.blocks,
                                mass_axes=tuple(a for a, r in zip(robot.actuator_names, reach) if r > 1e-6 * reach.max()))
    if progress:
        progress("  drive gains " + ", ".join(f"{a} {g:.4g} (sigma {s:.2g}; config {c:.4g})" for a, g, s, c in
                                              zip(robot.actuator_names, fit.gains, fit.sigma, per_amp)))
    return StepRecord(step.name, tuple(step.trajectories), method="gains",
                      free=tuple(f"g_{a}" for a in robot.actuator_names), drive_gains=figures)


def consistent(config: Config, robot: RobotModel, base_fit: BaseFit, equivalent: np.ndarray, initial: np.ndarray,
               truth: np.ndarray | None) -> tuple[ConsistentSet | None, str | None]:
    """The physical parameters nearest the CAD values ``initial`` (n,) that reproduce
    ``base_fit`` (:func:`ident_hw.identification.physical.consistent_parameters`), and None; the
    parameters the base step held keep their values in ``equivalent`` (n,). None and the reason
    when there is no such set."""
    physical = config.identification.physical
    names = robot.parameter_names
    held = {names.index(p): float(equivalent[names.index(p)]) for p in base_fit.held}
    # a drive term without a CAD value (friction) is scaled by its least-squares value, or where the
    # data left it at 0 (a rotor inertia merged into its link's) by the largest of its kind
    bodies = robot.physical_bodies()
    in_body = {i for body in bodies for i in body.indices}
    typical = np.array([abs(equivalent[i]) if i not in in_body and not initial[i] else initial[i]
                        for i in range(len(names))])
    for i, p in enumerate(names):
        if i not in in_body and not typical[i]:
            kin = [abs(equivalent[j]) for j, q in enumerate(names) if j not in in_body and drive_term(q) == drive_term(p)]
            typical[i] = max(kin, default=0.0)
    try:
        scale = np.array(physical_scales(physical, names, typical))
        # an offset and a Stribeck term have either sign (the Stribeck term: the friction dips or rises near rest)
        signed = [i for i, p in enumerate(names) if drive_term(p) in ("f0", "fs")]
        return consistent_parameters(names, tuple(robot.parameter_unit(p) for p in names), base_fit.H, base_fit.coef,
                                     base_fit.covariance, initial, scale, bodies, held=held,
                                     metric=physical.metric, prior_relative=physical.prior, truth=truth,
                                     signed=signed), None
    except (ConsistencyError, FieldError) as exc:
        return None, str(exc)
