"""The records a results folder stores beside its parameter tables, each with its JSON mapping.

* :class:`RecordingCoverage`: what the recording of one trajectory covered and what the fit used;
* :class:`StepRecord`: what one identification step did (fitted, skipped), with the figures of its
  fit (:class:`LeastSquaresFigures` or :class:`MassFitFigures`);
* :class:`BaseAnalysis`: what all the identification data determine (rank, base parameters);
* :class:`Verdict` with a :class:`TrajectoryVerdict` per trajectory: the quality verdict;
* :class:`TrajectoryMetrics`: the force prediction on one trajectory (the report's ``metrics.yaml``).

Each is a frozen dataclass whose ``to_json()`` and ``from_json()`` are the one place its keys in
``parameters.json`` (``metrics.yaml``) are spelt; ``from_json`` also reads folders written before a key existed
(an absent key reads as None or empty). Quantities are SI (s); ratios are fractions (0..1)
unless the name ends in ``_percent``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any, Mapping

from ident_hw.config.identification import QualityConfig

#: the JSON key of each :class:`RecordingCoverage` field written before the recording is prepared,
#: in order, and whether the quality verdict shows it (:class:`TrajectoryVerdict`, same field name)
_COVERAGE_JSON = (("file", "file", False), ("recording_status", "recording_status", True),
                  ("cycles", "cycles", False), ("cycles_planned", "cycles_planned", False),
                  ("coverage", "planned_fraction", True), ("valid_fraction", "valid_fraction", True),
                  ("longest_gap_s", "longest_gap_s", True), ("skipped_slots", "skipped_slots", False),
                  ("unplaced_frames", "unplaced_frames", True))
#: the JSON keys and field names the quality verdict shows
_JUDGED_JSON = tuple((key, name) for key, name, judged in _COVERAGE_JSON if judged)


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
    lines: tuple[int, ...]

    def describe(self) -> str:
        more = f" and {self.count - len(self.lines)} more" if self.count > len(self.lines) else ""
        return (f"{self.count} row{'s' if self.count > 1 else ''} with {CUT_REASONS[self.reason]} "
                f"(line{'s' if len(self.lines) > 1 else ''} {', '.join(map(str, self.lines))}{more})")

    def to_json(self) -> dict:
        return {"reason": self.reason, "count": self.count, "lines": list(self.lines)}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> CutRows:
        return cls(reason=doc["reason"], count=int(doc["count"]), lines=tuple(doc.get("lines") or ()))


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
        if self.step_median_s:
            lines.append(f"time steps {1e3 * self.step_min_s:.3g}-{1e3 * self.step_max_s:.3g} ms (median "
                         f"{1e3 * self.step_median_s:.3g} ms), resampled to an even {1e3 * self.period_s:.4g} ms"
                         + (f"; cut at {self.gaps} gap{'s' if self.gaps > 1 else ''}" if self.gaps else ""))
        lines.append(f"forces from the {self.force} column; velocities {self.velocity}")
        return lines

    def to_json(self) -> dict:
        doc = {f.name: getattr(self, f.name) for f in fields(self)}
        doc["cut"] = [c.to_json() for c in self.cut]
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> ImportSummary:
        known = {f.name for f in fields(cls)}
        values = {k: v for k, v in doc.items() if k in known}
        values["cut"] = tuple(CutRows.from_json(c) for c in doc.get("cut") or ())
        return cls(**values)


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

    def to_json(self) -> dict:
        return {"missing": self.missing, "saturated": self.saturated, "peak_A": self.peak_A, "limit_A": self.limit_A}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> AxisShortfall:
        return cls(missing=doc.get("missing") or 0, saturated=doc.get("saturated") or 0, peak_A=doc.get("peak_A"),
                   limit_A=doc.get("limit_A"))


@dataclass(frozen=True)
class RecordingCoverage:
    """What the recording of one trajectory holds, and how much of it the fit used.

    ``recording_status``: ``complete``, ``stopped: <why>`` after a fault or a signal, ``running
    (checkpoint)`` when the recording process died, ``raw log`` or ``raw log, truncated``.
    ``cycles`` recorded of ``cycles_planned`` (None: unknown); ``planned_fraction``: their ratio,
    at most 1 (None: unknown; JSON ``coverage``); ``valid_fraction``: complete cycles / SYNC slots
    (a slot the producer skipped counts as incomplete); ``longest_gap_s``: s, the longest stretch
    without a complete cycle; ``skipped_slots``: SYNC slots without a row; ``unplaced_frames``:
    frames the master could not place in their cycle (some samples may hold another cycle's data).

    Once the recording is prepared (:meth:`with_use`): ``samples_used`` after decimation,
    ``rows_left_out`` per rule (rows at the input rate, :class:`ident_hw.segments.Segments`),
    ``gaps`` the recording is cut at and the ``stretches`` filtered; None before;
    ``uncounted_axes``: the actuators of an identification trajectory whose positions are not
    whole encoder counts (:func:`ident_hw.experiment.encoder.uncounted_axes`: no encoder draws
    were taken, for any step), JSON ``positions_not_in_counts`` when there are any;
    ``imported``: how a recording made elsewhere was read (:class:`ImportSummary`), JSON
    ``imported`` (absent for the tool's own recordings);
    ``shortfalls``: per axis that misses cycles or saturates, its :class:`AxisShortfall` (JSON
    ``shortfalls``, only when there is one): the first cause the verdict names.
    """

    file: str | None
    recording_status: str
    cycles: int
    cycles_planned: int | None
    planned_fraction: float | None
    valid_fraction: float
    longest_gap_s: float
    skipped_slots: int = 0
    unplaced_frames: int | None = 0
    samples_used: int | None = None
    rows_left_out: Mapping[str, int] | None = None
    gaps: int | None = None
    stretches: int | None = None
    uncounted_axes: tuple[str, ...] = ()
    imported: ImportSummary | None = None
    shortfalls: Mapping[str, AxisShortfall] = field(default_factory=dict)

    @property
    def prepared(self) -> bool:
        """The fit's use of the recording is known (:meth:`with_use`)."""
        return self.samples_used is not None

    def with_use(self, samples_used: int, rows_left_out: Mapping[str, int], gaps: int,
                 stretches: int, uncounted_axes: tuple[str, ...] = ()) -> RecordingCoverage:
        """This coverage with what the fit used of the recording."""
        return replace(self, samples_used=samples_used, rows_left_out=rows_left_out, gaps=gaps, stretches=stretches,
                       uncounted_axes=tuple(uncounted_axes))

    def to_json(self) -> dict:
        doc = {key: getattr(self, name) for key, name, _ in _COVERAGE_JSON}
        if self.prepared:
            doc.update(samples_used=self.samples_used, rows_left_out=self.rows_left_out, gaps=self.gaps,
                       stretches=self.stretches)
        if self.uncounted_axes:
            doc["positions_not_in_counts"] = list(self.uncounted_axes)
        if self.imported is not None:
            doc["imported"] = self.imported.to_json()
        if self.shortfalls:
            doc["shortfalls"] = {name: axis.to_json() for name, axis in self.shortfalls.items()}
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> RecordingCoverage:
        books = {name: doc.get(key) for key, name, _ in _COVERAGE_JSON}
        status = books["recording_status"]
        books.update(recording_status="" if status is None else str(status), cycles=doc["cycles"],
                     longest_gap_s=books["longest_gap_s"] or 0.0, skipped_slots=books["skipped_slots"] or 0)
        return cls(**books, samples_used=doc.get("samples_used"), rows_left_out=doc.get("rows_left_out"),
                   gaps=doc.get("gaps"), stretches=doc.get("stretches"),
                   uncounted_axes=tuple(doc.get("positions_not_in_counts") or ()),
                   imported=ImportSummary.from_json(doc["imported"]) if doc.get("imported") else None,
                   shortfalls={name: AxisShortfall.from_json(a) for name, a in (doc.get("shortfalls") or {}).items()})


@dataclass(frozen=True)
class LeastSquaresFigures:
    """The figures of a step's least-squares fit of base parameters
    (:class:`ident_hw.identification.least_squares.LeastSquaresResult`): the residual variance
    ``sigma2`` of the (weighted) rows, the condition number ``cond`` of the (weighted) regressor,
    how its ``covariance`` was computed, per actuator the unweighted ``residual_rms`` (its force
    unit, N or N·m) and the ``output_std`` that weighted it (None: OLS), and the base parameters
    ``poorly_identified``. In JSON, keys of the step's record."""

    sigma2: float | None = None
    cond: float | None = None
    covariance: str | None = None
    residual_rms: tuple[float, ...] = ()
    output_std: tuple[float, ...] | None = None
    poorly_identified: tuple[str, ...] = ()

    @classmethod
    def of(cls, fit) -> LeastSquaresFigures:
        """The figures of a :class:`ident_hw.identification.least_squares.LeastSquaresResult`."""
        return cls(sigma2=float(fit.sigma2), cond=float(fit.cond), covariance=fit.covariance_method,
                   residual_rms=tuple(fit.residual_rms.tolist()),
                   output_std=None if fit.output_std is None else tuple(fit.output_std.tolist()),
                   poorly_identified=tuple(fit.poorly_identified))

    def to_json(self) -> dict:
        return {"sigma2": self.sigma2, "cond": self.cond, "covariance": self.covariance,
                "residual_rms": list(self.residual_rms),
                "output_std": None if self.output_std is None else list(self.output_std),
                "poorly_identified": list(self.poorly_identified)}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> LeastSquaresFigures:
        output_std = doc.get("output_std")
        return cls(sigma2=doc.get("sigma2"), cond=doc.get("cond"), covariance=doc.get("covariance"),
                   residual_rms=tuple(doc.get("residual_rms") or ()),
                   output_std=None if output_std is None else tuple(output_std),
                   poorly_identified=tuple(doc.get("poorly_identified") or ()))


@dataclass(frozen=True)
class MassFitFigures:
    """The figures of a step's SQP mass fit (:class:`ident_hw.identification.mass_fit.MassFitResult`):
    every parameter's value after the fit (``parameters``, the held ones at their given values)
    and in the ``lsq_linear`` cross-check (``parameters_lsq_linear``), their largest relative
    difference ``max_rel_difference`` over the free ones, the weighted residual ``cost``, per
    actuator the unweighted ``residual_rms`` (its force unit, N or N·m) and the ``output_std``
    that weighted it, the SLSQP ``iterations``, ``success`` and ``message``, and the free
    parameters ``at_bounds``. In JSON, keys of the step's record."""

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

    @classmethod
    def of(cls, fit) -> MassFitFigures:
        """The figures of a :class:`ident_hw.identification.mass_fit.MassFitResult`."""
        return cls(parameters={nm: float(v) for nm, v in zip(fit.names, fit.coef)},
                   parameters_lsq_linear={nm: float(v) for nm, v in zip(fit.names, fit.coef_lsq)},
                   max_rel_difference=float(fit.max_rel_difference), cost=float(fit.cost),
                   residual_rms=tuple(fit.residual_rms.tolist()), output_std=tuple(fit.output_std.tolist()),
                   iterations=int(fit.iterations), success=bool(fit.success), message=fit.message,
                   at_bounds=tuple(fit.at_bounds))

    def to_json(self) -> dict:
        return {"parameters": dict(self.parameters), "parameters_lsq_linear": dict(self.parameters_lsq_linear),
                "max_rel_difference": self.max_rel_difference, "cost": self.cost,
                "residual_rms": list(self.residual_rms), "output_std": list(self.output_std),
                "iterations": self.iterations, "success": self.success, "message": self.message,
                "at_bounds": list(self.at_bounds)}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> MassFitFigures:
        return cls(parameters=doc.get("parameters") or {}, parameters_lsq_linear=doc.get("parameters_lsq_linear") or {},
                   max_rel_difference=doc.get("max_rel_difference"), cost=doc.get("cost"),
                   residual_rms=tuple(doc.get("residual_rms") or ()), output_std=tuple(doc.get("output_std") or ()),
                   iterations=doc.get("iterations"), success=doc.get("success"), message=doc.get("message"),
                   at_bounds=tuple(doc.get("at_bounds") or ()))


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

    def to_json(self) -> dict:
        return {f.name: (list(getattr(self, f.name)) if isinstance(getattr(self, f.name), tuple) else getattr(self, f.name))
                for f in fields(self)}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> DriveGainsFigures:
        return cls(**{f.name: (tuple(doc[f.name]) if isinstance(doc[f.name], list) else doc[f.name])
                      for f in fields(cls) if f.name in doc})


@dataclass(frozen=True)
class StepRecord:
    """What one identification step did.

    ``skipped``: why it fitted nothing (None: it fitted). ``method`` and ``free``: the fit's
    method and the parameters it fitted. ``eliminated``: for a least-squares step of base
    parameters, the free parameters regrouped into the others or not excited; None for an SQP
    mass fit. ``figures``: the fit's own figures (of a least-squares step or a mass fit; None:
    skipped, or not in the folder). ``rows_left_out``: per trajectory, rows
    left out per rule (mass fit). ``cond_scaled``: condition number of the step's regressor,
    columns scaled to unit RMS; ``cond_W``: of the weighted one of the statistics (mass fit).
    ``unexcited``: free parameters its data do not excite, held. ``statistics_missing``: why the
    mass fit has no covariance. ``encoder_draws`` and ``encoder_sigma`` (one per estimate, in
    its unit): the encoders read again (:mod:`ident_hw.experiment.encoder`), 0 and () without;
    ``encoder_shift`` (a least-squares step, one per base parameter): how far the correction for
    the encoders' noise in the regressor moved each estimate
    (:func:`ident_hw.identification.least_squares.compensated`), () without.
    ``held_sigma`` (one per estimate of a mass fit, in its unit, () when none applies): what
    the values its step holds are worth in the estimate (an earlier step's sigma, else the CAD
    prior; :func:`ident_hw.experiment.offline.held_value_sigma`), a part of its sigma.
    ``consistency_failure``: why no physically consistent parameters reproduce the step's base
    parameters (None: there are some, or none were asked for). ``drive_gains``: a ``gains``
    step's figures (:class:`DriveGainsFigures`; JSON ``drive_gains``), None for the others.
    """

    name: str
    trajectories: tuple[str, ...]
    skipped: str | None = None
    method: str = ""
    free: tuple[str, ...] = ()
    eliminated: tuple[str, ...] | None = None
    figures: LeastSquaresFigures | MassFitFigures | None = None
    rows_left_out: Mapping[str, Mapping[str, int]] | None = None
    cond_scaled: float | None = None
    unexcited: tuple[str, ...] = ()
    statistics_missing: str | None = None
    encoder_draws: int = 0
    encoder_sigma: tuple[float, ...] = ()
    encoder_shift: tuple[float, ...] = ()
    held_sigma: tuple[float, ...] = ()
    cond_W: float | None = None
    consistency_failure: str | None = None
    drive_gains: DriveGainsFigures | None = None

    @property
    def fits_base_parameters(self) -> bool:
        """A least-squares step of base parameters (else an SQP mass fit, or skipped)."""
        return self.eliminated is not None

    def to_json(self) -> dict:
        doc: dict[str, Any] = {"name": self.name, "trajectories": list(self.trajectories)}
        if self.skipped is not None:
            doc["skipped"] = self.skipped
            return doc
        if self.drive_gains is not None:
            doc.update(method=self.method, free=list(self.free), drive_gains=self.drive_gains.to_json())
            return doc
        figures = {} if self.figures is None else self.figures.to_json()
        encoder = ({"encoder_draws": self.encoder_draws, "encoder_sigma": list(self.encoder_sigma)}
                   if self.encoder_draws else {})
        if self.encoder_shift:
            encoder["encoder_shift"] = list(self.encoder_shift)
        if self.fits_base_parameters:
            doc.update({"free": list(self.free), "method": self.method, "eliminated": list(self.eliminated),
                        **figures, "cond_scaled": self.cond_scaled, **encoder})
            if self.consistency_failure is not None:
                doc["consistent"] = self.consistency_failure
            return doc
        doc.update({"method": self.method, "free": list(self.free), **figures,
                    "rows_left_out": self.rows_left_out, "cond_scaled": self.cond_scaled})
        if self.unexcited:
            doc["unexcited"] = list(self.unexcited)
        if self.statistics_missing is not None:
            doc["statistics"] = self.statistics_missing
        doc.update(encoder)
        if self.held_sigma:
            doc["held_sigma"] = list(self.held_sigma)
        if self.cond_W is not None:
            doc["cond_W"] = self.cond_W
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> StepRecord:
        if doc.get("drive_gains"):
            return cls(name=doc.get("name", ""), trajectories=tuple(doc.get("trajectories") or ()),
                       method=doc.get("method", ""), free=tuple(doc.get("free") or ()),
                       drive_gains=DriveGainsFigures.from_json(doc["drive_gains"]))
        eliminated = doc.get("eliminated")
        kind = MassFitFigures if eliminated is None else LeastSquaresFigures
        figures = None if "skipped" in doc else kind.from_json(doc)
        figures = None if figures == kind() else figures       # none in the folder
        return cls(name=doc.get("name", ""), trajectories=tuple(doc.get("trajectories") or ()),
                   skipped=doc.get("skipped"), method=doc.get("method", ""), free=tuple(doc.get("free") or ()),
                   eliminated=None if eliminated is None else tuple(eliminated),
                   figures=figures,
                   rows_left_out=doc.get("rows_left_out"), cond_scaled=doc.get("cond_scaled"),
                   unexcited=tuple(doc.get("unexcited") or ()), statistics_missing=doc.get("statistics"),
                   encoder_draws=doc.get("encoder_draws") or 0, encoder_sigma=tuple(doc.get("encoder_sigma") or ()),
                   encoder_shift=tuple(doc.get("encoder_shift") or ()),
                   held_sigma=tuple(doc.get("held_sigma") or ()), cond_W=doc.get("cond_W"), consistency_failure=doc.get("consistent"))


@dataclass(frozen=True)
class BaseAnalysis:
    """What all the identification data determine, whether or not a step fits base parameters
    (:func:`ident_hw.identification.base_params.base_parameters` of every identification
    trajectory's regressor): its ``rank`` of ``n_params``, the rank tolerance ``rtol`` relative to
    the largest of the ``singular_values`` (column-scaled regressor), the base parameters as
    readable ``expressions`` (JSON ``base_parameters``), the parameters ``eliminated`` and those
    ``unexcited`` (in no base parameter). An analysis, not an estimate: the estimates of one step's
    base parameters are its :class:`ident_hw.results.BaseFit`."""

    rank: int
    n_params: int
    rtol: float | None = None
    singular_values: tuple[float, ...] = ()
    expressions: tuple[str, ...] = ()
    eliminated: tuple[str, ...] = ()
    unexcited: tuple[str, ...] = ()

    @classmethod
    def of(cls, base) -> BaseAnalysis:
        """The analysis of a :class:`ident_hw.identification.base_params.BaseParameters`."""
        return cls(rank=base.rank, n_params=len(base.names), rtol=base.rtol,
                   singular_values=tuple(base.singular_values.tolist()), expressions=base.expressions,
                   eliminated=base.eliminated, unexcited=base.unexcited)

    def to_json(self) -> dict:
        return {"rank": self.rank, "n_params": self.n_params, "rtol": self.rtol,
                "singular_values": list(self.singular_values), "base_parameters": list(self.expressions),
                "eliminated": list(self.eliminated), "unexcited": list(self.unexcited)}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> BaseAnalysis:
        return cls(rank=doc.get("rank"), n_params=doc.get("n_params"), rtol=doc.get("rtol"),
                   singular_values=tuple(doc.get("singular_values") or ()),
                   expressions=tuple(doc.get("base_parameters") or ()),
                   eliminated=tuple(doc.get("eliminated") or ()), unexcited=tuple(doc.get("unexcited") or ()))


@dataclass(frozen=True)
class TrajectoryVerdict:
    """The figures the quality verdict judged on one trajectory.

    Of its recording (``recorded``: it has one), the fields of its :class:`RecordingCoverage` the
    verdict judges, with their names and JSON keys: ``recording_status``, ``planned_fraction``,
    ``valid_fraction``, ``longest_gap_s`` (s) and ``unplaced_frames``. Of the force prediction on
    it, when it was judged (its ``role``, ``identification`` or ``validation``): ``d_tau_percent`` of the
    step-by-step parameters, ``base_fit_d_tau_percent`` of the base-parameter fit and
    ``disagreement_percent`` between the two predictions (None: not computed).
    """

    recorded: bool = False
    recording_status: str | None = None
    planned_fraction: float | None = None
    valid_fraction: float | None = None
    longest_gap_s: float | None = None
    unplaced_frames: int | None = None
    role: str | None = None
    d_tau_percent: float | None = None
    base_fit_d_tau_percent: float | None = None
    disagreement_percent: float | None = None

    @classmethod
    def of(cls, coverage: RecordingCoverage) -> TrajectoryVerdict:
        """The recording figures of ``coverage``."""
        return cls(recorded=True, **{name: getattr(coverage, name) for _, name in _JUDGED_JSON})

    def to_json(self) -> dict:
        doc: dict[str, Any] = {}
        if self.recorded:
            doc.update((key, getattr(self, name)) for key, name in _JUDGED_JSON)
        if self.role is not None:
            doc["role"] = self.role
        for key in ("d_tau_percent", "base_fit_d_tau_percent", "disagreement_percent"):
            if getattr(self, key) is not None:
                doc[key] = getattr(self, key)
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> TrajectoryVerdict:
        recorded = any(key in doc for key, _ in _JUDGED_JSON)
        return cls(recorded=recorded, **{name: doc.get(key) for key, name in _JUDGED_JSON},
                   role=doc.get("role"), d_tau_percent=doc.get("d_tau_percent"),
                   base_fit_d_tau_percent=doc.get("base_fit_d_tau_percent"),
                   disagreement_percent=doc.get("disagreement_percent"))


def _thresholds_to_json(limits: QualityConfig | None) -> dict:
    """The JSON form of a verdict's thresholds: ``{field: value}`` in field order, ``{}`` for None."""
    return {} if limits is None else {f.name: getattr(limits, f.name) for f in fields(QualityConfig)}


def _thresholds_from_json(doc: Mapping[str, Any] | None) -> QualityConfig | None:
    """The thresholds of :func:`_thresholds_to_json`: None for none, a limit not written at its default."""
    if not doc:
        return None
    return QualityConfig(**{f.name: doc[f.name] for f in fields(QualityConfig) if f.name in doc})


#: the per-axis checks of the quality verdict, by the name the verdict and the report give them
AXIS_CHECKS = ("gain", "noise floor", "force lag", "prediction")


@dataclass(frozen=True)
class AxisFigures:
    """The figures the quality verdict judged on one axis (:mod:`ident_hw.experiment.quality`);
    None: not judged (the verdict's ``not_judged`` says why, when it is not the axis's alone).

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

    gain_percent: float | None = None
    gain_sigma_percent: float | None = None
    residual_over_floor: float | None = None
    floor_trajectory: str | None = None
    residual_A: float | None = None
    floor_A: float | None = None
    force_lag_s: float | None = None
    force_lag_sigma_s: float | None = None
    force_lag_share: float | None = None
    rre_percent: float | None = None
    rre_consistent_percent: float | None = None
    rre_trajectory: str | None = None
    failed: tuple[str, ...] = ()

    def to_json(self) -> dict:
        doc: dict[str, Any] = {f.name: getattr(self, f.name) for f in fields(self)
                               if f.name != "failed" and getattr(self, f.name) is not None}
        doc["failed"] = list(self.failed)
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> AxisFigures:
        return cls(**{f.name: doc.get(f.name) for f in fields(cls) if f.name != "failed"},
                   failed=tuple(doc.get("failed") or ()))


@dataclass(frozen=True)
class Verdict:
    """The quality verdict of a result (:func:`ident_hw.experiment.quality.verdict`).

    ``passed``: no threshold missed; ``reasons``: one per missed threshold, first causes
    (what the recordings lack) before their consequences; ``thresholds``: the
    ``identification.quality`` limits judged against (JSON: one key per field of
    :class:`ident_hw.config.QualityConfig`; None when the folder holds none, a limit it lacks
    reads as its default). Per trajectory its
    :class:`TrajectoryVerdict`; per step its scaled condition number ``cond_scaled`` (JSON
    ``steps``); ``well_identified``: the fitted parameters (physical, then base) with %σ at most
    the campaign's threshold. Per judged axis (``axes_judged``) its :class:`AxisFigures` (JSON
    ``axes``). ``not_judged``: the checks that could not be made, and why (JSON only when there
    are some: ``{"noise floor": "no standstill"}``). ``notes``: what the verdict saw and does not
    fail on, with why (JSON only when there are some).
    """

    passed: bool
    reasons: tuple[str, ...] = ()
    thresholds: QualityConfig | None = None
    trajectories: Mapping[str, TrajectoryVerdict] = field(default_factory=dict)
    cond_scaled: Mapping[str, float | None] = field(default_factory=dict)
    well_identified: tuple[str, ...] = ()
    axes: Mapping[str, AxisFigures] = field(default_factory=dict)
    not_judged: Mapping[str, str] = field(default_factory=dict)
    axes_judged: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def to_json(self) -> dict:
        doc = {"passed": self.passed, "reasons": list(self.reasons), "thresholds": _thresholds_to_json(self.thresholds),
               "trajectories": {name: t.to_json() for name, t in self.trajectories.items()},
               "steps": {name: {"cond_scaled": cond} for name, cond in self.cond_scaled.items()},
               "well_identified": list(self.well_identified),
               "axes": {name: figures.to_json() for name, figures in self.axes.items()},
               "axes_judged": list(self.axes_judged)}
        if self.not_judged:
            doc["not_judged"] = dict(self.not_judged)
        if self.notes:
            doc["notes"] = list(self.notes)
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Verdict:
        axes = {name: AxisFigures.from_json(figures) for name, figures in (doc.get("axes") or {}).items()}
        if not axes:            # a folder written before the per-axis records: its lags and floor ratios
            lags, sigmas = doc.get("force_lag_s") or {}, doc.get("force_lag_sigma_s") or {}
            over = doc.get("axis_residual_over_floor") or {}
            axes = {name: AxisFigures(residual_over_floor=over.get(name), force_lag_s=lags.get(name),
                                      force_lag_sigma_s=sigmas.get(name))
                    for name in dict.fromkeys([*lags, *over])}
        return cls(passed=bool(doc["passed"]), reasons=tuple(doc.get("reasons") or ()),
                   thresholds=_thresholds_from_json(doc.get("thresholds")),
                   trajectories={name: TrajectoryVerdict.from_json(t)
                                 for name, t in (doc.get("trajectories") or {}).items()},
                   cond_scaled={name: s.get("cond_scaled") for name, s in (doc.get("steps") or {}).items()},
                   well_identified=tuple(doc.get("well_identified") or ()), axes=axes,
                   not_judged=doc.get("not_judged") or {}, axes_judged=tuple(doc.get("axes_judged") or ()),
                   notes=tuple(doc.get("notes") or ()))


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

    def to_json(self) -> dict:
        return {"rms": dict(self.rms), "nrms_percent": dict(self.nrms_percent), "d_tau_percent": self.d_tau_percent,
                "j_rmse": self.j_rmse}


@dataclass(frozen=True)
class TrajectoryMetrics:
    """The force prediction on one trajectory: its ``role`` (``identification`` or
    ``validation``), the ``samples`` fitted, the prediction of the step-by-step parameters
    (``stepwise``, whose keys the JSON holds at the top level) and of the base-parameter fit
    (``base_fit``; None without one)."""

    role: str
    samples: int
    stepwise: PredictionMetrics
    base_fit: PredictionMetrics | None = None

    def to_json(self) -> dict:
        doc = {"role": self.role, "samples": self.samples, **self.stepwise.to_json()}
        if self.base_fit is not None:
            doc["base_fit"] = self.base_fit.to_json()
        return doc


@dataclass(frozen=True)
class FrictionChoice:
    """The friction model identified with (:mod:`ident_hw.experiment.friction_choice`): its
    Coulomb term's ``model``, whether each actuator has an ``offset``, its ``presliding`` distance
    (rad | m; None: not a Dahl model) and ``stribeck`` velocity (rad/s | m/s; None: no Stribeck
    term); ``tried``: for each constant chosen on the data (``presliding``, ``stribeck``), the
    values tried and the residual each left (the sum of the actuators' squared relative
    residuals), on ``trajectories``."""

    model: str
    offset: bool
    presliding: tuple[float, ...] | None = None
    stribeck: tuple[float, ...] | None = None
    tried: Mapping[str, tuple[tuple[float, ...], tuple[tuple[float, ...], ...]]] = field(default_factory=dict)
    trajectories: tuple[str, ...] = ()

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

    def to_json(self) -> dict:
        doc = {"model": self.model, "offset": self.offset,
               "presliding": None if self.presliding is None else list(self.presliding),
               "stribeck": None if self.stribeck is None else list(self.stribeck)}
        if self.tried:
            doc["tried"] = {k: {"values": list(v), "relative_residual": [list(x) for x in r]}
                            for k, (v, r) in self.tried.items()}
            doc["trajectories"] = list(self.trajectories)
        return doc

    @classmethod
    def from_json(cls, doc: Mapping) -> FrictionChoice:
        tried = {k: (tuple(v["values"]), tuple(tuple(x) for x in v["relative_residual"]))
                 for k, v in (doc.get("tried") or {}).items()}

        def row(key):
            return None if doc.get(key) is None else tuple(doc[key])
        return cls(model=doc["model"], offset=bool(doc.get("offset")), presliding=row("presliding"),
                   stribeck=row("stribeck"), tried=tried, trajectories=tuple(doc.get("trajectories") or ()))
