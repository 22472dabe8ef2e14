"""The results of a campaign as typed objects, and the results folder that stores them.

A results folder holds::

    STATUS               "running", "identifying", then "complete" (the quality verdict passed),
                         "degraded: <reasons>" (it did not), "partial: <why>" after a fault or a
                         signal, "failed: <why>" when nothing could be identified
    config.yaml          the config used, with every ``extends:`` merged in
    parameters.json/.yaml  Table-1-like rows: initial, identified, truth, sigma, %sigma, bounds, step;
                         the base-parameter least-squares fit (``base_fit``) when a step made one;
                         ``steps``: what each step did; ``base_parameters``: the rank and base
                         parameters of all the identification data (an analysis, not a fit);
                         ``trajectories``: what each recording covered and how much of it the fit
                         used; ``quality``: the verdict, its figures, thresholds and reasons
                         (these four: the records of :mod:`ident_hw.records`);
                         ``model_comparison`` (only with ``identification.compare_models``): the
                         base parameters of the dynamic, power and energy models
    fits/<name>.npz      measured and model forces along each trajectory (t, tau, tau_model, Theta, X,
                         tau_base = the base fit's prediction)
    online.npz           estimates over time of an online run (optional)
    data/                the recordings (raw CAN log + decoded samples), written by the runner

:func:`save_results` writes these files and :func:`load_results` reads them back;
:mod:`ident_hw.report` renders them (tables, plots, HTML, MATLAB export) from the folder alone.
The runner, :func:`ident_hw.experiment.identify` and the report share these classes.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import yaml

from ident_hw.identification.intervals import coverage_factor, effective_dof
from ident_hw.identification.least_squares import POORLY_IDENTIFIED_PERCENT
from ident_hw.identification.metrics import validation_metrics
from ident_hw.identification.model_comparison import ModelComparison
from ident_hw.identification.physical import ConsistentSet
from ident_hw.model import ThreePRRR
from ident_hw.model.interface import FORCE_UNITS, POSITION_UNITS
from ident_hw.records import (BaseAnalysis, FrictionChoice, PredictionMetrics, RecordingCoverage, StepRecord, TrajectoryMetrics,
                              Verdict)

STATUS_FILE = "STATUS"
#: an online estimate has settled when it stays within this fraction of the true value
SETTLED = 0.02


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


@dataclass(frozen=True)
class ParameterRow:
    """One physical parameter of the results table (SI unit from the robot model).

    ``step`` names the identification step that estimated it ("" = held at ``initial``);
    ``truth``/``error_percent`` exist in simulation only; ``well_identified``: fitted with a %σ
    at most the campaign's threshold. ``dof``: the effective degrees of freedom of ``sigma``
    (:mod:`ident_hw.identification.intervals`; inf: the normal interval), which
    :attr:`interval_95` follows.
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
    well_identified: bool
    truth: float | None = None
    error_percent: float | None = None
    dof: float = math.inf

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

    def to_json(self) -> dict:
        doc = {"name": self.name, "unit": self.unit, "initial": self.initial, "identified": self.identified,
               "sigma": self.sigma, "rel_sigma_percent": self.rel_sigma_percent, "bounds": list(self.bounds),
               "step": self.step, "method": self.method}
        if self.truth is not None:
            doc.update(truth=self.truth, error_percent=self.error_percent)
        return doc


@dataclass(frozen=True)
class BaseRow:
    """One base parameter of a :class:`BaseFit`: a readable combination ``expression`` of the
    physical parameters, its estimate and statistics (``truth``/``error_percent`` in simulation;
    ``dof`` as :class:`ParameterRow`'s)."""

    expression: str
    initial: float
    identified: float
    sigma: float
    rel_sigma_percent: float | None
    well_identified: bool
    truth: float | None = None
    error_percent: float | None = None
    dof: float = math.inf

    @property
    def interval_95(self) -> float:
        """Half-width of the 95 % interval, ``k sigma``."""
        return float(coverage_factor(self.dof)) * self.sigma

    @property
    def error_sigmas(self) -> float | None:
        """(identified - truth) / sigma (None without a truth or a sigma)."""
        return error_sigmas(self.identified, self.truth, self.sigma)

    def to_json(self) -> dict:
        doc = {"base_parameter": self.expression, "initial": self.initial, "identified": self.identified,
               "sigma": self.sigma, "rel_sigma_percent": self.rel_sigma_percent,
               "well_identified": self.well_identified}
        if self.truth is not None:
            doc.update(truth=self.truth, error_percent=self.error_percent)
        return doc


@dataclass(frozen=True)
class EstimatorSummary:
    """How one online estimator did over a campaign (:meth:`OnlineTrace.comparison`).

    ``j_rmse``: RMS a-priori prediction error in units of the output noise; ``diverged_at``: campaign
    time (s) it failed numerically, None if it did not; ``settling``: per tracked base parameter,
    s from the payload change until it stays within :data:`SETTLED` of its new truth (None: never).
    """

    label: str
    j_rmse: float
    diverged_at: float | None
    settling: tuple[tuple[str, float | None], ...]


@dataclass
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
    def from_rows(cls, rows: list[dict]) -> ParameterTable:
        def col(key, default=math.nan):
            return np.array([default if r.get(key) is None else r[key] for r in rows], dtype=float)
        has_truth = all("truth" in r for r in rows)
        return cls(names=tuple(r["name"] for r in rows), units=tuple(r["unit"] for r in rows), initial=col("initial"), identified=col("identified"),
                   sigma=col("sigma"), lower=np.array([_num_in(r["bounds"][0], -np.inf) for r in rows]),
                   upper=np.array([_num_in(r["bounds"][1], np.inf) for r in rows]),
                   step=tuple(r["step"] for r in rows), method=tuple(r["method"] for r in rows),
                   truth=col("truth") if has_truth else None)


@dataclass
class BaseFit:
    """Least-squares estimate of base parameters (the SVD-DLS paper) with statistics (the power-model paper).

    ``r`` base parameters ``pi_b = H pi`` of the ``n`` physical ones: ``expressions`` (r,) read
    them (e.g. ``"m_c + 0.5 m_l2"``); ``coef``, ``sigma`` (r,) estimate and standard deviation;
    ``initial``, ``truth`` (r,) the same combinations of the CAD and true values (truth None
    outside simulation). ``held``: physical parameters held at known values during the fit;
    ``unexcited``: free ones the data says nothing of. A base parameter whose %σ exceeds
    ``threshold`` is poorly identified on its data (:attr:`well_identified_mask`).
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

    @property
    def rel_sigma_percent(self) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return 100.0 * self.sigma / np.abs(self.coef)

    @property
    def well_identified_mask(self) -> np.ndarray:
        """(r,) bool: %σ at most ``threshold`` (the estimates themselves are :attr:`coef`)."""
        return self.rel_sigma_percent <= self.threshold

    def rows(self) -> list[BaseRow]:
        """The rows, their ``dof`` infinite: the degrees of freedom of each σ follow from the base
        step's record of encoder draws, which :meth:`Results.base_rows` reads (use it for intervals)."""
        out = []
        for i, expr in enumerate(self.expressions):
            rel = float(self.rel_sigma_percent[i])
            truth = None if self.truth is None else float(self.truth[i])
            out.append(BaseRow(
                expression=expr, initial=float(self.initial[i]), identified=float(self.coef[i]),
                sigma=float(self.sigma[i]), rel_sigma_percent=rel if math.isfinite(rel) else None,
                well_identified=bool(self.well_identified_mask[i]), truth=truth,
                error_percent=None if truth is None else _error_percent(float(self.coef[i]), truth)))
        return out

    def to_dict(self) -> dict:
        return {"step": self.step, "method": self.method, "trajectories": list(self.trajectories),
                "threshold_rel_sigma_percent": self.threshold, "held": list(self.held),
                "unexcited": list(self.unexcited), "H": self.H.tolist(),
                "rows": [r.to_json() for r in self.rows()]}

    @classmethod
    def from_dict(cls, doc: dict) -> BaseFit:
        rows = doc["rows"]
        def col(key):
            return np.array([math.nan if r.get(key) is None else r[key] for r in rows], dtype=float)
        has_truth = all("truth" in r for r in rows)
        return cls(step=doc["step"], method=doc["method"], trajectories=tuple(doc["trajectories"]),
                   expressions=tuple(r["base_parameter"] for r in rows), H=np.array(doc["H"], dtype=float),
                   coef=col("identified"), sigma=col("sigma"), initial=col("initial"),
                   truth=col("truth") if has_truth else None, held=tuple(doc["held"]),
                   unexcited=tuple(doc["unexcited"]), threshold=float(doc["threshold_rel_sigma_percent"]))


@dataclass
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

    def save(self, path: Path) -> None:
        arrays = {k: getattr(self, k) for k in self.ARRAYS if getattr(self, k) is not None}
        np.savez_compressed(path, name=self.name, role=self.role, **arrays)

    @classmethod
    def load(cls, path: Path) -> TrajectoryFit:
        with np.load(path) as f:
            return cls(name=str(f["name"]), role=str(f["role"]),
                       **{k: (f[k] if k in f else None) for k in cls.ARRAYS})


@dataclass
class OnlineTrace:
    """Estimates of an online run (:mod:`ident_hw.experiment.campaign_estimator`).

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
    estimates: dict[str, np.ndarray]
    rank: np.ndarray | None = None
    j_rmse: dict[str, float] = field(default_factory=dict)
    base_names: tuple[str, ...] = ()
    H: np.ndarray | None = None
    truth: np.ndarray | None = None
    change_time: float | None = None
    unexcited: tuple[str, ...] = ()
    diverged: dict[str, float] = field(default_factory=dict)

    def base(self, estimates: np.ndarray) -> np.ndarray:
        """(M, b) the base parameters of ``estimates`` (M, n)."""
        return estimates @ self.H.T

    def tracked(self) -> list[int]:
        """The base parameters whose truth changes at the payload change."""
        if self.truth is None or self.change_time is None or self.H is None:
            return []
        b = self.base(self.truth)
        return [i for i in range(b.shape[1]) if np.ptp(b[:, i]) > 1e-12 * max(np.abs(b[:, i]).max(), 1e-300)]

    def settling_time(self, estimator: str, i: int) -> float | None:
        """s from the payload change until base parameter ``i`` of ``estimator`` stays within
        :data:`SETTLED` of its new true value (None: it does not, by the end)."""
        after = self.t >= self.change_time
        est = self.base(self.estimates[estimator])[after, i]
        true = self.base(self.truth)[after, i]
        off = ~(np.abs(est - true) <= SETTLED * np.abs(true))      # NaN (a diverged estimator) is off
        if not len(off) or off[-1]:
            return None
        last_off = np.nonzero(off)[0]
        k = last_off[-1] + 1 if len(last_off) else 0
        return float(self.t[after][k] - self.change_time)

    def comparison(self) -> list[EstimatorSummary]:
        """Per estimator (SVD-DLS first): J_RMSE, divergence and the settling of each tracked
        base parameter after the payload change."""
        tracked = self.tracked()
        return [EstimatorSummary(label, self.j_rmse.get(label, math.nan), self.diverged.get(label),
                                 tuple((self.base_names[i], self.settling_time(label, i)) for i in tracked))
                for label in self.estimates]

    def save(self, path: Path) -> None:
        labels = list(self.estimates)
        arrays = {f"estimates_{i}": self.estimates[k] for i, k in enumerate(labels)}
        np.savez_compressed(path, names=np.array(self.names), t=self.t, estimators=np.array(labels),
                            j_rmse=np.array([self.j_rmse.get(k, np.nan) for k in labels]),
                            rank=self.rank if self.rank is not None else np.zeros(0),
                            base_names=np.array(self.base_names), H=self.H if self.H is not None else np.zeros((0, 0)),
                            truth=self.truth if self.truth is not None else np.zeros((0, 0)),
                            change_time=np.nan if self.change_time is None else self.change_time,
                            unexcited=np.array(self.unexcited),
                            diverged=np.array([self.diverged.get(k, np.nan) for k in labels]), **arrays)

    @classmethod
    def load(cls, path: Path) -> "OnlineTrace":
        with np.load(path) as f:
            names = tuple(str(n) for n in f["names"])
            if "estimators" not in f:                  # written before the baselines were traced
                return cls(names, f["t"], {"SVD-DLS": f["estimates"]})
            labels = [str(k) for k in f["estimators"]]
            change = float(f["change_time"])
            return cls(names, f["t"], {k: f[f"estimates_{i}"] for i, k in enumerate(labels)},
                       rank=f["rank"] if f["rank"].size else None,
                       j_rmse=dict(zip(labels, (float(v) for v in f["j_rmse"]))),
                       base_names=tuple(str(n) for n in f["base_names"]), H=f["H"] if f["H"].size else None,
                       truth=f["truth"] if f["truth"].size else None,
                       change_time=None if np.isnan(change) else change,
                       unexcited=tuple(str(u) for u in f["unexcited"]),
                       diverged={k: float(v) for k, v in zip(labels, f["diverged"]) if not np.isnan(v)})


@dataclass
class Results:
    """Everything a results folder records about one campaign."""

    parameters: ParameterTable
    #: the robot's actuators in the order of every (N, n) array: names and kinds (``revolute``, ``prismatic``)
    actuators: tuple[str, ...]
    actuator_kinds: tuple[str, ...]
    fits: list[TrajectoryFit] = field(default_factory=list)
    #: what each identification step did, in their order
    steps: list[StepRecord] = field(default_factory=list)
    #: what all the identification data determine (rank, readable base parameters), stored under
    #: ``base_parameters``; None: not analysed. Not an estimate: that is ``base_fit``
    base_analysis: BaseAnalysis | None = None
    online: OnlineTrace | None = None
    #: the estimates of the base parameters of the least-squares step; None: no such step
    base_fit: BaseFit | None = None
    rel_sigma_threshold: float = POORLY_IDENTIFIED_PERCENT
    #: per trajectory: what its recording covered and what the fit used (``offline.coverage``)
    trajectories: dict[str, RecordingCoverage] = field(default_factory=dict)
    #: the quality verdict (``ident_hw.experiment.quality.verdict``); None: not judged
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
        """What the step-by-step prediction (:attr:`TrajectoryFit.tau_model`) is made of, as the
        terminal, the report and the plots name it: ``step by step`` (the parameters the mass-fit
        steps fitted, the others held), or ``CAD values`` when no step fitted a physical parameter
        (only base parameters were fitted: the prediction is the CAD model's, not a result)."""
        return "step by step" if any(r.fitted for r in self.parameter_rows()) else "CAD values"

    def parameter_rows(self) -> list[ParameterRow]:
        """The physical parameters, judged by this campaign's %σ threshold, each σ with its
        degrees of freedom from the step that fitted it (:func:`_draws_dof`)."""
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
        if record is None or len(record.encoder_sigma) != len(rows):
            return rows
        dof = effective_dof(self.base_fit.sigma, np.array(record.encoder_sigma), record.encoder_draws)
        return [replace(r, dof=float(d)) for r, d in zip(rows, dof)]


def _draws_dof(record: StepRecord | None, sigma: float | None, name: str) -> float:
    """The effective degrees of freedom of ``sigma``, the σ of parameter ``name`` of a mass-fit
    step (``record``): its encoder draws' part (``record.encoder_sigma``, in ``record.free``'s
    order) is a sample of ``record.encoder_draws``; the rest (least squares, held values) is
    counted exact. inf without draws."""
    if (record is None or record.fits_base_parameters or sigma is None or name not in record.free
            or len(record.encoder_sigma) != len(record.free)):
        return math.inf
    return float(effective_dof(sigma, record.encoder_sigma[record.free.index(name)], record.encoder_draws))


# ----------------------------------------------------------------------------- status
def write_atomically(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file renamed over it: a reader (or a run
    continued after Ctrl-C) never sees half of it."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)


def mark_status(folder: str | Path, status: str) -> None:
    """Write STATUS (see the module docstring), atomically: a reader never sees half of it."""
    write_atomically(Path(folder, STATUS_FILE), status.strip() + "\n")


def final_status(results: Results) -> str:
    """``complete`` when the quality verdict passed (or there is none), else ``degraded: <reasons>``."""
    if results.passed:
        return "complete"
    return "degraded: " + "; ".join(results.quality.reasons)


def read_status(folder: str | Path) -> str:
    path = Path(folder, STATUS_FILE)
    return path.read_text().strip() if path.is_file() else "unknown (no STATUS file)"


# ----------------------------------------------------------------------------- saving
def save_results(folder: str | Path, results: Results) -> Path:
    """Write the parameters, fits and online trace into ``folder`` (returned); the report is
    built from them by :func:`ident_hw.report.build_report`."""
    folder = Path(folder)
    (folder / "fits").mkdir(parents=True, exist_ok=True)
    doc = {"parameters": [r.to_json() for r in results.parameter_rows()], "rel_sigma_threshold_percent": results.rel_sigma_threshold,
           "base_fit": None if results.base_fit is None else results.base_fit.to_dict(),
           "steps": [s.to_json() for s in results.steps],
           "base_parameters": None if results.base_analysis is None else results.base_analysis.to_json(),
           "trajectories": {name: c.to_json() for name, c in results.trajectories.items()},
           "quality": None if results.quality is None else results.quality.to_json(),
           "actuators": [{"name": n, "kind": k} for n, k in zip(results.actuators, results.actuator_kinds)]}
    if results.model_comparison is not None:      # absent otherwise: files without it stay as they were
        doc["model_comparison"] = results.model_comparison.to_dict()
    if results.consistent is not None:
        doc["consistent"] = results.consistent.to_dict()
    figures = validation_figures(results)
    if figures:
        doc["validation"] = {name: f.to_json() for name, f in figures.items()}
    if results.compared_label is not None:
        doc["compared_with"] = results.compared_label
    if results.friction is not None:
        doc["friction"] = results.friction.to_json()
    (folder / "parameters.json").write_text(json.dumps(doc, indent=2, default=_jsonable))
    (folder / "parameters.yaml").write_text(yaml.safe_dump(json.loads(json.dumps(doc, default=_jsonable)),
                                                           sort_keys=False))
    for fit in results.fits:
        fit.save(folder / "fits" / f"{fit.name}.npz")
    if results.online is not None:
        results.online.save(folder / "online.npz")
    return folder


def load_results(folder: str | Path) -> Results:
    """Read back what :func:`save_results` wrote."""
    folder = Path(folder)
    path = folder / "parameters.json"
    if not path.is_file():
        raise FileNotFoundError(f"{folder} is not a results folder: no parameters.json")
    doc = json.loads(path.read_text())
    fits = [TrajectoryFit.load(p) for p in sorted((folder / "fits").glob("*.npz"))]
    fits.sort(key=lambda f: f.role != "identification")
    online = None
    if (folder / "online.npz").is_file():
        online = OnlineTrace.load(folder / "online.npz")
    base_fit = BaseFit.from_dict(doc["base_fit"]) if doc.get("base_fit") else None
    # a folder written before the actuators were recorded holds the 3PRRR, the only robot then
    actuators = doc.get("actuators") or [{"name": n, "kind": k}
                                         for n, k in zip(ThreePRRR.actuator_names, ThreePRRR.actuator_kinds)]
    return Results(actuators=tuple(a["name"] for a in actuators), actuator_kinds=tuple(a["kind"] for a in actuators),
                   parameters=ParameterTable.from_rows(doc["parameters"]), fits=fits,
                   steps=[StepRecord.from_json(s) for s in doc.get("steps") or []],
                   base_analysis=BaseAnalysis.from_json(doc["base_parameters"]) if doc.get("base_parameters") else None,
                   online=online, base_fit=base_fit,
                   rel_sigma_threshold=doc.get("rel_sigma_threshold_percent", POORLY_IDENTIFIED_PERCENT),
                   trajectories={name: RecordingCoverage.from_json(c)
                                 for name, c in (doc.get("trajectories") or {}).items()},
                   quality=Verdict.from_json(doc["quality"]) if doc.get("quality") else None,
                   model_comparison=ModelComparison.from_dict(doc["model_comparison"]) if doc.get("model_comparison")
                   else None,
                   consistent=ConsistentSet.from_dict(doc["consistent"]) if doc.get("consistent") else None,
                   compared_label=doc.get("compared_with"),
                   friction=FrictionChoice.from_json(doc["friction"]) if doc.get("friction") else None)


# ----------------------------------------------------------------------------- figures
def metrics(results: Results) -> dict[str, TrajectoryMetrics]:
    """Per trajectory: the force prediction of the step-by-step parameters and of the
    base-parameter fit."""
    return {fit.name: TrajectoryMetrics(
        role=fit.role, samples=int(len(fit.t)), stepwise=_metrics(results.actuators, fit.tau, fit.tau_model),
        base_fit=None if fit.tau_base is None else _metrics(results.actuators, fit.tau, fit.tau_base))
        for fit in results.fits}


def relative_residual_percent(tau: np.ndarray, predicted: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """(a,) per actuator ``rre = 100 ||tau - predicted|| / ||tau||`` over the rows (N,) or (N, a)
    bool ``rows`` (all: None), the measure of the UR10e dataset's authors: for the whole
    trajectory it is the ``nrms_percent`` of :func:`ident_hw.identification.metrics.validation_metrics`.
    NaN where no row is left or the forces there are all 0."""
    tau, predicted = np.asarray(tau, dtype=float), np.asarray(predicted, dtype=float)
    mask = np.ones(tau.shape, dtype=bool) if rows is None else np.broadcast_to(
        np.asarray(rows, dtype=bool).reshape(len(tau), -1), tau.shape)
    error = np.sqrt(np.sum(np.where(mask, (tau - predicted) ** 2, 0.0), axis=0))
    size = np.sqrt(np.sum(np.where(mask, tau ** 2, 0.0), axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(size > 0, 100.0 * error / size, np.nan)


@dataclass(frozen=True)
class ValidationFigures:
    """The force prediction on one validation trajectory, per actuator (in actuator order), as
    the UR10e dataset's authors measure it (:func:`relative_residual_percent`): ``rre_fit`` of
    the identified parameters (:attr:`TrajectoryFit.tau_fit`), ``rre_compared`` of the set from
    elsewhere (None: none); each also over the rows where the actuator moves and where it is at
    rest (``*_moving``, ``*_at_rest``); ``at_rest_fraction`` of the rows; ``residual_at_rest``: the
    share (%) of each prediction's squared residual that the rows at rest hold: where what is
    left comes from."""

    trajectory: str
    rre_fit: tuple[float, ...]
    rre_compared: tuple[float, ...] | None = None
    rre_fit_moving: tuple[float, ...] | None = None
    rre_fit_at_rest: tuple[float, ...] | None = None
    rre_compared_moving: tuple[float, ...] | None = None
    rre_compared_at_rest: tuple[float, ...] | None = None
    at_rest_fraction: tuple[float, ...] | None = None
    residual_at_rest_fit: tuple[float, ...] | None = None
    residual_at_rest_compared: tuple[float, ...] | None = None

    @classmethod
    def of(cls, fit: TrajectoryFit) -> ValidationFigures:
        """The figures of one fitted trajectory."""
        def figures(prediction):
            if prediction is None:
                return None, None, None, None
            whole = relative_residual_percent(fit.tau, prediction)
            if fit.at_rest is None:
                return whole, None, None, None
            squared = (fit.tau - prediction) ** 2
            with np.errstate(invalid="ignore", divide="ignore"):
                share = 100.0 * np.sum(np.where(fit.at_rest, squared, 0.0), axis=0) / np.sum(squared, axis=0)
            return (whole, relative_residual_percent(fit.tau, prediction, ~fit.at_rest),
                    relative_residual_percent(fit.tau, prediction, fit.at_rest), share)

        def row(values):
            return None if values is None else tuple(float(v) for v in values)
        own, compared = figures(fit.tau_fit), figures(fit.tau_compared)
        rest = None if fit.at_rest is None or not len(fit.t) else fit.at_rest.mean(axis=0)
        return cls(trajectory=fit.name, rre_fit=row(own[0]), rre_compared=row(compared[0]),
                   rre_fit_moving=row(own[1]), rre_fit_at_rest=row(own[2]), rre_compared_moving=row(compared[1]),
                   rre_compared_at_rest=row(compared[2]), at_rest_fraction=row(rest),
                   residual_at_rest_fit=row(own[3]), residual_at_rest_compared=row(compared[3]))

    def to_json(self) -> dict:
        def pair(fit, compared):
            doc = {"fit": _numbers(fit)}
            if compared is not None:
                doc["compared"] = _numbers(compared)
            return doc
        doc = {"rre_percent": pair(self.rre_fit, self.rre_compared)}
        if self.rre_fit_moving is not None:
            doc["rre_moving_percent"] = pair(self.rre_fit_moving, self.rre_compared_moving)
            doc["rre_at_rest_percent"] = pair(self.rre_fit_at_rest, self.rre_compared_at_rest)
            doc["residual_share_at_rest_percent"] = pair(self.residual_at_rest_fit, self.residual_at_rest_compared)
            doc["at_rest_fraction"] = _numbers(self.at_rest_fraction)
        return doc


def validation_figures(results: Results) -> dict[str, ValidationFigures]:
    """:class:`ValidationFigures` of every validation trajectory, by name."""
    return {fit.name: ValidationFigures.of(fit) for fit in results.fits if fit.role == "validation"}


def _numbers(values) -> list[float | None] | None:
    """A row of figures for JSON: NaN as null."""
    return None if values is None else [v if math.isfinite(v) else None for v in values]


def _metrics(actuators: tuple[str, ...], tau: np.ndarray, tau_model: np.ndarray) -> PredictionMetrics:
    if not len(tau):                # nothing of the trajectory could be fitted (the verdict says why)
        nan = dict.fromkeys(actuators, float("nan"))
        return PredictionMetrics(rms=nan, nrms_percent=dict(nan), d_tau_percent=float("nan"), j_rmse=float("nan"))
    m = validation_metrics(tau, tau_model)
    return PredictionMetrics(rms=dict(zip(actuators, m.rms.tolist())),
                             nrms_percent=dict(zip(actuators, m.nrms_percent.tolist())),
                             d_tau_percent=m.d_tau_percent, j_rmse=m.j_rmse)



def _num(value) -> float | None:
    return float(value) if math.isfinite(value) else None


def _num_in(value, default: float) -> float:
    return default if value is None else float(value)


def _jsonable(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot store {type(obj).__name__} in parameters.json")
