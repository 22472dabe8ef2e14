"""The results folder: what :func:`save_results` writes and :func:`load_results` reads back.

A results folder holds::

    STATUS               one line: where its run is (:mod:`ident_hw.results.status`)
    config.yaml          the config used, with every ``extends:`` merged in
    parameters.json/.yaml  :class:`ResultsFile`: the physical parameters' rows (initial, identified,
                         truth, sigma, %sigma, bounds, step); ``base_fit``: the base-parameter
                         least-squares fit when a step made one; ``steps``: what each step did;
                         ``base_parameters``: the rank and base parameters of all the identification
                         data (an analysis, not a fit); ``trajectories``: what each recording covered
                         and how much of it the fit used; ``quality``: the verdict, its figures,
                         thresholds and reasons (these four: the records of :mod:`ident_hw.records`);
                         ``model_comparison`` (only with ``identification.compare_models``): the
                         base parameters of the dynamic, power and energy models; ``consistent``:
                         the physically consistent parameters; ``validation``: each validation
                         trajectory's relative residuals (:class:`~ident_hw.results.figures.ValidationFigures`)
    fits/<name>.npz      measured and model forces along each trajectory (:class:`TrajectoryFit`'s arrays)
    online.npz           estimates over time of an online run (optional, :class:`OnlineTrace`)
    data/                the recordings (raw CAN log + decoded samples), written by the runner

Every file carries the format version (``format``, :data:`ident_hw.storage.FORMAT`); a folder of
before the version was written (format 0) reads the same. The JSON files are stored by
:mod:`ident_hw.storage`: each object below is a frozen dataclass whose fields are its keys. The
numeric results (columns of arrays) and their stored rows are converted here, and only here.
:mod:`ident_hw.report` renders a folder from these files alone.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ident_hw.identification.least_squares import POORLY_IDENTIFIED_PERCENT
from ident_hw.identification.model_comparison import EQUATIONS, OUTPUT_UNITS, ModelComparison, ModelFit
from ident_hw.identification.physical import BodyMargin, ConsistentSet
from ident_hw.model.robot import ThreePRRR
from ident_hw.records import BaseAnalysis, FrictionChoice, RecordingCoverage, StepRecord, Verdict
from ident_hw.storage import EMPTY, FORMAT, NONE, file_document, of_document, stored, write_atomically

from .figures import ValidationFigures, validation_figures
from .objects import BaseFit, BaseRow, OnlineTrace, ParameterRow, ParameterTable, Results, TrajectoryFit

PARAMETERS_FILE = "parameters.json"


# ----------------------------------------------------------------------------- the stored forms
@dataclass(frozen=True)
class BaseFitFile:
    """A :class:`BaseFit` as stored: its rows (:class:`BaseRow`) and ``H`` (r, n); the %σ above
    which a base parameter is poorly identified, ``threshold_rel_sigma_percent``."""

    step: str
    method: str
    trajectories: tuple[str, ...]
    threshold_rel_sigma_percent: float
    held: tuple[str, ...]
    unexcited: tuple[str, ...]
    H: np.ndarray
    rows: tuple[BaseRow, ...]

    @classmethod
    def of(cls, fit: BaseFit) -> BaseFitFile:
        return cls(step=fit.step, method=fit.method, trajectories=fit.trajectories,
                   threshold_rel_sigma_percent=fit.threshold, held=fit.held, unexcited=fit.unexcited, H=fit.H,
                   rows=tuple(fit.rows()))

    def fit(self) -> BaseFit:
        """The base fit (its covariance is not stored: None)."""
        def col(values) -> np.ndarray:
            return np.array([math.nan if v is None else v for v in values], dtype=float)
        has_truth = bool(self.rows) and all(r.truth is not None for r in self.rows)
        return BaseFit(step=self.step, method=self.method, trajectories=self.trajectories,
                       expressions=tuple(r.base_parameter for r in self.rows), H=np.asarray(self.H, dtype=float),
                       coef=col(r.identified for r in self.rows), sigma=col(r.sigma for r in self.rows),
                       initial=col(r.initial for r in self.rows),
                       truth=col(r.truth for r in self.rows) if has_truth else None, held=self.held,
                       unexcited=self.unexcited, threshold=float(self.threshold_rel_sigma_percent),
                       size=col(r.size for r in self.rows) if any(r.size is not None for r in self.rows) else None)


@dataclass(frozen=True)
class ConsistentRow:
    """One parameter of a :class:`ConsistentSet` as stored (``truth`` in simulation only)."""

    name: str
    unit: str
    value: float
    prior: float
    sigma: float
    prior_share: float
    decided_by: str
    truth: float | None = field(default=None, metadata=stored(NONE))


@dataclass(frozen=True)
class ConsistentFile:
    """A :class:`ConsistentSet` as stored: its figures (``chi2_limit_95``: the 95 % quantile its
    ``chi2`` is judged by; ``reproduces_base`` and ``physical`` as the set says), each body's
    margin and one row per parameter."""

    metric: str
    prior_relative_std: float
    base_count: int
    chi2: float
    chi2_limit_95: float
    reproduces_base: bool
    physical: bool
    bodies: tuple[BodyMargin, ...]
    parameters: tuple[ConsistentRow, ...]

    @classmethod
    def of(cls, c: ConsistentSet) -> ConsistentFile:
        rows = tuple(ConsistentRow(name, c.units[i], float(c.values[i]), float(c.prior[i]), float(c.sigma[i]),
                                   float(c.prior_share[i]), c.decided_by[i],
                                   None if c.truth is None else float(c.truth[i]))
                     for i, name in enumerate(c.names))
        return cls(metric=c.metric, prior_relative_std=c.prior_relative, base_count=c.base_count, chi2=c.chi2,
                   chi2_limit_95=c.chi2_limit, reproduces_base=c.reproduces_base, physical=c.physical,
                   bodies=c.bodies, parameters=rows)

    def consistent_set(self) -> ConsistentSet:
        rows = self.parameters

        def col(key: str) -> np.ndarray:
            return np.array([getattr(r, key) for r in rows], dtype=float)
        return ConsistentSet(names=tuple(r.name for r in rows), units=tuple(r.unit for r in rows),
                             values=col("value"), prior=col("prior"), sigma=col("sigma"),
                             prior_share=col("prior_share"), decided_by=tuple(r.decided_by for r in rows),
                             bodies=self.bodies, chi2=self.chi2, chi2_limit=self.chi2_limit_95,
                             base_count=self.base_count, metric=self.metric, prior_relative=self.prior_relative_std,
                             truth=col("truth") if rows and all(r.truth is not None for r in rows) else None)


def _no_model_truth(row: ComparisonRowFile) -> bool:
    return row.truth is None


@dataclass(frozen=True)
class ComparisonRowFile:
    """One base parameter of one model of a :class:`ModelComparison` as stored."""

    base_parameter: str
    estimate: float
    sigma: float
    rel_sigma_percent: float | None
    truth: float | None = field(default=None, metadata=stored(record=_no_model_truth))
    error_percent: float | None = field(default=None, metadata=stored(record=_no_model_truth))


@dataclass(frozen=True)
class ModelFitFile:
    """A :class:`ModelFit` as stored, with its model's ``equation`` and ``output_unit`` written out;
    ``cond_scaled``: its ``cond``, ``window_s``: its ``window``."""

    model: str
    equation: str
    output_unit: str
    method: str
    equations: int
    rank: int
    free: int
    cond_scaled: float
    residual_rms: float
    window_s: float | None
    H: np.ndarray
    rows: tuple[ComparisonRowFile, ...]

    @classmethod
    def of(cls, f: ModelFit) -> ModelFitFile:
        return cls(model=f.model, equation=EQUATIONS[f.model], output_unit=OUTPUT_UNITS[f.model], method=f.method,
                   equations=f.equations, rank=f.rank, free=f.free, cond_scaled=f.cond, residual_rms=f.residual_rms,
                   window_s=f.window, H=f.H,
                   rows=tuple(ComparisonRowFile(r.expression, r.estimate, r.sigma, r.rel_sigma_percent, r.truth,
                                                r.error_percent) for r in f.rows()))

    def model_fit(self) -> ModelFit:
        rows = self.rows
        has_truth = bool(rows) and all(r.truth is not None for r in rows)
        return ModelFit(model=self.model, method=self.method, expressions=tuple(r.base_parameter for r in rows),
                        H=np.asarray(self.H, dtype=float).reshape(len(rows), -1),
                        coef=np.array([r.estimate for r in rows], dtype=float),
                        sigma=np.array([r.sigma for r in rows], dtype=float),
                        truth=np.array([r.truth for r in rows], dtype=float) if has_truth else None,
                        equations=self.equations, rank=self.rank, free=self.free, cond=self.cond_scaled,
                        residual_rms=self.residual_rms, window=self.window_s)


@dataclass(frozen=True)
class ModelComparisonFile:
    """A :class:`ModelComparison` as stored (``threshold_rel_sigma_percent``: its threshold)."""

    step: str
    trajectories: tuple[str, ...]
    held: tuple[str, ...]
    threshold_rel_sigma_percent: float
    models: tuple[ModelFitFile, ...]

    @classmethod
    def of(cls, c: ModelComparison) -> ModelComparisonFile:
        return cls(step=c.step, trajectories=c.trajectories, held=c.held, threshold_rel_sigma_percent=c.threshold,
                   models=tuple(ModelFitFile.of(f) for f in c.fits))

    def comparison(self) -> ModelComparison:
        return ModelComparison(step=self.step, trajectories=self.trajectories, held=self.held,
                               fits=tuple(m.model_fit() for m in self.models),
                               threshold=self.threshold_rel_sigma_percent)


@dataclass(frozen=True)
class Actuator:
    """One actuator of the robot, in the order of every per-actuator array: its name and kind
    (``revolute``, ``prismatic``)."""

    name: str
    kind: str


@dataclass(frozen=True)
class ResultsFile:
    """``parameters.json``: everything of a :class:`Results` but the arrays of its fits and its
    online trace (see the module docstring). ``validation`` is computed from the fits when
    written, and not read back (the fits give it again)."""

    parameters: tuple[ParameterRow, ...]
    rel_sigma_threshold_percent: float = POORLY_IDENTIFIED_PERCENT
    base_fit: BaseFitFile | None = None
    steps: tuple[StepRecord, ...] = ()
    base_parameters: BaseAnalysis | None = None
    trajectories: dict[str, RecordingCoverage] = field(default_factory=dict)
    quality: Verdict | None = None
    #: none in a folder of before they were written: the 3PRRR's, the only robot then
    actuators: tuple[Actuator, ...] = ()
    model_comparison: ModelComparisonFile | None = field(default=None, metadata=stored(NONE))
    consistent: ConsistentFile | None = field(default=None, metadata=stored(NONE))
    validation: dict[str, ValidationFigures] = field(default_factory=dict, metadata=stored(EMPTY))
    compared_with: str | None = field(default=None, metadata=stored(NONE))
    friction: FrictionChoice | None = field(default=None, metadata=stored(NONE))

    @staticmethod
    def upgrade_json(doc: dict) -> dict:
        """Null lists of folders that wrote them so read as empty."""
        for key in ("steps", "trajectories", "actuators"):
            if key in doc and doc[key] is None:
                del doc[key]
        return doc

    @classmethod
    def of(cls, results: Results) -> ResultsFile:
        return cls(parameters=tuple(results.parameter_rows()),
                   rel_sigma_threshold_percent=results.rel_sigma_threshold,
                   base_fit=None if results.base_fit is None else BaseFitFile.of(results.base_fit),
                   steps=tuple(results.steps), base_parameters=results.base_analysis,
                   trajectories=dict(results.trajectories), quality=results.quality,
                   actuators=tuple(Actuator(n, k) for n, k in zip(results.actuators, results.actuator_kinds)),
                   model_comparison=(None if results.model_comparison is None
                                     else ModelComparisonFile.of(results.model_comparison)),
                   consistent=None if results.consistent is None else ConsistentFile.of(results.consistent),
                   validation=validation_figures(results), compared_with=results.compared_label,
                   friction=results.friction)

    def results(self, fits: tuple[TrajectoryFit, ...] = (), online: OnlineTrace | None = None) -> Results:
        """The results this file holds, with the arrays of their ``fits`` and ``online`` trace."""
        actuators = self.actuators or tuple(Actuator(n, k) for n, k in zip(ThreePRRR.actuator_names,
                                                                             ThreePRRR.actuator_kinds))
        return Results(parameters=ParameterTable.from_rows(self.parameters),
                       actuators=tuple(a.name for a in actuators), actuator_kinds=tuple(a.kind for a in actuators),
                       fits=fits, steps=self.steps, base_analysis=self.base_parameters, online=online,
                       base_fit=None if self.base_fit is None else self.base_fit.fit(),
                       rel_sigma_threshold=self.rel_sigma_threshold_percent, trajectories=self.trajectories,
                       quality=self.quality,
                       model_comparison=None if self.model_comparison is None else self.model_comparison.comparison(),
                       consistent=None if self.consistent is None else self.consistent.consistent_set(),
                       compared_label=self.compared_with, friction=self.friction)


# ----------------------------------------------------------------------------- the arrays
def _version(path: Path, f) -> int:
    """The format of an ``.npz`` file (0 without one); a newer one than this code's is refused."""
    version = int(f["format"]) if "format" in f else 0
    if version > FORMAT:
        raise ValueError(f"{path}: format {version}, newer than this ident_hw's ({FORMAT}): update ident_hw")
    return version


def save_fit(path: str | Path, fit: TrajectoryFit) -> None:
    """Write a :class:`TrajectoryFit` (its arrays that are not None) as ``.npz``."""
    arrays: dict[str, Any] = {k: getattr(fit, k) for k in fit.ARRAYS if getattr(fit, k) is not None}
    np.savez_compressed(path, format=FORMAT, name=fit.name, role=fit.role, **arrays)


def load_fit(path: str | Path) -> TrajectoryFit:
    """Read back what :func:`save_fit` wrote."""
    with np.load(path) as f:
        _version(Path(path), f)
        arrays: dict[str, Any] = {k: (f[k] if k in f else None) for k in TrajectoryFit.ARRAYS}
        return TrajectoryFit(name=str(f["name"]), role=str(f["role"]), **arrays)


def save_online(path: str | Path, trace: OnlineTrace) -> None:
    """Write an :class:`OnlineTrace` as ``.npz`` (an absent part as an empty array, NaN for a time)."""
    labels = list(trace.estimates)
    arrays: dict[str, Any] = {f"estimates_{i}": trace.estimates[k] for i, k in enumerate(labels)}
    np.savez_compressed(path, format=FORMAT, names=np.array(trace.names), t=trace.t, estimators=np.array(labels),
                        j_rmse=np.array([trace.j_rmse.get(k, np.nan) for k in labels]),
                        rank=trace.rank if trace.rank is not None else np.zeros(0),
                        base_names=np.array(trace.base_names), H=trace.H if trace.H is not None else np.zeros((0, 0)),
                        truth=trace.truth if trace.truth is not None else np.zeros((0, 0)),
                        change_time=np.nan if trace.change_time is None else trace.change_time,
                        unexcited=np.array(trace.unexcited),
                        diverged=np.array([trace.diverged.get(k, np.nan) for k in labels]), **arrays)


def load_online(path: str | Path) -> OnlineTrace:
    """Read back what :func:`save_online` wrote (a file of before the baselines holds SVD-DLS alone)."""
    with np.load(path) as f:
        _version(Path(path), f)
        names = tuple(str(n) for n in f["names"])
        if "estimators" not in f:                  # written before the baselines were traced
            return OnlineTrace(names, f["t"], {"SVD-DLS": f["estimates"]})
        labels = [str(k) for k in f["estimators"]]
        change = float(f["change_time"])
        return OnlineTrace(names, f["t"], {k: f[f"estimates_{i}"] for i, k in enumerate(labels)},
                           rank=f["rank"] if f["rank"].size else None,
                           j_rmse=dict(zip(labels, (float(v) for v in f["j_rmse"]))),
                           base_names=tuple(str(n) for n in f["base_names"]), H=f["H"] if f["H"].size else None,
                           truth=f["truth"] if f["truth"].size else None,
                           change_time=None if np.isnan(change) else change,
                           unexcited=tuple(str(u) for u in f["unexcited"]),
                           diverged={k: float(v) for k, v in zip(labels, f["diverged"]) if not np.isnan(v)})


# ----------------------------------------------------------------------------- the folder
def save_results(folder: str | Path, results: Results) -> Path:
    """Write the parameters, fits and online trace into ``folder`` (returned); the report is
    built from them by :func:`ident_hw.report.build_report`."""
    folder = Path(folder)
    (folder / "fits").mkdir(parents=True, exist_ok=True)
    doc = file_document(ResultsFile.of(results))
    write_atomically(folder / PARAMETERS_FILE, json.dumps(doc, indent=2))
    write_atomically(folder / "parameters.yaml", yaml.safe_dump(json.loads(json.dumps(doc)), sort_keys=False))
    for fit in results.fits:
        save_fit(folder / "fits" / f"{fit.name}.npz", fit)
    if results.online is not None:
        save_online(folder / "online.npz", results.online)
    return folder


def load_results(folder: str | Path) -> Results:
    """Read back what :func:`save_results` wrote (any format up to :data:`ident_hw.storage.FORMAT`)."""
    folder = Path(folder)
    path = folder / PARAMETERS_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{folder} is not a results folder: no {PARAMETERS_FILE}")
    stored_file = of_document(ResultsFile, json.loads(path.read_text()), str(path))
    fits = sorted((load_fit(p) for p in sorted((folder / "fits").glob("*.npz"))),
                  key=lambda f: f.role != "identification")
    online = load_online(folder / "online.npz") if (folder / "online.npz").is_file() else None
    return stored_file.results(tuple(fits), online)
