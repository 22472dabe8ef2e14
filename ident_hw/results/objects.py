"""The results of a campaign as typed objects, each built once and frozen.

:class:`Results` holds the physical parameters (:class:`ParameterTable`, whose rows are
:class:`ParameterRow`), the base-parameter fit (:class:`BaseFit`, rows :class:`BaseRow`), the
forces along each trajectory (:class:`TrajectoryFit`), an online run's estimates
(:class:`OnlineTrace`) and the records of :mod:`ident_hw.records` (steps, coverage, verdict).
The folder that stores them is :mod:`ident_hw.results.folder`; the figures computed from them,
:mod:`ident_hw.results.figures`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from ident_hw.identification.intervals import coverage_factor, effective_dof
from ident_hw.identification.least_squares import POORLY_IDENTIFIED_PERCENT
from ident_hw.identification.model_comparison import ModelComparison
from ident_hw.identification.physical_size import well_identified
from ident_hw.identification.physical import ConsistentSet
from ident_hw.model.interface import FORCE_UNITS, POSITION_UNITS
from ident_hw.records import (BaseAnalysis, BaseStep, FrictionChoice, MassFitStep, RecordingCoverage, StepRecord,
                              Verdict)
from ident_hw.storage import NONE, stored


def _well_identified(rel_sigma_percent: float | None, threshold: float) -> bool:
    """%σ defined and at most ``threshold`` (an estimate of 0, at its bound or without statistics
    has none)."""
    return rel_sigma_percent is not None and rel_sigma_percent <= threshold


def _error_percent(estimate: float, truth: float | None) -> float | None:
    return 100.0 * (estimate - truth) / abs(truth) if truth else None


def error_sigmas(value: float, truth: float | None, sigma: float | None) -> float | None:
    """``(value - truth) / sigma``, the error in units of the reported standard deviation; None
    without a truth or a positive finite sigma."""
    if truth is None or sigma is None or not math.isfinite(sigma) or sigma <= 0:
        return None
    return (value - truth) / sigma


def _no_truth(row: ParameterRow | BaseRow) -> bool:
    return row.truth is None


@dataclass(frozen=True)
class ParameterRow:
    """One physical parameter of the results table (SI unit from the robot model), as
    ``parameters.json`` holds it.

    ``step`` names the identification step that estimated it ("" = held at ``initial``);
    ``truth``/``error_percent`` exist in simulation only (stored then); ``well_identified``:
    fitted with a %σ at most the campaign's threshold. ``dof``: the effective degrees of freedom
    of ``sigma`` (:mod:`ident_hw.identification.intervals`; inf: the normal interval), which
    :attr:`interval_95` follows. These two are not stored: they are judged again from the table.
    """

    name: str
    unit: str
    initial: float
    identified: float
    sigma: float | None
    rel_sigma_percent: float | None
    bounds: tuple[float | None, float | None]
    step: str
    method: str
    well_identified: bool = field(default=False, metadata=stored(store=False))
    truth: float | None = field(default=None, metadata=stored(record=_no_truth))
    error_percent: float | None = field(default=None, metadata=stored(record=_no_truth))
    dof: float = field(default=math.inf, metadata=stored(store=False))

    @property
    def interval_95(self) -> float | None:
        """Half-width of the 95 % interval, ``k sigma`` (None without a sigma)."""
        return None if self.sigma is None else float(coverage_factor(self.dof)) * self.sigma

    @property
    def fitted(self) -> bool:
        return bool(self.step)

    @property
    def error_sigmas(self) -> float | None:
        """(identified - truth) / sigma: how many of its own standard deviations the estimate is
        off (None without a truth or a sigma)."""
        return error_sigmas(self.identified, self.truth, self.sigma)

    @property
    def poorly_identified(self) -> bool:
        """Fitted, but its %σ is above the threshold or undefined."""
        return self.fitted and not self.well_identified


@dataclass(frozen=True)
class BaseRow:
    """One base parameter of a :class:`BaseFit`: a readable combination ``base_parameter`` of
    the physical parameters, its estimate and statistics (``truth``/``error_percent`` in
    simulation; ``dof`` as :class:`ParameterRow`'s, not stored)."""

    base_parameter: str
    initial: float
    identified: float
    sigma: float
    rel_sigma_percent: float | None
    well_identified: bool
    truth: float | None = field(default=None, metadata=stored(record=_no_truth))
    error_percent: float | None = field(default=None, metadata=stored(record=_no_truth))
    dof: float = field(default=math.inf, metadata=stored(store=False))
    #: the physical size the robot's bodies give the combination
    #: (:mod:`ident_hw.identification.physical_size`; None: not known, the %σ alone judges it)
    size: float | None = field(default=None, metadata=stored(NONE))

    @property
    def interval_95(self) -> float:
        """Half-width of the 95 % interval, ``k sigma``."""
        return float(coverage_factor(self.dof)) * self.sigma

    @property
    def error_sigmas(self) -> float | None:
        """(identified - truth) / sigma (None without a truth or a sigma)."""
        return error_sigmas(self.identified, self.truth, self.sigma)


def _num(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


@dataclass(frozen=True)
class ParameterTable:
    """One row per parameter (n of them), arrays of shape (n,).

    ``sigma`` is NaN where no standard deviation is known; ``truth`` is None outside simulation;
    ``step`` names the identification step that estimated the parameter ("" = held at ``initial``);
    ``units`` the SI unit of each (the model's ``parameter_unit``).
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    initial: np.ndarray
    identified: np.ndarray
    sigma: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    step: tuple[str, ...]
    method: tuple[str, ...]
    truth: np.ndarray | None = None

    def rows(self, threshold: float = POORLY_IDENTIFIED_PERCENT) -> list[ParameterRow]:
        """The table's rows; ``threshold``: the %σ above which a fitted parameter is poorly identified."""
        out = []
        for i, name in enumerate(self.names):
            ident, sigma = float(self.identified[i]), float(self.sigma[i])
            rel = 100.0 * sigma / abs(ident) if ident and math.isfinite(sigma) else None
            truth = None if self.truth is None else float(self.truth[i])
            out.append(ParameterRow(
                name=name, unit=self.units[i], initial=float(self.initial[i]), identified=ident,
                sigma=sigma if math.isfinite(sigma) else None, rel_sigma_percent=rel,
                bounds=(_num(self.lower[i]), _num(self.upper[i])), step=self.step[i], method=self.method[i],
                well_identified=bool(self.step[i]) and _well_identified(rel, threshold),
                truth=truth, error_percent=None if truth is None else _error_percent(ident, truth)))
        return out

    @classmethod
    def from_rows(cls, rows: Sequence[ParameterRow]) -> ParameterTable:
        """The table of stored rows (a bound of None is unbounded; a truth only where every row has one)."""
        def col(values) -> np.ndarray:
            return np.array([math.nan if v is None else v for v in values], dtype=float)
        has_truth = bool(rows) and all(r.truth is not None for r in rows)
        return cls(names=tuple(r.name for r in rows), units=tuple(r.unit for r in rows),
                   initial=col(r.initial for r in rows), identified=col(r.identified for r in rows),
                   sigma=col(r.sigma for r in rows),
                   lower=np.array([-np.inf if r.bounds[0] is None else r.bounds[0] for r in rows], dtype=float),
                   upper=np.array([np.inf if r.bounds[1] is None else r.bounds[1] for r in rows], dtype=float),
                   step=tuple(r.step for r in rows), method=tuple(r.method for r in rows),
                   truth=col(r.truth for r in rows) if has_truth else None)


@dataclass(frozen=True)
class BaseFit:
    """Least-squares estimate of base parameters (the SVD-DLS paper) with statistics (the power-model paper).

    ``r`` base parameters ``pi_b = H pi`` of the ``n`` physical ones: ``expressions`` (r,) read
    them (e.g. ``"m_c + 0.5 m_l2"``); ``coef``, ``sigma`` (r,) estimate and standard deviation;
    ``initial``, ``truth`` (r,) the same combinations of the CAD and true values (truth None
    outside simulation). ``held``: physical parameters held at known values during the fit;
    ``unexcited``: free ones the data says nothing of. ``size`` (r,): the physical size of each
    combination (:mod:`ident_hw.identification.physical_size`), or None. A base parameter whose
    σ exceeds ``threshold`` % of its size (of its estimate's magnitude where that is larger, or
    without a size) is poorly identified on its data (:attr:`well_identified_mask`).
    """

    step: str
    method: str
    trajectories: tuple[str, ...]
    expressions: tuple[str, ...]
    H: np.ndarray
    coef: np.ndarray
    sigma: np.ndarray
    initial: np.ndarray
    truth: np.ndarray | None
    held: tuple[str, ...]
    unexcited: tuple[str, ...]
    threshold: float
    #: (r, r) covariance of ``coef``, for the consistent step of the same run (not stored: None
    #: when read back from a results folder)
    covariance: np.ndarray | None = None
    size: np.ndarray | None = None

    @property
    def rel_sigma_percent(self) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return 100.0 * self.sigma / np.abs(self.coef)

    @property
    def well_identified_mask(self) -> np.ndarray:
        """(r,) bool: σ at most ``threshold`` % of ``max(|coef|, size)``
        (:func:`~ident_hw.identification.physical_size.well_identified`)."""
        return well_identified(self.coef, self.sigma, self.size, self.threshold)

    def rows(self) -> list[BaseRow]:
        """The rows, their ``dof`` infinite: the degrees of freedom of each σ follow from the base
        step's record of encoder draws, which :meth:`Results.base_rows` reads (use it for intervals)."""
        out = []
        for i, expr in enumerate(self.expressions):
            rel = float(self.rel_sigma_percent[i])
            truth = None if self.truth is None else float(self.truth[i])
            out.append(BaseRow(
                base_parameter=expr, initial=float(self.initial[i]), identified=float(self.coef[i]),
                sigma=float(self.sigma[i]), rel_sigma_percent=rel if math.isfinite(rel) else None,
                well_identified=bool(self.well_identified_mask[i]), truth=truth,
                error_percent=None if truth is None else _error_percent(float(self.coef[i]), truth),
                size=None if self.size is None else float(self.size[i])))
        return out


@dataclass(frozen=True)
class TrajectoryFit:
    """Measured and model forces along one trajectory (SI, after filtering/decimation).

    Attributes:
        name: trajectory name; role: ``"identification"`` or ``"validation"``.
        t: (N,) s; tau, tau_model: (N, a) N·m / N; Theta: (N, a) rad / m;
        X: (N, pose size) the poses, or None.
        tau_base: (N, a) the forces the base-parameter fit (:class:`BaseFit`) predicts, or None.
        moving: (N, a) bool, the rows of each axis the fits use (an axis near rest gives none,
            ``identification.min_speed``), or None (every row).
        tau_compared: (N, a) the forces a parameter set from elsewhere predicts
            (``identification.compare_with``), in the same measure, or None.
        at_rest: (N, a) bool, the rows where the actuator is at rest (slower than its friction
            model's rest speed), or None: not known.
        tau_consistent: (N, a) the forces of the physically consistent parameters
            (:class:`~ident_hw.identification.physical.ConsistentSet`), or None: none.
    """

    name: str
    role: str
    t: np.ndarray
    tau: np.ndarray
    tau_model: np.ndarray
    Theta: np.ndarray
    X: np.ndarray | None = None
    tau_base: np.ndarray | None = None
    moving: np.ndarray | None = None
    tau_compared: np.ndarray | None = None
    at_rest: np.ndarray | None = None
    tau_consistent: np.ndarray | None = None

    #: the arrays a fit's file holds (those that are not None)
    ARRAYS = ("t", "tau", "tau_model", "Theta", "X", "tau_base", "moving", "tau_compared", "at_rest",
              "tau_consistent")

    @property
    def tau_fit(self) -> np.ndarray:
        """(N, a) the identified prediction: the base-parameter fit's, else the step-by-step values'."""
        return self.tau_base if self.tau_base is not None else self.tau_model

    def used(self) -> np.ndarray:
        """(N, a) bool: :attr:`moving`, every row where it is None."""
        return np.ones(self.tau.shape, bool) if self.moving is None else self.moving


@dataclass(frozen=True)
class OnlineTrace:
    """Estimates of an online run (:mod:`ident_hw.experiment.campaign_estimator`); how each
    estimator did is :func:`ident_hw.results.figures.estimator_summaries`.

    Attributes:
        names: (n,) parameter names. t: (M,) campaign time of each sample, s.
        estimates: per estimator (the first is SVD-DLS), (M, n) in the units of ``names``.
        rank: (M,) excited directions of SVD-DLS after each sample (None: not recorded).
        j_rmse: per estimator, RMS a-priori prediction error over the campaign, in units of the
            output noise (``identification.online.output_noise``).
        base_names, H: the base parameters of the data, ``pi_b = H @ pi`` (b, n).
        truth: (M, n) the simulated truth at each sample (None on hardware).
        change_time: campaign time of the payload change (s), None without one.
        unexcited: the directions SVD-DLS holds at the end, readable.
        diverged: per estimator that failed numerically, the campaign time (s) it stopped at.
    """

    names: tuple[str, ...]
    t: np.ndarray
    estimates: Mapping[str, np.ndarray]
    rank: np.ndarray | None = None
    j_rmse: Mapping[str, float] = field(default_factory=dict)
    base_names: tuple[str, ...] = ()
    H: np.ndarray | None = None
    truth: np.ndarray | None = None
    change_time: float | None = None
    unexcited: tuple[str, ...] = ()
    diverged: Mapping[str, float] = field(default_factory=dict)

    def base(self, estimates: np.ndarray) -> np.ndarray:
        """(M, b) the base parameters of ``estimates`` (M, n)."""
        if self.H is None:
            raise ValueError("the trace holds no base parameters (H)")
        return estimates @ self.H.T


@dataclass(frozen=True)
class Results:
    """Everything a results folder records about one campaign, built once (a result with one more
    part is a new one: :func:`dataclasses.replace`)."""

    parameters: ParameterTable
    #: the robot's actuators in the order of every (N, n) array: names and kinds (``revolute``, ``prismatic``)
    actuators: tuple[str, ...]
    actuator_kinds: tuple[str, ...]
    fits: tuple[TrajectoryFit, ...] = ()
    #: what each identification step did, in their order
    steps: tuple[StepRecord, ...] = ()
    #: what all the identification data determine (rank, readable base parameters), stored under
    #: ``base_parameters``; None: not analysed. Not an estimate: that is ``base_fit``
    base_analysis: BaseAnalysis | None = None
    online: OnlineTrace | None = None
    #: the estimates of the base parameters of the least-squares step; None: no such step
    base_fit: BaseFit | None = None
    rel_sigma_threshold: float = POORLY_IDENTIFIED_PERCENT
    #: per trajectory: what its recording covered and what the fit used
    #: (:func:`ident_hw.experiment.preparation.coverage`)
    trajectories: Mapping[str, RecordingCoverage] = field(default_factory=dict)
    #: the quality verdict (:func:`ident_hw.experiment.quality.verdict`); None: not judged
    quality: Verdict | None = None
    #: the dynamic, power and energy models side by side (``identification.compare_models``); None: not asked
    model_comparison: ModelComparison | None = None
    #: the physically consistent parameters of the base fit (``identification.physical``); None: none made
    consistent: ConsistentSet | None = None
    #: the label of the parameter set from elsewhere whose predictions the fits hold
    #: (``identification.compare_with``); None: none
    compared_label: str | None = None
    #: the friction model identified with, where it is not the default Coulomb and viscous terms
    #: (:class:`ident_hw.records.FrictionChoice`); None: the default
    friction: FrictionChoice | None = None

    @property
    def force_units(self) -> tuple[str, ...]:
        """SI unit of each actuator's force (N·m, N)."""
        return tuple(FORCE_UNITS[k] for k in self.actuator_kinds)

    @property
    def position_units(self) -> tuple[str, ...]:
        """SI unit of each actuator's position (rad, m)."""
        return tuple(POSITION_UNITS[k] for k in self.actuator_kinds)

    @property
    def passed(self) -> bool:
        """The quality verdict passed, or there is none."""
        return self.quality is None or self.quality.passed

    @property
    def stepwise_label(self) -> str:
        """What the step-by-step prediction (``TrajectoryFit.tau_model``) is made of, as the
        terminal, the report and the plots name it: ``step by step`` (the parameters the mass-fit
        steps fitted, the others held), or ``CAD values`` when no step fitted a physical parameter
        (only base parameters were fitted: the prediction is the CAD model's, not a result)."""
        return "step by step" if any(r.fitted for r in self.parameter_rows()) else "CAD values"

    def parameter_rows(self) -> list[ParameterRow]:
        """The physical parameters, judged by this campaign's %σ threshold, each σ with its
        degrees of freedom from the step that fitted it (``_draws_dof``)."""
        records = {s.name: s for s in self.steps}
        return [replace(r, dof=_draws_dof(records.get(r.step), r.sigma, r.name)) if r.fitted else r
                for r in self.parameters.rows(self.rel_sigma_threshold)]

    def base_rows(self) -> list[BaseRow]:
        """The base fit's rows (none without one), each σ with its degrees of freedom from the
        encoder draws of the base step's record."""
        if self.base_fit is None:
            return []
        record = next((s for s in self.steps if s.name == self.base_fit.step), None)
        rows = self.base_fit.rows()
        if not isinstance(record, BaseStep) or len(record.encoder_sigma) != len(rows):
            return rows
        dof = effective_dof(self.base_fit.sigma, np.array(record.encoder_sigma), record.encoder_draws)
        return [replace(r, dof=float(d)) for r, d in zip(rows, dof)]


def _draws_dof(record: StepRecord | None, sigma: float | None, name: str) -> float:
    """The effective degrees of freedom of ``sigma``, the σ of parameter ``name`` of a mass-fit
    step (``record``): its encoder draws' part (``record.encoder_sigma``, in ``record.free``'s
    order) is a sample of ``record.encoder_draws``; the rest (least squares, held values) is
    counted exact. inf without draws."""
    if (not isinstance(record, MassFitStep) or sigma is None or name not in record.free
            or len(record.encoder_sigma) != len(record.free)):
        return math.inf
    return float(effective_dof(sigma, record.encoder_sigma[record.free.index(name)], record.encoder_draws))
