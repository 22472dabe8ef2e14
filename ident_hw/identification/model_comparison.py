"""The dynamic, power and energy models side by side (the power-model paper, its Table 1).

The same recordings, cut into the same stretches and filtered by the same position filter, give
three sets of linear equations in the robot's parameter vector ``pi`` (P,):

- **dynamic model**: ``tau = Y pi``, one row per actuator and sample, ``Y`` built from the
  accelerations; rows and forces filtered in parallel and decimated
  (:func:`ident_hw.experiment.preparation.prepare`: exactly the rows the least-squares step fits);
- **power model**: ``Thetadᵀ tau = dE/dt + Σ_j (f_vj qd_j² + f_cj qd_j tanh(qd_j / w))``, one
  scalar row per sample, no acceleration (``dH/dt`` of the energy regressor by fourth-order
  central differences); rows and actuated power filtered in parallel and decimated by the same
  filter as the dynamic rows (:func:`power_energy_rows`);
- **energy model**: the power model integrated over consecutive windows (cumulative Simpson):
  ``∫ Thetadᵀ tau dt = ΔE + friction work``, one scalar row per window. Its integrands (actuated
  power, friction power) and ``H`` get the same parallel low-pass first (a linear filter commutes
  with the integral and the differences, so the equation still holds): integrated raw, the force
  noise and the drives' fast force ripple above the cut-off pass the window's boxcar far more
  than the Butterworth, and on the simulated 2R the energy model's σ came out 2 to 4 times the
  power model's (with the filter: about the same). Its rows lie on the stretch without *twice*
  the filter's edges: ``H`` and the power are filtered separately, and their edge transients do
  not match (at one trim they left 7e-5 of relative error on exact 2R data, growing with the
  rate; at two, 3e-6, falling as the rate rises). The windows are one decimated sample long, so
  the three models have rows at the same rate (the window length hardly changes σ: longer
  windows give fewer rows of more signal).

``E = H pi`` is the robot's energy (``RobotModel.energy_regressor(Theta, Thetad, guess)`` (N, P):
kinetic and potential energy of the bodies, the rotors' ``Jm qd² / 2``, zero friction columns),
the friction power columns go to the model's own ``f_v``, ``f_c`` entries
(:class:`ident_hw.identification.power.FrictionLayout`).

Each model's base parameters are found from its own rows by the SVD of the column-scaled rows
(:func:`ident_hw.identification.base_params.identify_base`), fitted by least squares with σ from
the residual (the HAC covariance of :mod:`ident_hw.identification.least_squares`). The power and
energy models see only what does work: a parameter that changes no energy along any motion (a
term of ``Y`` that is a constraint force, or a gravity term on a horizontal robot) is not in their
rank; where their null space is the dynamic model's, their base parameters are written in the
dynamic model's basis (:func:`ident_hw.identification.base_params.with_basis`), so a table can
set them side by side; otherwise each keeps its own, and the record says the rank each found.

Rows of an axis near rest are left out of the dynamic model (``identification.min_speed``), not
out of the power and energy models: there the friction power ``f_c qd tanh(qd / w)`` goes to zero
with the speed, so the ill-defined friction at rest carries no weight in their rows.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ident_hw.filtering import FilterSettings, lowpass, parallel_decimate
from ident_hw.model.base_basis import BaseBasis

from .base_params import column_scale, identify_base, scaled_condition
from .least_squares import POORLY_IDENTIFIED_PERCENT, informative_rows
from .power import FrictionLayout, friction_power, power_rows_in_layout, windowed_energy_rows

#: the models, in the order of the tables
MODELS = ("dynamic", "power", "energy")
#: each model's equation and the unit of its output, for the tables
EQUATIONS = {"dynamic": "tau = Y pi", "power": "Thetad·tau = dE/dt + friction power",
             "energy": "∫ Thetad·tau dt = ΔE + friction work"}
#: the unit of each model's output
OUTPUT_UNITS = {"dynamic": "N·m | N", "power": "W", "energy": "J"}


@dataclass(frozen=True)
class ModelRows:
    """The equations of one model (:data:`MODELS`) on some data: regressor ``Y`` (M, k, P) and
    outputs ``y`` (M, k) with ``y ≈ Y @ pi`` (k = the actuators for the dynamic model, 1 for the
    scalar power (W) and energy (J) models; a NaN output leaves its row out). ``window``: the
    energy model's integration window, s (None for the others)."""

    model: str
    Y: np.ndarray
    y: np.ndarray
    window: float | None = None

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(f"unknown model {self.model!r}; expected one of {MODELS}")
        if self.Y.ndim != 3 or self.y.shape != self.Y.shape[:2]:
            raise ValueError(f"expected Y (M, k, P) and y (M, k); got {self.Y.shape}, {self.y.shape}")

    @classmethod
    def concatenate(cls, parts: Sequence["ModelRows"]) -> "ModelRows":
        """The rows of several stretches or recordings of one model, one after the other."""
        if not parts:
            raise ValueError("no rows to concatenate")
        windows = [p.window for p in parts if p.window is not None]
        return cls(parts[0].model, np.concatenate([p.Y for p in parts]), np.concatenate([p.y for p in parts]),
                   max(windows) if windows else None)


def energy_columns(robot, Theta, Thetad, poses=None) -> np.ndarray:
    """The robot's energy regressor ``H`` (N, P) in the order of its ``parameter_names`` (``E =
    H @ pi``, J) at actuated positions ``Theta`` and rates ``Thetad`` (N, n); ``poses`` (N,
    pose_size) the per-sample guesses of the assembly mode (None: the model's own continuation).

    Raises:
        ValueError: the model has no energy regressor over its whole parameter vector (the
            3PRRR's gives the kinetic energy of its 7 inertial parameters from the pose rates).
    """
    Theta, Thetad = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (Theta, Thetad))
    P = len(robot.parameter_names)
    method = getattr(robot, "energy_regressor", None)
    if method is None:
        raise ValueError(f"{type(robot).__name__} has no energy regressor: the power and energy models need one")
    try:
        H = np.asarray(method(Theta, Thetad, poses), dtype=float)
    except TypeError as exc:
        raise ValueError(f"{type(robot).__name__}.energy_regressor does not take (Theta, Thetad, guess): "
                         f"the power and energy models need the energy over the whole parameter vector ({exc})") from exc
    if H.shape != (len(Theta), P):
        raise ValueError(f"{type(robot).__name__}.energy_regressor gives {H.shape}, expected ({len(Theta)}, {P})")
    return H


def supports_energy_models(robot) -> str | None:
    """None when the power and energy models can be built for ``robot`` (an energy regressor
    over its parameter vector, friction coefficients among its entries), else why not."""
    try:
        FrictionLayout.of(robot)
        home = np.asarray(robot.home_actuated(), dtype=float)
        energy_columns(robot, home[None], np.zeros((1, home.size)), None)
    except ValueError as exc:
        return str(exc)
    return None


def power_energy_rows(robot, t, Theta, Thetad, tau, poses, settings: FilterSettings,
                      window: int | None = None) -> tuple[ModelRows, ModelRows]:
    """The power and energy models' rows of one stretch at the input rate.

    Args:
        robot: a model with an energy regressor over its parameters (:func:`energy_columns`).
        t: uniform sample times (N,), s.
        Theta, Thetad: filtered actuated positions and rates (N, n), rad or m, rad/s or m/s
            (:func:`ident_hw.filtering.prepare_actuated`).
        tau: measured actuator forces (N, n), N·m or N, not filtered.
        poses: (N, pose_size) guesses of the assembly mode per sample.
        settings: the filter of the dynamic rows; the power rows get the same parallel filter,
            trim and decimation (:func:`ident_hw.filtering.parallel_decimate`).
        window: the energy model's window, samples (default the decimation: one row per
            decimated sample), over the stretch without ``2 settings.trim`` samples at each end;
            its integrands and ``H`` low-passed by the parallel filter first.

    Returns:
        The power rows (M, 1, P), W, and the energy rows (K, 1, P), J (none when the trimmed
        stretch is shorter than a window).
    """
    t = np.asarray(t, dtype=float)
    Thetad, tau = np.asarray(Thetad, dtype=float), np.asarray(tau, dtype=float)
    layout = FrictionLayout.of(robot)
    H = energy_columns(robot, Theta, Thetad, poses)
    W, y = power_rows_in_layout(t, H, Thetad, tau, robot.coulomb_width, layout, edges=True)
    # the second-order rows at the two ends never survive the trim
    filt = settings if settings.trim >= 2 else dataclasses.replace(settings, trim=2)
    W, y = parallel_decimate(filt, W, y)
    power = ModelRows("power", W[:, None, :], y[:, None])
    window = settings.decimation if window is None else int(window)
    inner = slice(2 * settings.trim, t.size - 2 * settings.trim)
    P = layout.n_params
    if t[inner].size > window:
        Hf, Pf, Ff = (lowpass(x, settings.sample_rate, settings.decimation_cutoff_hz, settings.order)
                      for x in (H, np.sum(Thetad * tau, axis=1), friction_power(Thetad, robot.coulomb_width)))
        We, ye = windowed_energy_rows(t[inner], Hf[inner], Pf[inner], Ff[inner], layout, window)
    else:
        We, ye = np.zeros((0, P)), np.zeros(0)
    energy = ModelRows("energy", We[:, None, :], ye[:, None], window=window / settings.sample_rate)
    return power, energy


@dataclass(frozen=True)
class ComparisonRow:
    """One base parameter of one model: its estimate, σ and %σ, and, in simulation, its true
    value (the same combination of the true parameters) and the error, %."""

    model: str
    expression: str
    estimate: float
    sigma: float
    rel_sigma_percent: float | None
    truth: float | None
    error_percent: float | None


@dataclass(frozen=True)
class ModelFit:
    """The base parameters one model identifies.

    Attributes:
        model: one of :data:`MODELS`; method: ``OLS`` or ``WLS``.
        expressions: (r,) the base parameters ``pi_b = H pi`` written out.
        H: (r, P) over the robot's whole parameter vector (held parameters' columns 0).
        coef, sigma: (r,) estimate and standard deviation (units of each combination).
        truth: (r,) ``H @ truth`` in simulation, else None.
        equations: rows the fit used (informative, not left out).
        rank: of the model's rows over the free parameters (of ``free``).
        free: how many parameters were free.
        cond: condition number of the kept columns scaled to unit RMS.
        residual_rms: RMS residual of the rows, in :data:`OUTPUT_UNITS` of the model.
        window: the energy model's window, s (None for the others).
    """

    model: str
    method: str
    expressions: tuple[str, ...]
    H: np.ndarray
    coef: np.ndarray
    sigma: np.ndarray
    truth: np.ndarray | None
    equations: int
    rank: int
    free: int
    cond: float
    residual_rms: float
    window: float | None = None

    @property
    def rel_sigma_percent(self) -> np.ndarray:
        """(r,) ``100 σ / |estimate|`` (inf at a zero estimate)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return 100.0 * self.sigma / np.abs(self.coef)

    @property
    def error_percent(self) -> np.ndarray | None:
        """(r,) ``100 (estimate − truth) / |truth|``, NaN where the truth is 0; None without a truth."""
        if self.truth is None:
            return None
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.truth != 0, 100.0 * (self.coef - self.truth) / np.abs(self.truth), np.nan)

    def rows(self) -> list[ComparisonRow]:
        """One :class:`ComparisonRow` per base parameter."""
        rel, err = self.rel_sigma_percent, self.error_percent
        return [ComparisonRow(self.model, e, float(self.coef[i]), float(self.sigma[i]), _finite(rel[i]),
                              None if self.truth is None else float(self.truth[i]),
                              None if err is None else _finite(err[i]))
                for i, e in enumerate(self.expressions)]


@dataclass(frozen=True)
class ModelComparison:
    """The dynamic, power and energy models' base parameters on the same data (the power-model
    paper's Table 1): ``fits`` in the order of :data:`MODELS` (a model without rows is absent);
    ``step`` and ``trajectories``: the least-squares step whose recordings were used; ``held``:
    parameters held at known values (their contribution taken off every model's outputs);
    ``threshold``: the %σ above which an estimate is poorly identified."""

    step: str
    trajectories: tuple[str, ...]
    held: tuple[str, ...]
    fits: tuple[ModelFit, ...]
    threshold: float = POORLY_IDENTIFIED_PERCENT

    def fit(self, model: str) -> ModelFit | None:
        """The fit of ``model``, None when it had no rows."""
        return next((f for f in self.fits if f.model == model), None)

    @property
    def has_truth(self) -> bool:
        """Some model's base parameters have true values (simulation)."""
        return any(f.truth is not None for f in self.fits)

    @property
    def shared_expressions(self) -> tuple[str, ...] | None:
        """The base parameters when every model identified the same ones, else None."""
        names = {f.expressions for f in self.fits}
        return names.pop() if len(names) == 1 else None


def compare_models(names: Sequence[str], rows: Sequence[ModelRows], *, free: Sequence[str] | None = None,
                   values: np.ndarray | None = None, truth: np.ndarray | None = None, weighted: bool = False,
                   basis: BaseBasis | None = None, step: str = "", trajectories: Sequence[str] = (),
                   threshold: float = POORLY_IDENTIFIED_PERCENT) -> ModelComparison:
    """Fit the base parameters of each model's rows (:class:`ModelRows`, at most one per model).

    Args:
        names: the robot's parameter names (P).
        rows: the models' equations over the same parameter vector.
        free: the parameters to fit (default all); the others are held at ``values`` (P,) and
            their contribution is taken off the outputs.
        truth: (P,) the true parameters (simulation), for each base parameter's error.
        weighted: WLS (each actuator's rows weighted by its noise) for the dynamic model; the
            scalar models have one output and are fitted by OLS.
        basis: the robot's readable base parameters over ``free``
            (``RobotModel.readable_base``), used for the dynamic model where its data
            identifies them all; the other models use the dynamic model's basis where their
            null space is the same.
        step, trajectories, threshold: recorded in the result.
    """
    names = tuple(names)
    free = names if free is None else tuple(free)
    idx = [names.index(p) for p in free]
    held = [i for i in range(len(names)) if i not in idx]
    if held and values is None:
        raise ValueError(f"values of the held parameters {[names[i] for i in held]} are needed")
    order = sorted(rows, key=lambda r: MODELS.index(r.model))
    if len({r.model for r in order}) != len(order):
        raise ValueError(f"one set of rows per model, got {[r.model for r in order]}")
    fits, common = [], basis
    for r in order:
        Y = np.asarray(r.Y, dtype=float)
        if Y.shape[2] != len(names):
            raise ValueError(f"{r.model} rows have {Y.shape[2]} columns for {len(names)} parameters")
        y = np.asarray(r.y, dtype=float)
        if held:
            y = y - Y[:, :, held] @ np.asarray(values, dtype=float)[held]
        Yf = Y[:, :, idx]
        if not informative_rows(np.where(np.isnan(y)[..., None], 0.0, Yf)).any():
            continue
        dynamic = r.model == "dynamic"
        base, fit = identify_base(Yf, y, free, scale=column_scale(Yf), weighted=weighted and dynamic,
                                  basis=common if not held or not dynamic else None)
        if dynamic:
            common = base
        kept = [free.index(k) for k in base.kept]
        H = np.zeros((base.rank, len(names)))
        H[:, idx] = np.where(np.abs(base.H) > 1e-10, base.H, 0.0)
        rho = y - Yf[:, :, kept] @ fit.coef
        used = ~np.isnan(rho) & informative_rows(np.where(np.isnan(y)[..., None], 0.0, Yf))
        fits.append(ModelFit(
            model=r.model, method=fit.method, expressions=base.expressions, H=H, coef=fit.coef, sigma=fit.std,
            truth=None if truth is None else H @ np.asarray(truth, dtype=float), equations=int(used.sum()),
            rank=base.rank, free=len(free), cond=scaled_condition(Yf[:, :, kept], y),
            residual_rms=float(np.sqrt(np.mean(rho[used] ** 2))), window=r.window))
    return ModelComparison(step=step, trajectories=tuple(trajectories), held=tuple(names[i] for i in held),
                           fits=tuple(fits), threshold=threshold)


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None
