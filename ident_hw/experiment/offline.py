"""Identification from recorded samples: the config's steps, then validation (no bus involved).

Each recording (positions and motor currents of the six axes at the SYNC rate, SI) goes through
the same preparation (:func:`ident_hw.signal.prepare_actuated`, then the parallel filter and
decimation of forces and regressor). The steps of ``identification.steps`` run in order, each
an SQP fit of its parameters with the others held at their current values (CAD at the start),
so the sweep's ``m_c`` is used by the squares' step. A ``wls``/``ols`` step instead fits the
base parameters of its parameters (:func:`fit_base`), reported beside the physical ones with
its own prediction of every trajectory. The result is a :class:`ident_hw.report.Results` with
standard deviations from the weighted least-squares statistics of each step, a
base-parameter analysis of all identification data, what each recording covered
(:func:`coverage`) and the quality verdict (:func:`ident_hw.experiment.quality.verdict`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from drivers.errors import RecordingError
from drivers.recording import Recording
from ident_hw.config import Config
from ident_hw.identification.base_params import base_parameters, identify_base
from ident_hw.identification.least_squares import check_regression_data, stack, wls
from ident_hw.identification.mass_fit import sqp_fit
from ident_hw.model import InertialParams, ThreePRRR
from ident_hw.report import BaseFit, ParameterTable, Results, TrajectoryFit, coverage_text
from ident_hw.signal import kept_samples, parallel_decimate, prepare_actuated

from .plan import motion_bandwidth, robot_model
from .quality import verdict
from .recordings import planned_cycles, require_trajectories

NAMES = InertialParams.NAMES


@dataclass
class Prepared:
    """One trajectory after preparation and decimation: t (M,), Theta (M, 6), X (M, 3),
    regressor Y (M, 6, n), forces tau (M, 6); ``excluded`` decimated samples were left out;
    ``moving`` (M, 6) marks the rows the fits use (:attr:`tau_fit`)."""

    name: str
    t: np.ndarray
    Theta: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    tau: np.ndarray
    moving: np.ndarray
    excluded: int = 0

    @property
    def tau_fit(self) -> np.ndarray:
        """``tau`` with NaN in the rows of axes near rest (left out of the fits, see
        :mod:`ident_hw.identification.least_squares`)."""
        return np.where(self.moving, self.tau, np.nan)


def fill_gaps(t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation over NaN samples (cycles in which a frame was missing), per column."""
    out = np.array(values, dtype=float)
    for j in range(out.shape[1]):
        bad = ~np.isfinite(out[:, j])
        if bad.all():
            raise ValueError(f"axis {j} has no valid sample")
        if bad.any():
            out[bad, j] = np.interp(t[bad], t[~bad], out[~bad, j])
    return out


def sample_times(rec: Recording) -> np.ndarray:
    """Sample times (s) of a recording: the SYNC grid ``cycle × sync_period`` when the
    recording knows its SYNC period (the drives sample on SYNC; the host's reception times
    carry its scheduling jitter), else the recorded ``t``."""
    period = rec.metadata.get("sync_period")
    if period:
        return (np.asarray(rec.cycle) - rec.cycle[0]) * float(period)
    return np.asarray(rec.t, dtype=float)


#: two SYNCs further apart than this many periods: the producer skipped a slot
SKIPPED_SLOT = 1.5


def with_skipped_slots(rec: Recording) -> Recording:
    """A hardware recording on the drives' time again: every SYNC slot a thread-timed producer
    skipped (:class:`drivers.bus.GridPeriodicTask`; SYNC timestamps ``t`` more than
    ``SKIPPED_SLOT`` periods apart) becomes a row without samples (NaN, invalid), so that
    ``cycle × sync_period`` (:func:`sample_times`) is the time the drives ran. Real drives move
    on through a skipped slot: without the rows, the motion across it would count one period
    instead of two (20 skipped slots in 10 s of exact samples biased base parameters by up to
    45 %; put back, 1.3 % against 0.7 % from the complete recording). Such a row keeps the
    set-point and statusword of the row before (the drives held them); the rows around it are
    left out of the fits (:func:`disturbed_samples`, metadata ``inserted_rows``). Not for the simulated rig, whose time
    advances one period per SYNC received."""
    period = rec.metadata.get("sync_period")
    if not period or len(rec.t) < 2:
        return rec
    interval = np.diff(np.asarray(rec.t, dtype=float)) / float(period)
    missing = np.where(interval > SKIPPED_SLOT, np.rint(interval).astype(np.int64) - 1, 0)
    if not missing.any():
        return rec
    row = np.concatenate([[0], np.cumsum(1 + missing)])    # each recorded row's slot
    n = int(row[-1]) + 1
    held = np.zeros(n, dtype=np.int64)                      # for every slot, the recorded row before it
    held[row] = np.arange(len(row))
    held = np.maximum.accumulate(held)

    def spread(values: np.ndarray) -> np.ndarray:
        out = np.full((n,) + values.shape[1:], np.nan)
        out[row] = values
        return out

    valid = np.zeros((n,) + rec.valid.shape[1:], dtype=bool)
    valid[row] = rec.valid
    inserted = np.setdiff1d(np.arange(n), row)
    metadata = dict(rec.metadata, slots_inserted=len(inserted), inserted_rows=inserted.tolist())
    return Recording(t=np.interp(np.arange(n), row, rec.t), cycle=rec.cycle[0] + np.arange(n),
                     position=spread(rec.position), velocity=spread(rec.velocity), current=spread(rec.current),
                     statusword=rec.statusword[held], target=rec.target[held], valid=valid, metadata=metadata)


def coverage(config: Config, name: str, rec: Recording) -> dict:
    """What the recording of trajectory ``name`` holds, for the report and the quality verdict.

    Keys: ``file``; ``recording_status`` (``complete``, ``stopped: <why>`` after a fault or a
    signal, ``running (checkpoint)`` when the recording process died, ``raw log`` or ``raw log,
    truncated``); ``cycles`` recorded and ``cycles_planned`` (the trajectory's set-points: the
    recording's ``n_targets``, else the config's trajectory of that name); ``coverage``
    (their ratio, None when unknown); ``valid_fraction`` (complete cycles / rows, with the SYNC
    slots a hardware producer skipped counted as rows, :func:`with_skipped_slots`);
    ``longest_gap_s`` (s, the longest stretch without a complete cycle); ``skipped_slots``;
    ``unplaced_frames`` (frames the master could not place in their cycle, so some samples
    may hold another cycle's data: :class:`drivers.acquisition.CycleAssembler`).
    """
    meta = rec.metadata
    planned = meta.get("n_targets") or planned_cycles(config, name)
    status = str(meta.get("status", "unknown"))
    if status == "decoded":
        status = "raw log, truncated" if meta.get("log_truncated") else "raw log"
    rows = rec if config.simulated else with_skipped_slots(rec)
    t = sample_times(rows)
    complete = rows.valid.all(axis=1)
    gap = 0.0
    if len(t) > 1:
        period = float(meta.get("sync_period") or np.median(np.diff(t)))
        edges = np.concatenate([[t[0] - period], t[complete], [t[-1] + period]])
        gap = round(max(0.0, float(np.max(np.diff(edges))) - period), 6)
    return {"file": meta.get("file"), "recording_status": status, "cycles": len(rec.t),
            "cycles_planned": None if planned is None else int(planned),
            "coverage": None if not planned else min(1.0, len(rec.t) / planned),
            "valid_fraction": float(complete.mean()) if len(t) else 0.0, "longest_gap_s": gap,
            "skipped_slots": int(rows.metadata.get("slots_inserted", 0)),
            "unplaced_frames": int(meta.get("unplaced_frames") or 0)}


#: a set-point sequence accelerating faster than this many times the axis limit was not
#: delivered on time (the drive held a stale set-point, then jumped)
SETPOINT_JUMP = 5.0
#: a current within this fraction of the drive's limit is clipped, not a measurement
SATURATION = 0.98


def disturbed_samples(config: Config, rec: Recording, t: np.ndarray, reach: float) -> np.ndarray:
    """Samples (N,) bool near a disturbance the model cannot explain: a current at the drive's
    limit, a set-point that arrived late (its second difference implies more than
    ``SETPOINT_JUMP`` × the axis' acceleration limit), or a skipped SYNC slot put back by
    :func:`with_skipped_slots` (metadata ``inserted_rows``: the drives moved on there, the
    gap-filling interpolation stands in for all six axes). Each is widened by ``reach`` s on
    both sides (the support of the filters that spread it). Cycles that came incomplete are
    not: their gaps are filled (on a slow simulated rig they can be most of the cycles)."""
    acts = config.robot.actuators
    limit = np.array([a.limits.current for a in acts])
    bad = np.any(np.abs(np.nan_to_num(rec.current)) >= SATURATION * limit, axis=1)
    bad[np.asarray(rec.metadata.get("inserted_rows", ()), dtype=np.int64)] = True
    if len(t) > 2:
        dt = float(np.median(np.diff(t)))
        counts = np.array([a.scaling().counts_per_unit for a in acts])
        jump = np.abs(np.diff(np.nan_to_num(rec.target), 2, axis=0))
        allowed = SETPOINT_JUMP * np.array([a.limits.acceleration for a in acts]) * dt**2 + 2.0 / counts
        bad[1:-1] |= np.any(jump > allowed, axis=1)
    width = int(np.ceil(reach / float(np.median(np.diff(t))))) if len(t) > 1 else 0
    if bad.any() and width:
        bad = np.convolve(bad, np.ones(2 * width + 1), mode="same") > 0
    return bad


def prepare(config: Config, robot: ThreePRRR, name: str, rec: Recording) -> Prepared:
    """Recording → filtered motion, regressor and forces, decimated in parallel; decimated
    samples near a disturbance (:func:`disturbed_samples`) are left out. On hardware the SYNC
    slots the producer skipped are put back first (:func:`with_skipped_slots`)."""
    if not config.simulated:
        rec = with_skipped_slots(rec)
    t = sample_times(rec)
    where = f"{rec.metadata.get('file', 'recording')} (trajectory {name!r})"
    if len(t) < 3:
        raise RecordingError(f"{where}: {len(t)} samples, too few to identify from")
    empty = [f"node {a.node_id} ({a.name})" for a, ok in zip(config.robot.actuators, rec.valid.any(axis=0)) if not ok]
    if empty:
        raise RecordingError(f"{where}: no valid sample of {', '.join(empty)}")
    rate = 1.0 / float(np.median(np.diff(t)))
    settings = config.identification.filter.settings(rate, motion_bandwidth(config, name))
    force_per_amp = np.array([a.scaling().force_per_amp for a in config.robot.actuators])
    samples = prepare_actuated(t, fill_gaps(t, rec.position), fill_gaps(t, rec.current), force_per_amp, settings)
    X = robot.forward_kinematics(samples.Theta, np.zeros(3))
    Y = robot.regressor_from_actuated(samples.Theta, samples.Thetad, samples.Thetadd, np.zeros(3))
    Y, tau = parallel_decimate(settings, Y, samples.tau)
    kept = np.arange(len(t))[kept_samples(settings, len(t))]
    good = ~disturbed_samples(config, rec, t, 2.0 / settings.decimation_cutoff_hz)[kept]
    kept = kept[good]
    speed_limit = np.array([a.limits.velocity for a in config.robot.actuators])
    moving = np.abs(samples.Thetad[kept]) >= config.identification.min_speed * speed_limit
    return Prepared(name, t[kept], samples.Theta[kept], X[kept], Y[good], tau[good], moving,
                    excluded=int((~good).sum()))


def column_scale(Y: np.ndarray) -> np.ndarray:
    """(n,) inverse RMS of each regressor column over all samples and outputs (1 for a zero
    column): scaling by it makes the rank decision of the base parameters unit-free."""
    rms = np.sqrt(np.mean(Y.reshape(-1, Y.shape[-1]) ** 2, axis=0))
    return np.divide(1.0, rms, out=np.ones_like(rms), where=rms > 0)


def scaled_condition(Y: np.ndarray, tau: np.ndarray) -> float:
    """Condition number of the stacked regressor ``Y`` (N, 6, n) with unit-RMS columns, over the
    rows the fit uses (``tau`` not NaN): unit-free, unlike cond(W) of kg next to kg·m²."""
    W, _ = stack(*check_regression_data(Y, tau))
    W = W[np.any(W != 0.0, axis=1)]
    if not len(W):
        return float("inf")
    return float(np.linalg.cond(W * column_scale(W[:, None, :])))


def fit_base(step, Y: np.ndarray, tau: np.ndarray, coef: np.ndarray, initial: np.ndarray,
             truth: np.ndarray | None, threshold: float) -> tuple[BaseFit, np.ndarray, dict]:
    """Least squares (``step.method`` ``wls``/``ols``) of the base parameters of ``step.parameters``
    on ``Y`` (N, 6, n), ``tau`` (N, 6), the other parameters held at ``coef``.

    Returns the :class:`BaseFit`, the physical vector (n,) that predicts the same forces (each
    kept parameter carries its base value, the eliminated ones 0, the held ones ``coef``) and the
    step's record for the results.
    """
    free = [NAMES.index(p) for p in step.parameters]
    held = [i for i in range(len(NAMES)) if i not in free]
    Yf = Y[:, :, free]
    base, fit = identify_base(Yf, tau - Y[:, :, held] @ coef[held], step.parameters, scale=column_scale(Yf),
                              weighted=step.method == "wls")
    H = np.zeros((base.rank, len(NAMES)))
    H[:, free] = np.where(np.abs(base.H) > 1e-10, base.H, 0.0)   # rounding of N1 N2^-1, not a coefficient
    equivalent = coef.copy()
    equivalent[free] = 0.0
    equivalent[[NAMES.index(k) for k in base.kept]] = fit.coef
    result = BaseFit(step=step.name, method=fit.method, trajectories=tuple(step.trajectories),
                     expressions=base.expressions, H=H, coef=fit.coef, sigma=fit.std,
                     initial=H @ initial, truth=None if truth is None else H @ truth,
                     held=tuple(NAMES[i] for i in held), unexcited=base.unexcited, threshold=threshold)
    record = {"name": step.name, "trajectories": list(step.trajectories), "free": list(step.parameters),
              "method": f"{fit.method} of the base parameters ({base.rank} of {len(free)})",
              "eliminated": list(base.eliminated), **{k: v for k, v in fit.to_dict().items() if k != "parameters"},
              "cond_scaled": scaled_condition(Yf[:, :, [list(step.parameters).index(k) for k in base.kept]], tau)}
    return result, equivalent, record


def identify(config: Config, recordings: Mapping[str, Recording],
             progress: Callable[[str], None] | None = None) -> Results:
    """Run the config's identification steps and validation on ``recordings`` (name → samples)."""
    ident = config.identification
    if ident is None:
        raise ValueError(f"{config.source}: identification: missing section")
    robot = robot_model(config)
    needed = [n for s in ident.steps for n in s.trajectories] + list(ident.validation)
    require_trajectories(config, recordings)
    used = {name: coverage(config, name, recordings[name]) for name in dict.fromkeys(needed)}
    if progress:
        for name, u in used.items():
            progress(f"  {name}: {coverage_text(u)}")
    prepared: dict[str, Prepared] = {}
    for name in dict.fromkeys(needed):
        if progress:
            progress(f"preparing {name}")
        prepared[name] = prepare(config, robot, name, recordings[name])
        if progress and prepared[name].excluded:
            progress(f"  {name}: {prepared[name].excluded} of {prepared[name].excluded + len(prepared[name].t)} "
                     "samples left out (current at its limit, late set-point or skipped SYNC slot nearby)")

    n = len(NAMES)
    initial = config.robot.cad.to_model().as_vector()
    coef = initial.copy()
    sigma = np.full(n, np.nan)
    lower, upper = np.full(n, -np.inf), np.full(n, np.inf)
    step_of, method_of = [""] * n, [""] * n
    truth = config.sim.truth.to_model().as_vector() if config.sim is not None else None
    steps = []
    base_fit, base_equivalent = None, None
    for step in ident.steps:
        if progress:
            progress(f"step {step.name}: fitting {', '.join(step.parameters)}"
                     + (f" (base parameters, {step.method.upper()})" if step.method != "sqp" else ""))
        Y = np.concatenate([prepared[t].Y for t in step.trajectories])
        tau = np.concatenate([prepared[t].tau_fit for t in step.trajectories])
        if step.method != "sqp":
            base_fit, base_equivalent, record = fit_base(step, Y, tau, coef, initial, truth,
                                                         ident.rel_sigma_threshold)
            steps.append(record)
            continue
        bounds = {p: ident.bounds[p] for p in step.parameters if p in ident.bounds}
        fit = sqp_fit(Y, tau, NAMES, coef, free=step.parameters, bounds=bounds)
        coef = fit.coef
        idx = [NAMES.index(p) for p in step.parameters]
        held = [i for i in range(n) if i not in idx]
        # sigma of the free parameters: WLS statistics of the same weighted problem
        record = {"name": step.name, "trajectories": list(step.trajectories), **fit.to_dict(),
                  "samples_left_out": {t: prepared[t].excluded for t in step.trajectories},
                  "cond_scaled": scaled_condition(Y[:, :, idx], tau)}
        try:
            stats = wls(Y[:, :, idx], tau - Y[:, :, held] @ coef[held], step.parameters, output_std=fit.output_std)
        except ValueError as exc:  # rank deficient: the fit is bounded, but has no covariance
            record["statistics"] = str(exc)
        else:
            sigma[idx] = stats.std
            record["cond_W"] = stats.cond
        for i, p in zip(idx, step.parameters):
            lo, hi = bounds.get(p, (0.0, np.inf))
            lower[i], upper[i] = lo, hi
            step_of[i], method_of[i] = step.name, step.method
        steps.append(record)

    id_names = list(dict.fromkeys(t for s in ident.steps for t in s.trajectories))
    W, _ = stack(*check_regression_data(np.concatenate([prepared[t].Y for t in id_names]),
                                        np.concatenate([prepared[t].tau_fit for t in id_names])))
    base = base_parameters(W, NAMES, scale=np.maximum(np.abs(initial), 1e-3)).to_dict()

    fits = []
    for name, p in prepared.items():
        role = "validation" if name in ident.validation and name not in id_names else "identification"
        fits.append(TrajectoryFit(name, role, p.t, p.tau, p.Y @ coef, p.Theta, p.X,
                                  tau_base=None if base_fit is None else p.Y @ base_equivalent))
    table = ParameterTable(names=NAMES, initial=initial, identified=coef, sigma=sigma, lower=lower, upper=upper,
                           step=tuple(step_of), method=tuple(method_of), truth=truth)
    for name, p in prepared.items():
        used[name].update(samples_used=len(p.t), samples_left_out=p.excluded)
    results = Results(parameters=table, fits=fits, steps=steps, base_parameters=base, base_fit=base_fit,
                      rel_sigma_threshold=ident.rel_sigma_threshold, trajectories=used)
    results.quality = verdict(results, ident.quality)
    return results
