"""The records a results folder stores beside its parameter tables.

* :class:`RecordingCoverage`: what the recording of one trajectory covered and what the fit used
  (:class:`ImportSummary`: how one made elsewhere was read);
* what one identification step did, one record per kind of step (:data:`StepRecord`):
  :class:`MassFitStep`, :class:`BaseStep`, :class:`GainsStep` or :class:`SkippedStep`;
* :class:`BaseAnalysis`: what all the identification data determine (rank, base parameters);
* :class:`Verdict` with a :class:`TrajectoryVerdict` per trajectory and :class:`AxisFigures` per
  axis: the quality verdict, judged against its :class:`Thresholds`;
* :class:`TrajectoryMetrics`: the force prediction on one trajectory (the report's ``metrics.yaml``);
* :class:`FrictionChoice`: the friction model identified with.

Each is a frozen dataclass stored by :mod:`ident_hw.storage`: its keys in ``parameters.json``
are its fields' names, in their order; a field's ``stored(...)`` metadata says when its key is
left out. Folders written before a key existed read it as the field's default. Quantities are SI
(s); ratios are fractions (0..1) unless the name ends in ``_percent``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Annotated, Any, Mapping, Union

from ident_hw.storage import EMPTY, NONE, choose, stored

#: the reasons a row of a file made elsewhere is left out (:mod:`ident_hw.experiment.external`), with
#: what each says in the report
CUT_REASONS = {
    "fields": "wrong number of fields",
    "number": "a field that is no finite number",
    "absurd": "a value beyond anything the robot can reach",
    "time_back": "time not going forward",
}


@dataclass(frozen=True)
class CutRows:
    """The rows of a file left out for one reason (:data:`CUT_REASONS`): how many, and the first
    few line numbers (1-based, as an editor counts, header included)."""

    reason: str
    count: int
    lines: tuple[int, ...] = ()

    def describe(self) -> str:
        more = f" and {self.count - len(self.lines)} more" if self.count > len(self.lines) else ""
        return (f"{self.count} row{'s' if self.count > 1 else ''} with {CUT_REASONS[self.reason]} "
                f"(line{'s' if len(self.lines) > 1 else ''} {', '.join(map(str, self.lines))}{more})")


@dataclass(frozen=True)
class ImportSummary:
    """How a recording made elsewhere (a CSV file) was read: what the report says of it.

    ``data_rows``: the file's data rows; ``window``: the part asked for (``rows 635..3510``,
    ``12.0..48.5 s``, None: all); ``cut``: rows left out, per reason; ``idle_head_s``,
    ``idle_tail_s``: s of the idle head and tail left out (nothing moved there); ``step_min_s``,
    ``step_median_s``, ``step_max_s``: the file's time steps; ``period_s``: the even step its rows
    were resampled to (positions by a cubic spline, the other values linearly; nothing across a
    gap); ``gaps``: steps longer than the config's ``recordings.gap`` × the median, where the
    recording is cut; ``velocity``: ``recorded`` or ``differentiated``; ``force``: the column the
    forces come from, ``current`` or ``torque``."""

    data_rows: int
    window: str | None
    rows_used: int
    cut: tuple[CutRows, ...] = ()
    idle_head_s: float = 0.0
    idle_tail_s: float = 0.0
    step_min_s: float | None = None
    step_median_s: float | None = None
    step_max_s: float | None = None
    period_s: float | None = None
    gaps: int = 0
    velocity: str = "recorded"
    force: str = "current"

    def describe(self) -> list[str]:
        """The summary as lines for the terminal and the report."""
        lines = [f"{self.rows_used} of {self.data_rows} data rows used" + (f" ({self.window})" if self.window else "")]
        if self.idle_head_s or self.idle_tail_s:
            lines.append(f"idle head {self.idle_head_s:.2f} s and tail {self.idle_tail_s:.2f} s left out "
                         "(no actuator moved)")
        lines += [f"cut: {c.describe()}" for c in self.cut]
        if self.step_median_s and self.step_min_s and self.step_max_s and self.period_s:
            lines.append(f"time steps {1e3 * self.step_min_s:.3g}-{1e3 * self.step_max_s:.3g} ms (median "
                         f"{1e3 * self.step_median_s:.3g} ms), resampled to an even {1e3 * self.period_s:.4g} ms"
                         + (f"; cut at {self.gaps} gap{'s' if self.gaps > 1 else ''}" if self.gaps else ""))
        lines.append(f"forces from the {self.force} column; velocities {self.velocity}")
        return lines


@dataclass(frozen=True)
class AxisShortfall:
    """What one axis lacks in a recording (:class:`RecordingCoverage`): ``missing`` cycles without
    its position or current (a TPDO lost, late or not placeable), ``saturated`` rows whose current
    is at its drive's limit (clipped, not a measurement: :data:`ident_hw.segments.SATURATION`),
    the largest current recorded ``peak_A`` and the drive's limit ``limit_A`` (A)."""

    missing: int = 0
    saturated: int = 0
    peak_A: float | None = None
    limit_A: float | None = None


def _not_prepared(coverage: RecordingCoverage) -> bool:
    return not coverage.prepared


@dataclass(frozen=True)
class RecordingCoverage:
    """What the recording of one trajectory holds, and how much of it the fit used.

    ``recording_status``: ``complete``, ``stopped: <why>`` after a fault or a signal, ``running
    (checkpoint)`` when the recording process died, ``raw log`` or ``raw log, truncated``.
    ``cycles`` recorded of ``cycles_planned`` (None: unknown); ``coverage``: their ratio, at most 1
    (None: unknown); ``valid_fraction``: complete cycles / SYNC slots (a slot the producer skipped
    counts as incomplete); ``longest_gap_s``: s, the longest stretch without a complete cycle;
    ``skipped_slots``: SYNC slots without a row; ``unplaced_frames``: frames the master could not
    place in their cycle (some samples may hold another cycle's data).

    Once the recording is prepared (:meth:`with_use`; stored only then): ``samples_used`` after
    decimation, ``rows_left_out`` per rule (rows at the input rate,
    :class:`ident_hw.segments.Segments`), ``gaps`` the recording is cut at and the ``stretches``
    filtered; None before. ``positions_not_in_counts``: the actuators of an identification
    trajectory whose positions are not whole encoder counts
    (:func:`ident_hw.experiment.encoder.uncounted_axes`: no encoder draws were taken, for any
    step); ``imported``: how a recording made elsewhere was read (:class:`ImportSummary`; None: the
    tool's own); ``shortfalls``: per axis that misses cycles or saturates, its
    :class:`AxisShortfall`: the first cause the verdict names. These three are stored only when
    there are some.
    """

    file: str | None
    recording_status: str
    cycles: int
    cycles_planned: int | None
    coverage: float | None
    valid_fraction: float
    longest_gap_s: float
    skipped_slots: int = 0
    unplaced_frames: int | None = 0
    samples_used: int | None = field(default=None, metadata=stored(record=_not_prepared))
    rows_left_out: Mapping[str, int] | None = field(default=None, metadata=stored(record=_not_prepared))
    gaps: int | None = field(default=None, metadata=stored(record=_not_prepared))
    stretches: int | None = field(default=None, metadata=stored(record=_not_prepared))
    positions_not_in_counts: tuple[str, ...] = field(default=(), metadata=stored(EMPTY))
    imported: ImportSummary | None = field(default=None, metadata=stored(NONE))
    shortfalls: Mapping[str, AxisShortfall] = field(default_factory=dict, metadata=stored(EMPTY))

    @property
    def prepared(self) -> bool:
        """The fit's use of the recording is known (:meth:`with_use`)."""
        return self.samples_used is not None

    def with_use(self, samples_used: int, rows_left_out: Mapping[str, int], gaps: int,
                 stretches: int, positions_not_in_counts: tuple[str, ...] = ()) -> RecordingCoverage:
        """This coverage with what the fit used of the recording (a new record)."""
        return replace(self, samples_used=samples_used, rows_left_out=rows_left_out, gaps=gaps, stretches=stretches,
                       positions_not_in_counts=tuple(positions_not_in_counts))

    @staticmethod
    def upgrade_json(doc: dict[str, Any]) -> dict[str, Any]:
        """A null status, gap or count of skipped slots (folders of before they were always
        written); frames not placed that a folder does not count are unknown (None)."""
        for key, empty in (("recording_status", ""), ("longest_gap_s", 0.0), ("skipped_slots", 0)):
            if doc.get(key) is None:
                doc[key] = empty
        doc.setdefault("unplaced_frames", None)
        return doc


# ----------------------------------------------------------------------------- the steps
@dataclass(frozen=True)
class SkippedStep:
    """A step that fitted nothing: ``skipped`` says why."""

    name: str
    trajectories: tuple[str, ...]
    skipped: str


def _no_draws(step: MassFitStep | BaseStep) -> bool:
    return not step.encoder_draws


@dataclass(frozen=True)
class MassFitStep:
    """What an SQP mass-fit step did (:class:`ident_hw.identification.mass_fit.MassFitResult`).

    ``method`` and ``free``: the fit's method and the parameters it fitted. Its figures: every
    parameter's value after the fit (``parameters``, the held ones at their given values) and in
    the ``lsq_linear`` cross-check (``parameters_lsq_linear``), their largest relative difference
    ``max_rel_difference`` over the free ones, the weighted residual ``cost``, per actuator the
    unweighted ``residual_rms`` (its force unit, N or N·m) and the ``output_std`` that weighted it,
    the SLSQP ``iterations``, ``success`` and ``message``, and the free parameters ``at_bounds``.
    ``rows_left_out``: per trajectory, rows left out per rule. ``cond_scaled``: condition number
    of the step's regressor, columns scaled to unit RMS; ``cond_W``: of the weighted one of the
    statistics (None: no statistics). ``unexcited``: free parameters its data do not excite, held.
    ``statistics``: why the fit has no covariance (None: it has one). ``encoder_draws`` and
    ``encoder_sigma`` (one per estimate, in its unit): the encoders read again
    (:mod:`ident_hw.experiment.encoder`), 0 and () without. ``held_sigma`` (one per estimate, in
    its unit, () when none applies): what the values the step holds are worth in the estimate (an
    earlier step's sigma, else the CAD prior; :func:`ident_hw.experiment.steps.held_value_sigma`),
    a part of its sigma.
    """

    name: str
    trajectories: tuple[str, ...]
    method: str
    free: tuple[str, ...]
    parameters: Mapping[str, float] = field(default_factory=dict)
    parameters_lsq_linear: Mapping[str, float] = field(default_factory=dict)
    max_rel_difference: float | None = None
    cost: float | None = None
    residual_rms: tuple[float, ...] = ()
    output_std: tuple[float, ...] = ()
    iterations: int | None = None
    success: bool | None = None
    message: str | None = None
    at_bounds: tuple[str, ...] = ()
    rows_left_out: Mapping[str, Mapping[str, int]] = field(default_factory=dict)
    cond_scaled: float | None = None
    unexcited: tuple[str, ...] = field(default=(), metadata=stored(EMPTY))
    statistics: str | None = field(default=None, metadata=stored(NONE))
    encoder_draws: int = field(default=0, metadata=stored(EMPTY))
    encoder_sigma: tuple[float, ...] = field(default=(), metadata=stored(record=_no_draws))
    held_sigma: tuple[float, ...] = field(default=(), metadata=stored(EMPTY))
    cond_W: float | None = field(default=None, metadata=stored(NONE))


@dataclass(frozen=True)
class BaseStep:
    """What a least-squares step of base parameters did (``method`` ``WLS`` or ``OLS``; the
    estimates are its :class:`ident_hw.results.BaseFit`).

    ``free``: the parameters it fitted, ``eliminated``: those regrouped into the others or not
    excited. The figures of its fit (:class:`ident_hw.identification.least_squares.LeastSquaresResult`):
    the residual variance ``sigma2`` of the (weighted) rows, the condition number ``cond`` of the
    (weighted) regressor, how its ``covariance`` was computed, per actuator the unweighted
    ``residual_rms`` (its force unit) and the ``output_std`` that weighted it (None: OLS), and the
    base parameters ``poorly_identified``. ``cond_scaled``: condition number of its regressor,
    columns scaled to unit RMS. ``encoder_draws``, ``encoder_sigma``: as a :class:`MassFitStep`'s;
    ``encoder_shift`` (one per base parameter): how far the correction for the encoders' noise in
    the regressor moved each estimate (:func:`ident_hw.identification.least_squares.compensated`),
    () without. ``consistent``: why no physically consistent parameters reproduce its base
    parameters (None: there are some, or none were asked for).
    """

    name: str
    trajectories: tuple[str, ...]
    free: tuple[str, ...]
    method: str
    eliminated: tuple[str, ...]
    sigma2: float | None = None
    cond: float | None = None
    covariance: str | None = None
    residual_rms: tuple[float, ...] = ()
    output_std: tuple[float, ...] | None = None
    poorly_identified: tuple[str, ...] = ()
    cond_scaled: float | None = None
    encoder_draws: int = field(default=0, metadata=stored(EMPTY))
    encoder_sigma: tuple[float, ...] = field(default=(), metadata=stored(record=_no_draws))
    encoder_shift: tuple[float, ...] = field(default=(), metadata=stored(EMPTY))
    consistent: str | None = field(default=None, metadata=stored(NONE))


@dataclass(frozen=True)
class DriveGainsFigures:
    """What a ``gains`` step found (:mod:`ident_hw.identification.drive_gains`), per actuator in
    actuator order: the identified ``gains`` (N·m/A | N/A) and their jackknife ``sigma``, the
    config's gains ``configured`` (torque constant × gear), the currents' residual ``residual_rms``
    (A) at the identified gains and ``residual_rms_configured`` with the configured ones (every
    other parameter fitted again); the payload's ``payload_mass`` (kg) and the trajectories that
    carry it; ``rank``: the base parameters fitted with the gains; ``blocks``: the jackknife's;
    ``mass_axes``: the actuators whose forces the payload's known mass acts on (its mass column not
    zero there): the others' gains follow only from the parameters the axes share."""

    gains: tuple[float, ...]
    sigma: tuple[float, ...]
    configured: tuple[float, ...]
    residual_rms: tuple[float, ...]
    residual_rms_configured: tuple[float, ...]
    payload_mass: float
    payload_trajectories: tuple[str, ...]
    rank: int
    blocks: int
    mass_axes: tuple[str, ...] = ()


@dataclass(frozen=True)
class GainsStep:
    """What a ``gains`` step did: the drive gains of every actuator (``free``: ``g_<actuator>``),
    fitted with the base parameters of all the model's (``drive_gains``)."""

    name: str
    trajectories: tuple[str, ...]
    method: str
    free: tuple[str, ...]
    drive_gains: DriveGainsFigures


def _step_kind(doc: Mapping[str, Any]) -> type:
    """The record a step's JSON is: its keys tell (a skipped step says why; a gains step has its
    figures; a least-squares step names what it eliminated)."""
    if "skipped" in doc:
        return SkippedStep
    if doc.get("drive_gains"):
        return GainsStep
    return BaseStep if doc.get("eliminated") is not None else MassFitStep


#: what one identification step did: one record per kind of step, told apart in JSON by its keys
StepRecord = Annotated[Union[MassFitStep, BaseStep, GainsStep, SkippedStep], choose(_step_kind)]
#: the kinds of step record, for ``isinstance``
STEP_KINDS = (MassFitStep, BaseStep, GainsStep, SkippedStep)


@dataclass(frozen=True)
class BaseAnalysis:
    """What all the identification data determine, whether or not a step fits base parameters
    (:func:`ident_hw.identification.base_params.base_parameters` of every identification
    trajectory's regressor): its ``rank`` of ``n_params``, the rank tolerance ``rtol`` relative to
    the largest of the ``singular_values`` (column-scaled regressor), the ``base_parameters`` as
    readable expressions, the parameters ``eliminated`` and those ``unexcited`` (in no base
    parameter). An analysis, not an estimate: the estimates of one step's base parameters are its
    :class:`ident_hw.results.BaseFit`."""

    rank: int
    n_params: int
    rtol: float | None = None
    singular_values: tuple[float, ...] = ()
    base_parameters: tuple[str, ...] = ()
    eliminated: tuple[str, ...] = ()
    unexcited: tuple[str, ...] = ()

    @classmethod
    def of(cls, base: Any) -> BaseAnalysis:
        """The analysis of a :class:`ident_hw.identification.base_params.BaseParameters`."""
        return cls(rank=base.rank, n_params=len(base.names), rtol=base.rtol,
                   singular_values=tuple(base.singular_values.tolist()), base_parameters=base.expressions,
                   eliminated=base.eliminated, unexcited=base.unexcited)


# ----------------------------------------------------------------------------- the verdict
def _not_recorded(t: TrajectoryVerdict) -> bool:
    return not t.recorded


@dataclass(frozen=True)
class TrajectoryVerdict:
    """The figures the quality verdict judged on one trajectory.

    Of its recording (stored when it has one: :attr:`recorded`), the fields of its
    :class:`RecordingCoverage` the verdict judges, of the same names: ``recording_status``,
    ``coverage``, ``valid_fraction``, ``longest_gap_s`` (s) and ``unplaced_frames``. Of the force
    prediction on it, when it was judged (its ``role``, ``identification`` or ``validation``):
    ``d_tau_percent`` of the step-by-step parameters, ``base_fit_d_tau_percent`` of the
    base-parameter fit and ``disagreement_percent`` between the two predictions (None: not computed).
    """

    recording_status: str | None = field(default=None, metadata=stored(record=_not_recorded))
    coverage: float | None = field(default=None, metadata=stored(record=_not_recorded))
    valid_fraction: float | None = field(default=None, metadata=stored(record=_not_recorded))
    longest_gap_s: float | None = field(default=None, metadata=stored(record=_not_recorded))
    unplaced_frames: int | None = field(default=None, metadata=stored(record=_not_recorded))
    role: str | None = field(default=None, metadata=stored(NONE))
    d_tau_percent: float | None = field(default=None, metadata=stored(NONE))
    base_fit_d_tau_percent: float | None = field(default=None, metadata=stored(NONE))
    disagreement_percent: float | None = field(default=None, metadata=stored(NONE))

    #: the fields of a :class:`RecordingCoverage` the verdict judges (same names)
    JUDGED = ("recording_status", "coverage", "valid_fraction", "longest_gap_s", "unplaced_frames")

    @property
    def recorded(self) -> bool:
        """The trajectory has a recording (its figures are those of its :class:`RecordingCoverage`)."""
        return self.recording_status is not None

    @classmethod
    def of(cls, coverage: RecordingCoverage) -> TrajectoryVerdict:
        """The recording figures of ``coverage``."""
        return cls(**{name: getattr(coverage, name) for name in cls.JUDGED})

    @staticmethod
    def upgrade_json(doc: dict[str, Any]) -> dict[str, Any]:
        """A recording's figures with a null status (folders that wrote one) are still a recording's."""
        if any(key in doc for key in TrajectoryVerdict.JUDGED) and doc.get("recording_status") is None:
            doc["recording_status"] = ""
        return doc


@dataclass(frozen=True)
class Thresholds:
    """The limits a verdict was judged against: what ``identification.quality`` gave
    (:class:`ident_hw.config.QualityConfig`, whose fields say what each limits), stored under the
    names of this record so that the results format does not follow the config's (the verdict
    maps one onto the other). A limit a folder lacks (written before its check existed) reads as
    the default the check came with."""

    min_coverage: float = 1.0
    min_valid_fraction: float = 0.9
    max_gap: float = 0.2
    max_condition: float = 1e4
    max_d_tau: float = 10.0
    max_disagreement: float = 10.0
    min_well_identified: int = 1
    max_force_lag: float = 5e-4
    max_axis_gain: float = 2.0
    max_axis_rre: float = 10.0
    min_lag_share: float = 0.2
    max_residual_over_floor: float = 5.0


#: the per-axis checks of the quality verdict, by the name the verdict and the report give them
AXIS_CHECKS = ("gain", "noise floor", "force lag", "prediction")


@dataclass(frozen=True)
class AxisFigures:
    """The figures the quality verdict judged on one axis (:mod:`ident_hw.experiment.quality`);
    None: not judged (the verdict's ``not_judged`` says why, when it is not the axis's alone), and
    not stored.

    ``gain_percent``: how far its forces are from its own model, every fitted parameter
    refitted with its gain free (:func:`ident_hw.identification.axis_gain.axis_gains`), with
    its standard error ``gain_sigma_percent`` (inf: not determined, its own parameters absorb
    any gain of it). ``residual_over_floor``: its worst residual over what noise alone leaves
    it, on the rows the fits used, on trajectory ``floor_trajectory``: the residual's RMS
    ``residual_A`` and the floor ``floor_A`` (its drive's current, A). ``force_lag_s``: the delay
    of its measured forces behind the model's, and its standard error ``force_lag_sigma_s`` (s);
    ``force_lag_share``: the share of its residual the lag accounts for. ``rre_percent``: its
    worst relative residual where it moves, on trajectory ``rre_trajectory`` (a validation one,
    else an identification one), of the identified parameters, and ``rre_consistent_percent`` of
    the physically consistent ones (%). ``failed``: the checks (of :data:`AXIS_CHECKS`) that name
    it in a reason.
    """

    gain_percent: float | None = field(default=None, metadata=stored(NONE))
    gain_sigma_percent: float | None = field(default=None, metadata=stored(NONE))
    residual_over_floor: float | None = field(default=None, metadata=stored(NONE))
    floor_trajectory: str | None = field(default=None, metadata=stored(NONE))
    residual_A: float | None = field(default=None, metadata=stored(NONE))
    floor_A: float | None = field(default=None, metadata=stored(NONE))
    force_lag_s: float | None = field(default=None, metadata=stored(NONE))
    force_lag_sigma_s: float | None = field(default=None, metadata=stored(NONE))
    force_lag_share: float | None = field(default=None, metadata=stored(NONE))
    rre_percent: float | None = field(default=None, metadata=stored(NONE))
    rre_consistent_percent: float | None = field(default=None, metadata=stored(NONE))
    rre_trajectory: str | None = field(default=None, metadata=stored(NONE))
    failed: tuple[str, ...] = ()


@dataclass(frozen=True)
class StepVerdict:
    """The figure the quality verdict judged on one identification step: the scaled condition
    number ``cond_scaled`` of its regressor (None: the step fitted nothing)."""

    cond_scaled: float | None = None


@dataclass(frozen=True)
class Verdict:
    """The quality verdict of a result (:func:`ident_hw.experiment.quality.verdict`).

    ``passed``: no threshold missed; ``reasons``: one per missed threshold, first causes
    (what the recordings lack) before their consequences; ``thresholds``: the limits judged
    against (None: the folder holds none). Per trajectory its :class:`TrajectoryVerdict`; per
    step its :class:`StepVerdict`; ``well_identified``: the fitted parameters (physical, then
    base) with %σ at most the campaign's threshold. Per judged axis (``axes_judged``) its
    :class:`AxisFigures`. ``not_judged``: the checks that could not be made, and why
    (``{"noise floor": "no standstill"}``), and ``notes``: what the verdict saw and does not fail
    on, with why; these two stored only when there are some.
    """

    passed: bool
    reasons: tuple[str, ...] = ()
    thresholds: Thresholds | None = None
    trajectories: Mapping[str, TrajectoryVerdict] = field(default_factory=dict)
    steps: Mapping[str, StepVerdict] = field(default_factory=dict)
    well_identified: tuple[str, ...] = ()
    axes: Mapping[str, AxisFigures] = field(default_factory=dict)
    axes_judged: tuple[str, ...] = ()
    not_judged: Mapping[str, str] = field(default_factory=dict, metadata=stored(EMPTY))
    notes: tuple[str, ...] = field(default=(), metadata=stored(EMPTY))

    @staticmethod
    def upgrade_json(doc: dict[str, Any]) -> dict[str, Any]:
        """Folders of before the per-axis records: their lags and floor ratios become axes (the
        keys of retired checks, a gain spread or a residual ratio against the same drives, are
        left out); an empty ``thresholds`` is none."""
        if not doc.get("axes"):
            lags, sigmas = doc.get("force_lag_s") or {}, doc.get("force_lag_sigma_s") or {}
            over = doc.get("axis_residual_over_floor") or {}
            doc["axes"] = {name: {key: value for key, value in (("residual_over_floor", over.get(name)),
                                                                 ("force_lag_s", lags.get(name)),
                                                                 ("force_lag_sigma_s", sigmas.get(name)))
                                  if value is not None}
                           for name in dict.fromkeys([*lags, *over])}
        if not doc.get("thresholds"):
            doc["thresholds"] = None
        for key in ("reasons", "trajectories", "steps", "well_identified", "not_judged", "axes_judged", "notes"):
            if key in doc and doc[key] is None:
                del doc[key]
        return doc


# ----------------------------------------------------------------------------- metrics
@dataclass(frozen=True)
class PredictionMetrics:
    """How well one parameter set predicts the measured forces of one trajectory
    (:func:`ident_hw.identification.metrics.validation_metrics`): per actuator the RMS error
    ``rms`` (its force unit, N·m or N) and ``nrms_percent`` (% of the RMS force); ``d_tau_percent``
    (%, mean relative error of the force vector) and ``j_rmse`` (mixed units). NaN when nothing of
    the trajectory could be fitted."""

    rms: Mapping[str, float]
    nrms_percent: Mapping[str, float]
    d_tau_percent: float
    j_rmse: float


@dataclass(frozen=True)
class TrajectoryMetrics:
    """The force prediction on one trajectory: its ``role`` (``identification`` or
    ``validation``), the ``samples`` fitted, the figures of the step-by-step parameters'
    prediction (those of a :class:`PredictionMetrics`, :attr:`stepwise`) and of the base-parameter
    fit's (``base_fit``; None without one, and not stored)."""

    role: str
    samples: int
    rms: Mapping[str, float]
    nrms_percent: Mapping[str, float]
    d_tau_percent: float
    j_rmse: float
    base_fit: PredictionMetrics | None = field(default=None, metadata=stored(NONE))

    @classmethod
    def of(cls, role: str, samples: int, stepwise: PredictionMetrics,
           base_fit: PredictionMetrics | None = None) -> TrajectoryMetrics:
        return cls(role, samples, stepwise.rms, stepwise.nrms_percent, stepwise.d_tau_percent, stepwise.j_rmse,
                   base_fit)

    @property
    def stepwise(self) -> PredictionMetrics:
        """The step-by-step parameters' prediction."""
        return PredictionMetrics(self.rms, self.nrms_percent, self.d_tau_percent, self.j_rmse)


# ----------------------------------------------------------------------------- friction
@dataclass(frozen=True)
class Tried:
    """The values of a friction constant tried on the data (:mod:`ident_hw.experiment.friction_choice`)
    and, per value, each actuator's residual (the sum of its squared relative residuals)."""

    values: tuple[float, ...]
    relative_residual: tuple[tuple[float, ...], ...]


def _untried(choice: FrictionChoice) -> bool:
    return not choice.tried


@dataclass(frozen=True)
class FrictionChoice:
    """The friction model identified with (:mod:`ident_hw.experiment.friction_choice`): its
    Coulomb term's ``model``, whether each actuator has an ``offset``, its ``presliding`` distance
    (rad | m; None: not a Dahl model) and ``stribeck`` velocity (rad/s | m/s; None: no Stribeck
    term); ``tried``: for each constant chosen on the data (``presliding``, ``stribeck``), the
    values tried and the residual each left, on ``trajectories`` (both stored only when some
    constant was chosen)."""

    model: str
    offset: bool
    presliding: tuple[float, ...] | None = None
    stribeck: tuple[float, ...] | None = None
    tried: Mapping[str, Tried] = field(default_factory=dict, metadata=stored(EMPTY))
    trajectories: tuple[str, ...] = field(default=(), metadata=stored(record=_untried))

    def describe(self) -> str:
        parts = [f"friction: {self.model} Coulomb term, viscous"]
        if self.stribeck is not None:
            parts.append("Stribeck velocities " + ", ".join(f"{v:.3g}" for v in self.stribeck))
        if self.offset:
            parts.append("an offset per actuator")
        text = ", ".join(parts)
        if self.presliding is not None:
            text += "; presliding " + ", ".join(f"{v:.3g}" for v in self.presliding)
        if self.tried:
            text += (f" ({' and '.join(dict.fromkeys(self.tried))} chosen per actuator on "
                     f"{', '.join(self.trajectories)}: the least residual of a grid)")
        return text

