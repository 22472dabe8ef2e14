"""What the quality verdict's per-axis checks judge beside the fits (:func:`axis_evidence`): the
axes the fitted parameters act on, each axis's gain against its own model refitted, and what
noise alone leaves each axis (:func:`noise_floors`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from drivers.recording import Recording
from ident_hw.config.trajectory import STANDSTILL_SETTLE
from ident_hw.filtering import parallel_decimate
from ident_hw.identification.axis_gain import axis_gains, sharing_axes
from ident_hw.model.interface import RobotModel

from .inputs import IdentificationPlan
from .preparation import Prepared, recording_period, trajectory_filter
from .quality import AxisEvidence
from .recordings import identification_valid


def noise_floors(plan: IdentificationPlan, recordings: Mapping[str, Recording], fitted: Sequence[str],
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
    :func:`ident_hw.experiment.uncertainty.reread_draws`) at the parameters ``coef``; with
    ``moving`` (per trajectory (rows, a) bool, ``Prepared.moving``), over each axis's rows the
    fits use (NaN for an axis without one), as the verdict takes the residual. The two add in
    squares. ``{}`` without a standstill recording, or without draws (on a fine trajectory the
    encoders' part can be most of the floor): the verdict then has no floor (:func:`floor_missing`
    says why)."""
    if len(draws) < 2 or coef is None:
        return {}
    stills = []                 # (sample rate, the current about its mean over the longest complete stretch)
    for name in plan.standstills:
        if name in recordings:
            rec = recordings[name]
            settled = rec.t >= rec.t[0] + STANDSTILL_SETTLE if len(rec.t) else np.zeros(0, bool)
            rows = _longest_run(identification_valid(rec).all(axis=1) & settled)
            if rows.stop > rows.start:
                stills.append((1.0 / recording_period(rec), rec.current[rows] - rec.current[rows].mean(axis=0)))
    floors = {}
    per_amp = plan.axes.force_per_amp
    for name in fitted:
        squares, count = np.zeros(len(per_amp)), 0
        for rate, current in stills:
            settings = trajectory_filter(plan, name, rate)
            band = replace(settings, cutoff_hz=settings.decimation_cutoff_hz, decimation=1)
            if len(current) <= 2 * band.trim + 1:
                continue
            (filtered,) = parallel_decimate(band, current)
            squares, count = squares + np.sum(filtered ** 2, axis=0), count + len(filtered)
        if count:
            moving_rows = None if moving is None else moving.get(name)
            floors[name] = np.sqrt(squares / count + _encoder_spread(draws, name, coef, moving_rows) ** 2
                                   / per_amp ** 2)
    return floors


def floor_missing(plan: IdentificationPlan, recordings: Mapping[str, Recording], fitted: Sequence[str],
                  floors: Mapping[str, np.ndarray], draws: Sequence) -> str | None:
    """Why :func:`noise_floors` gave no floor for some of the ``fitted`` trajectories (None: it
    gave every one): no standstill recorded, one too short for a trajectory's filter, or no
    encoder draws."""
    if all(name in floors for name in fitted):
        return None
    if not any(name in recordings for name in plan.standstills):
        return "no standstill"
    if len(draws) < 2:
        return "no encoder draws"
    short = [name for name in fitted if name not in floors]
    return f"the standstill is too short for the filter of {', '.join(short)}"


def acting_axes(robot: RobotModel, prepared: Mapping[str, Prepared], trajectories: Sequence[str],
                fitted: frozenset[str] | set[str]) -> tuple[str, ...]:
    """The axes whose forces some of the ``fitted`` parameters act on in ``trajectories`` (a non-zero
    regressor column): a carriage sweep's links, moved by their held CAD values only, are not."""
    acting = [robot.parameter_names.index(p) for p in fitted]
    return tuple(name for j, name in enumerate(robot.actuator_names)
                 if acting and any(np.any(prepared[t].Y[:, j, acting] != 0) for t in trajectories))


def axis_evidence(plan: IdentificationPlan, robot: RobotModel, recordings: Mapping[str, Recording],
                  prepared: Mapping[str, Prepared], fitted_trajectories: Sequence[str],
                  fitted: frozenset[str] | set[str], draws: Sequence[Mapping[str, Prepared]],
                  coef: np.ndarray) -> AxisEvidence:
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
        gains = axis_gains(Y, tau, coef, free, robot.actuator_names, plan.identification.quality.max_axis_gain,
                           judged)
        sharing = sharing_axes(Y, free, robot.actuator_names)
    floors = noise_floors(plan, recordings, fitted_trajectories, draws, coef,
                          {t: prepared[t].moving for t in fitted_trajectories})
    return AxisEvidence(judged=judged, gains=gains, floors=floors, sharing=sharing,
                        floor_missing=floor_missing(plan, recordings, fitted_trajectories, floors, draws))


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
