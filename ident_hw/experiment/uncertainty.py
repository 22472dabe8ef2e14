"""What a step's σ holds beside the least-squares one: the encoders' resolution (the recordings
read again by encoders whose count edges are moved, :func:`encoder_draws`, :mod:`ident_hw.experiment.encoder`)
and, in a mass-fit step, what the values it holds are worth (:func:`held_value_sigma`)."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from drivers.recording import Recording
from ident_hw.identification.least_squares import LeastSquaresResult, estimate, estimate_columns
from ident_hw.model.interface import RobotModel
from ident_hw.progress import report_progress

from .encoder import count_shifts, reread, smoothed_positions, uncounted_axes
from .inputs import IdentificationPlan
from .preparation import Prepared, kinematics_starts, prepare, usable_segments

logger = logging.getLogger(__name__)


def refit(fit: LeastSquaresResult, Y: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """The estimate of ``fit``'s method on ``Y`` (N, a, m), ``tau`` (N, a): WLS with ``fit``'s
    output weights, else OLS (the estimate alone: :func:`~ident_hw.identification.least_squares.estimate`),
    for data near ``fit``'s (its recordings read again): iterations preconditioned by ``fit``'s
    triangle, not a factorisation of its own."""
    return estimate(Y, tau, fit.names, fit.output_std, near=fit.triangle)


@dataclass(frozen=True)
class EncoderSpread:
    """What a step's encoder draws gave (a step record's fields): how many ``draws``, and each
    estimate's ``sigma`` from their spread, in its unit (0 and () without draws)."""

    draws: int = 0
    sigma: tuple[float, ...] = ()


def encoder_spread(draws: Sequence, covariance: np.ndarray) -> EncoderSpread:
    """The :class:`EncoderSpread` of a step's ``draws`` whose estimates spread with ``covariance``."""
    if not len(draws):
        return EncoderSpread()
    return EncoderSpread(len(draws), tuple(np.sqrt(np.diag(covariance)).tolist()))


def held_value_sensitivity(fit: LeastSquaresResult, Y: np.ndarray, tau: np.ndarray, free: Sequence[int],
                           held: Sequence[int]) -> np.ndarray:
    """(len(free), len(held)) how a mass-fit step's estimates move per unit of each value it
    holds: ``d z_i / d h_j``, for the step's weighted least squares (``fit``'s output weights)
    on ``Y`` (N, a, n) and the rows ``tau`` (N, a) leaves in (NaN: an axis left out).

    With ``A`` the free columns, ``B`` the held ones and ``Wt`` the weights, the estimate is
    ``z = (A' Wt A)^-1 A' Wt (tau - B h)``: column j is minus the fit of ``A`` to ``B_j`` (0 for a
    column that acts on no row). Exact for a fit whose bounds are not active: the model is
    linear in its parameters and the mass fit's weights do not depend on the held values."""
    out = np.zeros((len(free), len(held)))
    columns = np.where(np.isnan(tau)[..., None], np.nan, Y[:, :, list(held)])     # (N, a, len(held))
    acting = np.flatnonzero(np.any(np.nan_to_num(columns) != 0, axis=(0, 1)))
    if acting.size:             # every column on one factorisation of the free columns
        out[:, acting] = -estimate_columns(Y[:, :, list(free)], columns[:, :, acting], fit.names, fit.output_std)
    return out


def held_value_sigma(fit: LeastSquaresResult, Y: np.ndarray, tau: np.ndarray, free: Sequence[int],
                     held: Sequence[int], held_std: np.ndarray) -> np.ndarray:
    """(len(free),) what the values a mass-fit step holds are worth in each of its estimates, in
    their units: their uncertainties ``held_std`` (len(held),) through
    :func:`held_value_sensitivity`, taken as independent: ``sigma_i^2 = sum_j (S_ij std_j)^2``."""
    return np.sqrt(((held_value_sensitivity(fit, Y, tau, free, held) * np.asarray(held_std)) ** 2).sum(axis=1))


@dataclass(frozen=True)
class EncoderDraws:
    """The recordings read again (:func:`encoder_draws`): per draw, each trajectory's
    :class:`Prepared`; and per recording the actuators whose positions are not whole encoder
    counts (none drawn then)."""

    draws: tuple[Mapping[str, Prepared], ...] = ()
    uncounted: Mapping[str, tuple[str, ...]] = field(default_factory=dict)


def encoder_draws(plan: IdentificationPlan, robot: RobotModel, recordings: Mapping[str, Recording],
                  names: Sequence[str]) -> EncoderDraws:
    """The config's ``identification.encoder_draws`` of the recordings ``names``
    (:func:`reread_draws`), none if an axis of one of them is not in whole encoder counts
    (:func:`ident_hw.experiment.encoder.uncounted_axes`)."""
    wanted = plan.identification.encoder_draws
    counts_per_unit = plan.axes.counts_per_unit
    uncounted = {name: tuple(robot.actuator_names[j] for j in uncounted_axes(recordings[name], counts_per_unit))
                 for name in names}
    taken = wanted if not any(uncounted.values()) else 0
    if wanted:
        logger.info(f"the encoders read again, count edges moved: {taken} draws" if taken else
                    "no encoder draws: the positions of " + "; ".join(
                        f"{name} ({', '.join(axes)})" for name, axes in uncounted.items() if axes)
                    + " are not whole encoder counts")
    return EncoderDraws(tuple(reread_draws(plan, robot, recordings, names, taken)), uncounted)


def reread_draws(plan: IdentificationPlan, robot: RobotModel, recordings: Mapping[str, Recording],
                 names: Sequence[str], draws: int) -> list[dict[str, Prepared]]:
    """``draws`` versions of the recordings ``names`` read again by encoders whose count edges are
    moved (:mod:`ident_hw.experiment.encoder`), each prepared as the recording was: one dict
    (trajectory name -> :class:`Prepared`) per draw. Reports its progress (:mod:`ident_hw.progress`)."""
    counts_per_unit = plan.axes.counts_per_unit
    smooth, starts = {}, {}
    for name in names if draws else ():  # once per recording: the motion the draws read again, and
        rec = recordings[name]           # the poses their kinematics start from (a count away at most)
        usable = usable_segments(plan, name, rec)
        settings = usable.settings
        smooth[name] = smoothed_positions(rec, settings.sample_rate, settings.cutoff_hz, settings.order)
        starts[name] = kinematics_starts(robot, rec, usable.segments)
    out = []
    for k, shift in enumerate(count_shifts(draws, len(counts_per_unit))):
        report_progress(logger, "encoder draws", k, draws, "draw")
        out.append({name: prepare(plan, robot, name, reread(recordings[name], smooth[name], counts_per_unit, shift),
                                  starts=starts[name])
                    for name in names})
    if draws:
        report_progress(logger, "encoder draws", draws, draws, "draw")
    return out
