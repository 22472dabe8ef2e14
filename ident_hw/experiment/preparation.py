"""From a recording to what the fits use: each trajectory's rows cut at gaps and at rows left
out, filtered, differentiated, its regressor built and decimated in parallel (:func:`prepare`),
and what the recording covered (:func:`coverage`).

Each recording (positions and motor currents of the actuators at the SYNC rate, SI) goes through
the same preparation (:func:`ident_hw.filtering.prepare_actuated`, then the parallel filter and
decimation of forces and regressor), stretch by stretch, at its trajectory's own filter
(:meth:`ident_hw.experiment.inputs.IdentificationPlan.filter_of`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import astuple, dataclass

import numpy as np

from drivers.axis import AVERAGED
from drivers.errors import RecordingError
from drivers.profiles import AveragingFilter
from drivers.recording import Recording
from ident_hw.config.scales import drive_term
from ident_hw.filtering import (FilterSettings, kept_samples, near_rest, parallel_decimate, prepare_actuated,
                               running_average, through_position_lowpass)
from ident_hw.identification.model_comparison import ModelRows, power_energy_rows
from ident_hw.model.friction import FrictionModel
from ident_hw.model.interface import RobotModel
from ident_hw.records import AxisShortfall, ImportSummary, RecordingCoverage
from ident_hw.report.terminal import coverage_text
from ident_hw.segments import SATURATION, Segments, slot_indices, split, uniform

from .inputs import Axes, IdentificationPlan
from .recordings import identification_valid, recorded_currents

logger = logging.getLogger(__name__)

#: rows a stretch needs beyond the filters' support at its two ends
MIN_FILTERED = 8


@dataclass(frozen=True)
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
    segments: Segments
    Thetad: np.ndarray
    power: ModelRows | None = None
    energy: ModelRows | None = None

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


def current_averaging(axes: Axes, rec: Recording) -> tuple[AveragingFilter | None, ...] | None:
    """Each actuator's running average when ``rec`` holds its drive's averaged current, None for an
    axis with the instantaneous one; None when no axis has an averaged one. Both come from the
    recording (per axis, :func:`~ident_hw.experiment.recordings.recorded_currents`; its filter the
    recorded one, ``metadata.axes[i].current_filter``), the drive generation's filter (of the
    robot's ``axes``) where a recording made before did not keep it."""
    kinds = recorded_currents(rec, len(axes))
    if AVERAGED not in kinds:
        return None
    kept = [a.current_filter for a in rec.metadata.axes] if rec.metadata.axes else [None] * len(axes)
    return tuple(None if kind != AVERAGED else own or generation
                 for kind, own, generation in zip(kinds, kept, axes.current_averaging))


def segments_of(axes: Axes, rec: Recording, trim: int = 0, min_kept: int = 1,
                cut_trim: int | None = None) -> Segments:
    """The rows of ``rec`` the identification may use (:func:`ident_hw.segments.split`: a row
    whose positions and currents all arrived, :func:`identification_valid`)."""
    return split(rec.t, recording_period(rec), identification_valid(rec), rec.current, rec.target,
                 current_limit=axes.current_limit, acceleration_limit=axes.acceleration_limit,
                 counts_per_unit=axes.counts_per_unit, trim=trim, min_kept=min_kept, cut_trim=cut_trim)


def coverage(axes: Axes, planned: int | None, rec: Recording, imported: ImportSummary | None = None
             ) -> RecordingCoverage:
    """What a recording holds, for the report and the quality verdict.

    The cycles planned are the trajectory's set-points: the recording's ``n_targets``, else
    ``planned`` (the config's trajectory's, None: unknown); frames not placed in their cycle are
    counted by :class:`drivers.acquisition.CycleAssembler`. ``imported``: how a recording made
    elsewhere was read (its rows are all it holds: nothing was planned).
    """
    meta = rec.metadata
    planned = meta.n_targets or planned
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
                             coverage=None if not planned else min(1.0, len(rec.t) / planned),
                             valid_fraction=fraction, longest_gap_s=gap, skipped_slots=skipped,
                             unplaced_frames=int(meta.books.unplaced_frames), imported=imported,
                             shortfalls=shortfalls(axes, rec))


def shortfalls(axes: Axes, rec: Recording) -> dict[str, AxisShortfall]:
    """Per actuator that lacks something in ``rec``: the cycles without its position or current,
    the rows whose current is at its drive's limit (:data:`ident_hw.segments.SATURATION` of its
    current limit, as :func:`ident_hw.segments.split` leaves them out), its largest current
    and that limit. The verdict names these as the cause of what follows (rows left out, no
    stretch to fit)."""
    measured = identification_valid(rec)
    out = {}
    for j, name in enumerate(axes.names):
        current = np.abs(rec.current[measured[:, j], j])
        missing = int((~measured[:, j]).sum())
        saturated = int(np.sum(current >= SATURATION * axes.current_limit[j]))
        if missing or saturated:
            out[name] = AxisShortfall(missing=missing, saturated=saturated,
                                      peak_A=float(current.max()) if len(current) else None,
                                      limit_A=float(axes.current_limit[j]))
    return out


def _bridged(t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` (N, m) with the NaN rows linearly interpolated (for start guesses only)."""
    out = np.array(values, dtype=float)
    for j in range(out.shape[1]):
        bad = ~np.isfinite(out[:, j])
        if bad.any():
            out[bad, j] = np.interp(t[bad], t[~bad], out[~bad, j])
    return out


def trajectory_filter(plan: IdentificationPlan, name: str, sample_rate: float) -> FilterSettings:
    """The identification filter of trajectory ``name``'s recording sampled at ``sample_rate`` (Hz)
    (:meth:`~ident_hw.experiment.inputs.IdentificationPlan.filter_of`). Raises
    :class:`RecordingError` naming the trajectory, its rate and the config's filter where they do
    not fit (a cut-off above the recording's Nyquist frequency: recorded at another rate than the
    config's ``bus.sync_rate``, which the config check holds the cut-off to)."""
    try:
        return plan.filter_of(name, sample_rate)
    except ValueError as exc:
        raise RecordingError(f"trajectory {name!r} recorded at {sample_rate:g} Hz: identification.filter: {exc}") from exc


@dataclass(frozen=True)
class Usable:
    """A recording's trajectory filter at its rate, and the stretches of its rows it filters."""

    settings: FilterSettings
    segments: Segments


def usable_segments(plan: IdentificationPlan, name: str, rec: Recording) -> Usable:
    """Trajectory ``name``'s filter at its recording's rate, and the stretches of the recording
    it filters (:func:`segments_of`, trimmed as the filter needs)."""
    settings = trajectory_filter(plan, name, 1.0 / recording_period(rec))
    return Usable(settings, segments_of(plan.axes, rec, settings.trim, MIN_FILTERED, settings.cut_trim))


def kinematics_starts(robot: RobotModel, rec: Recording, segments: Segments) -> np.ndarray:
    """Start poses (len(segments.t), pose_size) for the kinematics of the usable rows: a
    continuation from the home pose along the whole recording, across its gaps (a Newton start
    only, never data: it picks the assembly mode)."""
    return robot.pose_series(_bridged(segments.t, rec.position), np.zeros(robot.pose_size))


def friction_of(robot: RobotModel) -> FrictionModel | None:
    """The robot's friction model where it has one (a described robot's,
    :class:`ident_hw.model.friction.FrictionModel`); None: the hand models' Coulomb and viscous terms."""
    friction = getattr(robot, "friction", None)
    return friction if isinstance(friction, FrictionModel) else None


def prepare(plan: IdentificationPlan, robot: RobotModel, name: str, rec: Recording, scalar_models: bool = False,
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
    axes = plan.axes
    where = f"{rec.metadata.file or 'recording'} (trajectory {name!r})"
    if len(rec.t) < 3:
        raise RecordingError(f"{where}: {len(rec.t)} samples, too few to identify from")
    empty = [label for label, ok in zip(axes.labels, np.asarray(identification_valid(rec).any(axis=0))) if not ok]
    if empty:
        raise RecordingError(f"{where}: no valid sample of {', '.join(empty)}")
    usable = usable_segments(plan, name, rec)
    settings, segments = usable.settings, usable.segments
    if not segments.slices:      # nothing to fit; the quality verdict says why
        a, m = len(robot.actuator_names), len(robot.parameter_names)
        return Prepared(name, np.zeros(0), np.zeros((0, a)), np.zeros((0, robot.pose_size)), np.zeros((0, a, m)),
                        np.zeros((0, a)), np.zeros((0, a), bool), segments=segments, Thetad=np.zeros((0, a)))
    guess = kinematics_starts(robot, rec, segments) if starts is None else starts
    averaging = current_averaging(axes, rec)
    # the friction columns that are not linear in the motion (a sign, a presliding state) pass the
    # positions' low-pass as the forces do
    coulomb = [i for i, p in enumerate(robot.parameter_names) if drive_term(p) in ("fc", "fs")]
    friction = friction_of(robot)
    min_speed = plan.identification.min_speed
    parts, scalar = [], []
    for stretch in segments.stretches:
        rows, ends = stretch.rows, stretch.ends
        t, Theta, current = uniform(segments.t[rows], rec.position[rows], rec.current[rows])
        samples = prepare_actuated(t, Theta, current, axes.force_per_amp, settings, ends)
        regressor, X = robot.identification_regressor(samples.Theta, samples.Thetad, samples.Thetadd, guess[rows])
        if averaging is not None:   # forces from averaged currents: the regressor through the same average
            period = (t[-1] - t[0]) / (len(t) - 1)
            steps = [UNFILTERED if f is None else astuple(f.over_period(period)) for f in averaging]
            regressor = running_average(regressor, np.array(steps))
        regressor, tau = through_position_lowpass(settings, samples.tau, regressor, coulomb, ends, copy=False)
        Y, tau = parallel_decimate(settings, regressor, tau, ends=ends)
        kept = kept_samples(settings, len(t), ends)
        slow = np.abs(samples.Thetad) < min_speed * axes.velocity_limit
        if friction is not None:    # an axis whose friction state its motion has not yet set
            slow |= ~friction.state_known(samples.Theta, samples.Thetad)
        parts.append((t[kept], samples.Theta[kept], X[kept], Y, tau, ~near_rest(slow, settings)[kept],
                      samples.Thetad[kept]))
        if scalar_models and len(t) > 2 * settings.trim:    # they trim ``trim`` at both ends
            scalar.append(power_energy_rows(robot, t, samples.Theta, samples.Thetad, samples.tau, guess[rows],
                                            settings))
    t, Theta, X, Y, tau, moving, Thetad = (np.concatenate(column) for column in zip(*parts))
    power, energy = (ModelRows.concatenate(column) for column in zip(*scalar)) if scalar else (None, None)
    return Prepared(name, t, Theta, X, Y, tau, moving, segments=segments, Thetad=Thetad, power=power, energy=energy)


def rest_speeds(plan: IdentificationPlan, robot: RobotModel) -> np.ndarray:
    """(a,) rad/s | m/s: an actuator slower than this is at rest (the validation's moving / at-rest
    split): its friction model's rest speed (a described robot's), else the identification's
    ``min_speed`` fraction of its velocity limit."""
    friction = friction_of(robot)
    if friction is not None:
        return np.full(len(robot.actuator_names), friction.rest_speed)
    return plan.identification.min_speed * plan.axes.velocity_limit


@dataclass(frozen=True)
class PreparedSet:
    """The needed trajectories' recordings prepared (:func:`prepare_all`): what each covered and
    each one's :class:`Prepared`, by name."""

    coverage: Mapping[str, RecordingCoverage]
    prepared: Mapping[str, Prepared]


def prepare_all(plan: IdentificationPlan, robot: RobotModel, recordings: Mapping[str, Recording],
                compared: Sequence[str], imported: Mapping[str, ImportSummary] | None = None) -> PreparedSet:
    """Each needed trajectory's coverage (what its recording holds; ``imported``: how those made
    elsewhere were read) and its :func:`prepare` (``compared``: the trajectories whose power and
    energy models' rows are made too). Says what each covered and how it was cut (logging)."""
    imported = imported or {}
    used = {name: coverage(plan.axes, plan.cycles_planned.get(name), recordings[name], imported.get(name))
            for name in plan.needed}
    for name, u in used.items():
        logger.info("  %s: %s", name, coverage_text(u))
    prepared: dict[str, Prepared] = {}
    for name in plan.needed:
        logger.info("preparing %s", name)
        prepared[name] = prepare(plan, robot, name, recordings[name], scalar_models=name in compared)
        if prepared[name].segments.describe():
            logger.info("  %s: %s", name, prepared[name].segments.describe())
    return PreparedSet(used, prepared)
