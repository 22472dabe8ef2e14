"""Figures computed from results: the force prediction on each trajectory (:func:`metrics`,
the report's ``metrics.yaml``), the relative residual of each actuator on each validation
trajectory (:func:`validation_figures`, stored in ``parameters.json``), and how each online
estimator settled after a payload change (:func:`estimator_summaries`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ident_hw.identification.metrics import validation_metrics
from ident_hw.records import PredictionMetrics, TrajectoryMetrics
from ident_hw.storage import NONE, stored

from .objects import OnlineTrace, Results, TrajectoryFit

#: an online estimate has settled when it stays within this fraction of the true value
SETTLED = 0.02


# ----------------------------------------------------------------------------- force predictions
def metrics(results: Results) -> dict[str, TrajectoryMetrics]:
    """Per trajectory: the force prediction of the step-by-step parameters and of the
    base-parameter fit."""
    return {fit.name: TrajectoryMetrics.of(
        role=fit.role, samples=int(len(fit.t)), stepwise=_metrics(results.actuators, fit.tau, fit.tau_model),
        base_fit=None if fit.tau_base is None else _metrics(results.actuators, fit.tau, fit.tau_base))
        for fit in results.fits}


def _metrics(actuators: tuple[str, ...], tau: np.ndarray, tau_model: np.ndarray) -> PredictionMetrics:
    if not len(tau):                # nothing of the trajectory could be fitted (the verdict says why)
        nan = dict.fromkeys(actuators, float("nan"))
        return PredictionMetrics(rms=nan, nrms_percent=dict(nan), d_tau_percent=float("nan"), j_rmse=float("nan"))
    m = validation_metrics(tau, tau_model)
    return PredictionMetrics(rms=dict(zip(actuators, m.rms.tolist())),
                             nrms_percent=dict(zip(actuators, m.nrms_percent.tolist())),
                             d_tau_percent=m.d_tau_percent, j_rmse=m.j_rmse)


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


#: per actuator, in actuator order, a figure (%, or a fraction); None: none (no row left)
Row = tuple[float | None, ...]


def _row(values: np.ndarray | None) -> Row | None:
    """A row of figures: NaN as None."""
    return None if values is None else tuple(float(v) if math.isfinite(v) else None for v in values)


@dataclass(frozen=True)
class Pair:
    """One figure per actuator of the identified parameters' prediction (``fit``) and of the set
    from elsewhere's (``compared``, ``identification.compare_with``; None: none, not stored)."""

    fit: Row
    compared: Row | None = field(default=None, metadata=stored(NONE))


def _whole_only(figures: ValidationFigures) -> bool:
    return figures.rre_moving_percent is None


@dataclass(frozen=True)
class ValidationFigures:
    """The force prediction on one validation trajectory, per actuator, as the UR10e dataset's
    authors measure it (:func:`relative_residual_percent`) of the identified parameters
    (:attr:`TrajectoryFit.tau_fit`) and of the set from elsewhere: ``rre_percent`` over the whole
    trajectory; where the trajectory says which rows are at rest, also over the rows where the
    actuator moves and where it is at rest (``rre_moving_percent``, ``rre_at_rest_percent``), the
    share (%) of each prediction's squared residual that the rows at rest hold
    (``residual_share_at_rest_percent``: where what is left comes from) and the fraction of the
    rows at rest (``at_rest_fraction``); these stored only then."""

    rre_percent: Pair
    rre_moving_percent: Pair | None = field(default=None, metadata=stored(NONE))
    rre_at_rest_percent: Pair | None = field(default=None, metadata=stored(NONE))
    residual_share_at_rest_percent: Pair | None = field(default=None, metadata=stored(NONE))
    at_rest_fraction: Row | None = field(default=None, metadata=stored(record=_whole_only))

    @classmethod
    def of(cls, fit: TrajectoryFit) -> ValidationFigures:
        """The figures of one fitted trajectory."""
        def figures(prediction: np.ndarray | None) -> tuple[np.ndarray | None, ...]:
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

        own, compared = figures(fit.tau_fit), figures(fit.tau_compared)

        def pair(k: int) -> Pair | None:
            mine = _row(own[k])
            return None if mine is None else Pair(mine, _row(compared[k]))
        rest = None if fit.at_rest is None or not len(fit.t) else fit.at_rest.mean(axis=0)
        whole = pair(0)
        assert whole is not None            # the identified prediction is always there
        return cls(rre_percent=whole, rre_moving_percent=pair(1), rre_at_rest_percent=pair(2),
                   residual_share_at_rest_percent=pair(3), at_rest_fraction=_row(rest))


def validation_figures(results: Results) -> dict[str, ValidationFigures]:
    """:class:`ValidationFigures` of every validation trajectory, by name."""
    return {fit.name: ValidationFigures.of(fit) for fit in results.fits if fit.role == "validation"}


# ----------------------------------------------------------------------------- online settling
@dataclass(frozen=True)
class EstimatorSummary:
    """How one online estimator did over a campaign (:func:`estimator_summaries`).

    ``j_rmse``: RMS a-priori prediction error in units of the output noise; ``diverged_at``: campaign
    time (s) it failed numerically, None if it did not; ``settling``: per tracked base parameter,
    s from the payload change until it stays within :data:`SETTLED` of its new truth (None: never).
    """

    label: str
    j_rmse: float
    diverged_at: float | None
    settling: tuple[tuple[str, float | None], ...]


def tracked(trace: OnlineTrace) -> list[int]:
    """The base parameters of ``trace`` whose truth changes at the payload change."""
    if trace.truth is None or trace.change_time is None or trace.H is None:
        return []
    b = trace.base(trace.truth)
    return [i for i in range(b.shape[1]) if np.ptp(b[:, i]) > 1e-12 * max(np.abs(b[:, i]).max(), 1e-300)]


def settling_time(trace: OnlineTrace, estimator: str, i: int) -> float | None:
    """s from the payload change until base parameter ``i`` of ``estimator`` stays within
    :data:`SETTLED` of its new true value (None: it does not, by the end, or no change)."""
    if trace.truth is None or trace.change_time is None:
        return None
    after = trace.t >= trace.change_time
    est = trace.base(trace.estimates[estimator])[after, i]
    true = trace.base(trace.truth)[after, i]
    off = ~(np.abs(est - true) <= SETTLED * np.abs(true))      # NaN (a diverged estimator) is off
    if not len(off) or off[-1]:
        return None
    last_off = np.nonzero(off)[0]
    k = last_off[-1] + 1 if len(last_off) else 0
    return float(trace.t[after][k] - trace.change_time)


def estimator_summaries(trace: OnlineTrace) -> list[EstimatorSummary]:
    """Per estimator of ``trace`` (SVD-DLS first): J_RMSE, divergence and the settling of each
    tracked base parameter after the payload change."""
    which = tracked(trace)
    return [EstimatorSummary(label, trace.j_rmse.get(label, math.nan), trace.diverged.get(label),
                             tuple((trace.base_names[i], settling_time(trace, label, i)) for i in which))
            for label in trace.estimates]
