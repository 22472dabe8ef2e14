"""The SQP mass fit of the 3PRRR paper (eq. 39), cross-checked by a bounded linear solver.

    pi* = argmin sum_t || (tau(t) − Y(t) pi) / sigma ||²   subject to  lo <= pi <= hi

over a subset of the parameters (the others held at given values), solved with SciPy's
SLSQP started from the CAD values. The problem is linear in ``pi``, so
``scipy.optimize.lsq_linear`` (BVLS) solves the same weighted problem exactly: both answers
are returned and must agree.

Both solvers work on columns scaled to unit norm and a unit right-hand side
(``z_j = ||W_j|| pi_j / ||b||``) so that kilograms of carriage and kg·m² of link inertia share
one scale of order one; the answer is mapped back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, optimize

from .least_squares import check_regression_data, output_noise_std, residual_rms, stack


@dataclass(frozen=True)
class MassFitResult:
    """Result of :func:`sqp_fit`.

    Attributes:
        names: all parameter names (n).
        free: names of the fitted parameters.
        coef: SLSQP estimate, full vector (n,) (held parameters at their given values).
        coef_lsq: ``lsq_linear`` estimate of the same problem, full vector (n,).
        max_rel_difference: ``max |z − z_lsq| / max(|z_lsq|, 1)`` over the free ones, in the
            scaled variables ``z`` (module docstring): the relative difference of ``coef`` and
            ``coef_lsq`` where ``|z_lsq| >= 1``, the absolute one in ``z`` below (no division by a
            value on a bound at zero).
        cost: weighted residual ``sum ||(tau − Y pi)/sigma||²`` at the SLSQP estimate.
        residual_rms: unweighted residual RMS of each output (k,).
        output_std: per-output weights used (k,).
        iterations: SLSQP iterations; ``success`` / ``message`` from SLSQP.
        at_bounds: free parameters on a bound at the optimum (``lsq_linear`` active set).
    """

    names: tuple[str, ...]
    free: tuple[str, ...]
    coef: np.ndarray
    coef_lsq: np.ndarray
    max_rel_difference: float
    cost: float
    residual_rms: np.ndarray
    output_std: np.ndarray
    iterations: int
    success: bool
    message: str
    at_bounds: tuple[str, ...]

    @property
    def method(self) -> str:
        """The fit's method, in words."""
        return "SQP (SLSQP) mass fit, checked by lsq_linear"


def sqp_fit(
    Y: np.ndarray,
    tau: np.ndarray,
    names,
    initial,
    free=None,
    bounds: dict | None = None,
    output_std=None,
    ftol: float = 1e-18,
    maxiter: int = 500,
) -> MassFitResult:
    """Bounded weighted least-squares fit of a parameter subset by SLSQP.

    Args:
        Y, tau: regressor (N, k, n) and outputs (N, k).
        names: the n parameter names (e.g. ``robot.parameter_names``).
        initial: (n,) start values (CAD); the parameters not in ``free`` are held at them.
        free: names to fit (default all), e.g. ``["m_c"]`` for the carriage sweep.
        bounds: ``{name: (lo, hi)}`` for free parameters; default ``(0, inf)`` (all
            parameters of the model are non-negative); ``None`` as a bound means unbounded.
        output_std: per-output noise std (k,) used as weights; default from each output's
            OLS residual (:func:`~ident_hw.identification.least_squares.output_noise_std`).
        ftol: SLSQP tolerance on the scaled cost (scaled to 1 at the start). The cost change
            near the optimum goes as the square of the parameter error, so 1e-18 lets SLSQP
            reach ~1e-9 of the initial misfit: at 1e-14 it stopped 3e-6 short on weakly
            excited link friction of the noise-free squares (a few more iterations).
    """
    Y, tau = check_regression_data(Y, tau, names)
    names = tuple(names)
    initial = np.asarray(initial, dtype=float)
    if initial.shape != (len(names),):
        raise ValueError(f"initial must have {len(names)} values, got shape {initial.shape}")
    free, idx, lo, hi = _free_and_bounds(names, free, bounds)
    sigma = output_noise_std(Y, tau) if output_std is None else np.asarray(output_std, dtype=float)
    if sigma.shape != (Y.shape[1],) or np.any(sigma <= 0):
        raise ValueError(f"output_std must be {Y.shape[1]} positive values, got {sigma}")
    W, y = stack(Y / sigma[None, :, None], tau / sigma)
    A, b, scale = _scaled_problem(W, y, initial, idx, free)

    # lsq_linear reference
    ref = optimize.lsq_linear(A, b, bounds=(lo * scale, hi * scale), method="bvls", tol=1e-14)
    z_lsq = ref.x
    z0 = np.clip(initial[idx] * scale, lo * scale, hi * scale)
    res = _slsqp(A, b, z0, lo * scale, hi * scale, ftol, maxiter)
    coef = initial.copy()
    coef[idx] = res.x / scale
    coef_lsq = initial.copy()
    coef_lsq[idx] = z_lsq / scale
    # in the scaled variables (of order one where a parameter carries its share of the fit): a
    # parameter the reference puts on a bound at zero has no relative difference
    diff = np.abs(res.x - z_lsq) / np.maximum(np.abs(z_lsq), 1.0)
    r = y - W @ coef
    at_bounds = tuple(f for f, active in zip(free, ref.active_mask) if active != 0)
    return MassFitResult(
        names=names, free=free, coef=coef, coef_lsq=coef_lsq, max_rel_difference=float(diff.max()),
        cost=float(r @ r), residual_rms=residual_rms(Y, tau, coef), output_std=sigma,
        iterations=int(res.nit), success=bool(res.success), message=str(res.message), at_bounds=at_bounds,
    )


def _free_and_bounds(names: tuple[str, ...], free, bounds: dict | None):
    """Checks the free parameters and their bounds against ``names``.

    Returns the free names (tuple), their indices (n_free,) into ``names`` and their lower and
    upper bounds (n_free,) each, in the parameters' units (default ``(0, inf)``, ``None`` = ±inf).
    """
    free = names if free is None else tuple(free)
    unknown = [f for f in free if f not in names]
    if unknown or not free:
        raise ValueError(f"free parameters {unknown or free} not among the parameter names {list(names)}")
    idx = np.array([names.index(f) for f in free])
    bounds = dict(bounds or {})
    bad = [b for b in bounds if b not in free]
    if bad:
        raise ValueError(f"bounds given for {bad}, which are not free parameters {list(free)}")
    lo = np.array([_bound(bounds.get(f, (0.0, None))[0], -np.inf) for f in free])
    hi = np.array([_bound(bounds.get(f, (0.0, None))[1], np.inf) for f in free])
    if np.any(lo > hi):
        raise ValueError(f"lower bound above upper bound for {[f for f, a, b in zip(free, lo, hi) if a > b]}")
    return free, idx, lo, hi


def _scaled_problem(W: np.ndarray, y: np.ndarray, initial: np.ndarray, idx: np.ndarray,
                    free: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The weighted problem ``W pi ≈ y`` (W (m, n), y (m,)) reduced to the free columns ``idx``
    (the held parameters moved to the right-hand side) and scaled (module docstring).

    Returns ``A`` (m, n_free) with unit-norm columns, ``b`` (m,) of unit norm and ``scale``
    (n_free,) with ``z = scale · pi``.
    """
    held = np.setdiff1d(np.arange(W.shape[1]), idx)
    b = y - W[:, held] @ initial[held]
    A = W[:, idx]
    scale = np.linalg.norm(A, axis=0)
    if np.any(scale == 0):
        raise ValueError(f"free parameters {[free[i] for i in np.flatnonzero(scale == 0)]} are not excited by the data")
    # z = scale · pi / ||b||: unit-norm columns and a unit right-hand side make z of order one.
    bnorm = float(np.linalg.norm(b)) or 1.0
    scale = scale / bnorm
    A = A / (scale * bnorm)
    b = b / bnorm
    return A, b, scale


def _slsqp(A: np.ndarray, b: np.ndarray, z0: np.ndarray, lo: np.ndarray, hi: np.ndarray, ftol: float,
           maxiter: int) -> optimize.OptimizeResult:
    """SLSQP on the QR-reduced cost ``||R z − Qᵀb||²`` from ``z0`` within ``lo ≤ z ≤ hi`` (scaled
    variables, (n_free,) each): the same minimiser as ``||A z − b||²`` with n_free rows and
    without squaring cond(A), scaled to 1 at the start so that ``ftol`` is relative."""
    Q, R = linalg.qr(A, mode="economic")
    c = Q.T @ b
    r0 = R @ z0 - c
    c0 = max(float(r0 @ r0), np.finfo(float).tiny)

    def cost(z):
        r = R @ z - c
        return float(r @ r) / c0

    def grad(z):
        return 2.0 * (R.T @ (R @ z - c)) / c0

    return optimize.minimize(
        cost, z0, jac=grad, method="SLSQP", bounds=list(zip(lo, hi)),
        options={"ftol": ftol, "maxiter": maxiter},
    )


def _bound(value, default: float) -> float:
    return default if value is None else float(value)
