"""Ordinary and weighted least squares with the statistics of the power-model paper (eqs. 10–12).

Data convention (the whole package): a regressor ``Y`` of shape (N, k, n) — N samples,
k outputs (actuator torques/forces), n parameters — and outputs ``tau`` (N, k) with
``tau ≈ Y @ pi``. :func:`stack` turns them into ``W`` (k·N, n) and ``y`` (k·N,), with the
rows of one output kept together (output-major), as the power-model paper arranges them. A NaN in ``tau``
leaves that row (one output of one sample) out of the fit: :func:`check_regression_data`
zeroes it, and the statistics count only the rows whose regressor is not all zero (such a
row carries no information, whatever its output).

Covariance of the estimate. Seed 004's ``C = sigma² (WᵀW)⁻¹`` assumes white residuals. On
measured data they are not: the parallel low-pass leaves the current noise correlated over
a few decimated samples, and the noise of positions differentiated twice (encoder
quantisation) enters the regressor with a spectrum rising as f⁴ up to the cut-off, so most
of the residual variance sits at high frequency, where the (low-frequency) regressor columns
do not pick it up. ``sigma² (WᵀW)⁻¹`` then errs both ways (too small for the carriage
terms, several times too large for the link terms, in our tests). The default is therefore
the heteroscedasticity and autocorrelation consistent (HAC) sandwich of Newey & West (1987):

    C = (WᵀW)⁻¹ S (WᵀW)⁻¹ · r/(r − n),   S = Γ₀ + Σ_{l=1..L} (1 − l/(L+1)) (Γ_l + Γ_lᵀ),
    Γ_l = Σ_t g_t g_{t−l}ᵀ,   g_t = Σ_j Y_tjᵀ rho_tj  (the score of sample t, all outputs)

with the rule-of-thumb bandwidth ``L = floor(4 (N/100)^(2/9))`` (Newey & West 1994): it
weighs the residual at the frequencies of the regressor, which is what the estimate's error
is made of (checked against Monte Carlo spreads in ``tests/test_ident_noise.py``). ``lags=0``
gives back the white-residual formula of the power-model paper.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np

#: A parameter whose relative standard deviation exceeds this (in %) is poorly identified.
POORLY_IDENTIFIED_PERCENT = 10.0


def check_regression_data(Y: np.ndarray, tau: np.ndarray, names=None) -> tuple[np.ndarray, np.ndarray]:
    """Validate and return ``Y`` (N, k, n) and ``tau`` (N, k) as float arrays; the rows where
    ``tau`` is NaN (left out) come back zeroed, in ``Y`` and ``tau``."""
    Y = np.asarray(Y, dtype=float)
    tau = np.asarray(tau, dtype=float)
    if Y.ndim != 3 or tau.shape != Y.shape[:2]:
        raise ValueError(f"expected Y (N, k, n) and tau (N, k); got Y {Y.shape}, tau {tau.shape}")
    if names is not None and len(names) != Y.shape[2]:
        raise ValueError(f"{len(names)} parameter names for a regressor with {Y.shape[2]} columns")
    left_out = np.isnan(tau)
    if left_out.any():
        Y = np.where(left_out[..., None], 0.0, Y)
        tau = np.where(left_out, 0.0, tau)
    if not (np.all(np.isfinite(Y)) and np.all(np.isfinite(tau))):
        raise ValueError("regressor or outputs contain NaN or infinite values (outside the rows left out)")
    return Y, tau


def informative_rows(Y: np.ndarray) -> np.ndarray:
    """(N, k) bool: the rows of ``Y`` (N, k, n) that are not all zero (the rows a fit counts)."""
    return np.any(Y != 0.0, axis=2)


def stack(Y: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Y`` (N, k, n), ``tau`` (N, k) → ``W`` (k·N, n), ``y`` (k·N,), output-major rows."""
    N, k, n = Y.shape
    return Y.transpose(1, 0, 2).reshape(k * N, n), tau.T.reshape(k * N)


def newey_west_lags(n_samples: int) -> int:
    """Rule-of-thumb HAC bandwidth ``floor(4 (N/100)^(2/9))`` (Newey & West 1994) for N samples."""
    return int(np.floor(4.0 * (n_samples / 100.0) ** (2.0 / 9.0)))


def output_noise_std(Y: np.ndarray, tau: np.ndarray, coef: np.ndarray | None = None) -> np.ndarray:
    """Noise standard deviation of each output (k,), from its residual at ``coef``.

    ``sigma_j² = ||rho_j||² / (N_j − n/k)`` with ``N_j`` the informative rows of output j
    (the n degrees of freedom shared out over the k outputs); ``coef`` defaults to the ordinary-least-squares estimate. On noise-free data the
    residual is at rounding level; each sigma_j is then floored at ``1e-9 × RMS(tau_j)`` so
    that weights stay finite and comparable. An output with no informative row gets 1.
    """
    from scipy import linalg    # on first use: the config reads this module's constants
    Y, tau = check_regression_data(Y, tau)
    N, k, n = Y.shape
    if coef is None:
        W, y = stack(Y, tau)
        coef = linalg.lstsq(W, y, lapack_driver="gelsd")[0]
    rho = tau - Y @ coef
    rows = informative_rows(Y).sum(axis=0)
    sigma = np.sqrt(np.sum(rho**2, axis=0) / np.maximum(rows - n / k, 1.0))
    floor = 1e-9 * np.sqrt(np.sum(tau**2, axis=0) / np.maximum(rows, 1))
    sigma = np.where(rows > 0, np.maximum(sigma, floor), 1.0)   # an output without rows weighs nothing
    if np.any(sigma == 0):
        raise ValueError(f"outputs {np.flatnonzero(sigma == 0).tolist()} are identically zero: cannot weight them")
    return sigma


@dataclass(frozen=True)
class LeastSquaresResult:
    """Estimate with its statistics (the power-model paper).

    Attributes:
        names: parameter names (n).
        coef: estimate (n,).
        covariance: covariance of the estimate (n, n): the HAC sandwich with ``lags`` lags,
            or ``sigma² (WᵀW)⁻¹`` of the (weighted) problem when ``lags == 0``.
        sigma2: residual variance of the (weighted) rows, ``||y − W pi||² / (r − n)``.
        cond: condition number of the (weighted) ``W``.
        residual_rms: RMS of the unweighted residual of each output (k,), output units.
        output_std: per-output standard deviations used as weights (k,), None for OLS.
        method: "OLS" or "WLS".
        lags: bandwidth of the HAC covariance (0: white-residual formula).
        triangle: R (n, n) of the QR of the (weighted) regressor the estimate solved, for a
            refit of data near it (:func:`estimate` ``near=``); None: not kept.
    """

    names: tuple[str, ...]
    coef: np.ndarray
    covariance: np.ndarray
    sigma2: float
    cond: float
    residual_rms: np.ndarray
    output_std: np.ndarray | None = None
    method: str = "OLS"
    lags: int = 0
    poorly_identified_percent: float = field(default=POORLY_IDENTIFIED_PERCENT)
    triangle: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of each parameter (n,)."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def rel_std_percent(self) -> np.ndarray:
        """``100 sigma_i / |pi_i|`` (n,); infinite where the estimate is zero."""
        with np.errstate(divide="ignore"):
            return 100.0 * self.std / np.abs(self.coef)

    @property
    def poorly_identified(self) -> tuple[str, ...]:
        """Names of the parameters with %sigma above the threshold (default 10 %)."""
        return tuple(nm for nm, p in zip(self.names, self.rel_std_percent) if not p <= self.poorly_identified_percent)

    @property
    def covariance_method(self) -> str:
        """How :attr:`covariance` was computed, in words."""
        return f"Newey-West HAC, {self.lags} lags" if self.lags else "sigma2 (W^T W)^-1 (white residuals)"


@dataclass(frozen=True)
class _Solved:
    """One QR solution of the least squares (:func:`_solve`): the estimate ``coef`` (n,), the
    factors ``R`` (n, n), the singular values ``s`` of ``R`` and the informative rows ``r``."""

    coef: np.ndarray
    R: np.ndarray
    s: np.ndarray
    r: int


def _solve(Y: np.ndarray, tau: np.ndarray, names) -> _Solved:
    """QR solution of ``min sum_t ||tau_t − Y_t pi||²`` (no statistics: the estimate alone is
    what a refit needs, :func:`estimate`)."""
    return _solve_many(Y, tau[..., None], names)[0]


def _solve_many(Y: np.ndarray, taus: np.ndarray, names) -> tuple[_Solved, np.ndarray]:
    """:func:`_solve` of ``Y`` (N, k, n) for each of the m right-hand sides ``taus`` (N, k, m)
    on one factorisation: the first one's :class:`_Solved` and every estimate (n, m)."""
    from scipy import linalg    # on first use: the config reads this module's constants
    N, k, n = Y.shape
    W = stack(Y, taus[..., 0])[0]
    B = taus.transpose(1, 0, 2).reshape(k * N, -1)         # output-major rows, as stack's
    r = int(informative_rows(Y).sum())
    if r <= n:
        raise ValueError(f"{r} equations for {n} parameters: need more equations than parameters")
    # one Householder QR of [W B]: its triangle holds R (n, n) and QᵀB (its last columns), so Q
    # (r, n) is never formed (forming it costs as much again as the factorisation)
    RB = cast(np.ndarray, np.linalg.qr(np.concatenate([W, B], axis=1), mode="r"))
    R, qtb = RB[:n, :n], RB[:n, n:]
    s = linalg.svdvals(R)
    tol = max(r, n) * np.finfo(float).eps * s[0]
    if s[-1] <= tol:
        raise ValueError(
            f"the regressor is rank deficient (rank {int(np.sum(s > tol))} < {n} parameters "
            f"{list(names)}): identify the base parameters instead (base_parameters / identify_base)"
        )
    coef = linalg.solve_triangular(R, qtb)
    return _Solved(coef[:, 0], R, s, r), coef


def _statistics(Y: np.ndarray, tau: np.ndarray, solved: _Solved, lags: int | None
                ) -> tuple[np.ndarray, float, float, int]:
    """The covariance of a :func:`_solve` estimate on the same ``Y``, ``tau`` (module docstring),
    sigma², cond(W) and the lags used."""
    from scipy import linalg
    N, k, n = Y.shape
    coef, R, r = solved.coef, solved.R, solved.r
    rho = tau - Y @ coef
    sigma2 = float(np.sum(rho**2)) / (r - n)
    Rinv = linalg.solve_triangular(R, np.eye(n))
    bread = Rinv @ Rinv.T  # (WᵀW)⁻¹
    lags = min(newey_west_lags(N) if lags is None else int(lags), N - 1)
    if lags < 0:
        raise ValueError(f"lags must be >= 0, got {lags}")
    if lags == 0:
        cov = sigma2 * bread
    else:
        g = np.einsum("tjn,tj->tn", Y, rho)  # per-sample scores
        meat = g.T @ g
        for lag in range(1, lags + 1):
            gamma = g[lag:].T @ g[:-lag]
            meat += (1.0 - lag / (lags + 1.0)) * (gamma + gamma.T)
        cov = bread @ meat @ bread * (r / (r - n))
    return 0.5 * (cov + cov.T), sigma2, float(solved.s[0] / solved.s[-1]), lags


def estimate(Y: np.ndarray, tau: np.ndarray, names, output_std: np.ndarray | None = None,
             near: np.ndarray | None = None) -> np.ndarray:
    """The estimate (n,) of :func:`ols` (``output_std`` None) or of :func:`wls` with the known
    output weights ``output_std`` (k,), without its statistics: the same values as theirs
    ``.coef``, at the cost of the solution alone (a refit of data read again, whose covariance
    nobody reads). ``near``: the triangle R (n, n) of a regressor near this one, weighted alike
    (:attr:`LeastSquaresResult.triangle` of the fit of the data before they were read again):
    the least squares of :data:`PRECONDITIONED_FROM` columns or more are then solved by
    iterations preconditioned by it (``_preconditioned``) instead of a factorisation of their
    own, to the same solution within rounding (where they do not converge: by the factorisation)."""
    Y, tau = check_regression_data(Y, tau, names)
    if output_std is not None:
        w = 1.0 / _checked_std(output_std, Y.shape[1])
        Y, tau = Y * w[None, :, None], tau * w
    if near is not None and Y.shape[2] >= PRECONDITIONED_FROM:
        coef = _preconditioned(*stack(Y, tau), near)
        if coef is not None:
            return coef
    return _solve(Y, tau, names).coef


#: ``_preconditioned``: iterations at most, and the decrease of the preconditioned normal
#: equations' residual (||R⁻ᵀ Wᵀ r||) at which the solution is taken (rounding level)
PRECONDITIONED_ITERATIONS = 40
PRECONDITIONED_RTOL = 1e-15
#: columns from which :func:`estimate` ``near=`` iterates: a Householder QR of r rows costs
#: about 2 r n² flops, an iteration 4 r n, and about ten iterations reach rounding level, so
#: with fewer columns the factorisation is as cheap (and its result the one of every other fit)
PRECONDITIONED_FROM = 40


def _preconditioned(W: np.ndarray, y: np.ndarray, R: np.ndarray) -> np.ndarray | None:
    """``argmin ||W x − y||`` for ``W`` (r, n) near a regressor whose QR triangle is ``R``
    (n, n): conjugate gradients on the normal equations (CGLS) of ``W R⁻¹``, whose singular
    values are near 1 (``W`` is the regressor ``R`` factorised, read again with a count's
    rounding moved), so that it converges to rounding level in a few iterations, each two
    products with ``W`` (4 r n flops; the Householder QR of ``W`` takes about r n²/2 of them,
    and reads the matrix once per column). None if the residual has not fallen by
    :data:`PRECONDITIONED_RTOL` within :data:`PRECONDITIONED_ITERATIONS`."""
    from scipy import linalg
    x = np.zeros(W.shape[1])
    r = np.array(y, dtype=float)
    s = linalg.solve_triangular(R, W.T @ r, trans="T")
    p = s.copy()
    gamma = start = float(s @ s)
    if gamma == 0.0:
        return x
    for _ in range(PRECONDITIONED_ITERATIONS):
        t = linalg.solve_triangular(R, p)
        q = W @ t
        alpha = gamma / float(q @ q)
        x += alpha * t
        r -= alpha * q
        s = linalg.solve_triangular(R, W.T @ r, trans="T")
        new = float(s @ s)
        if new <= PRECONDITIONED_RTOL ** 2 * start:
            return x
        p = s + (new / gamma) * p
        gamma = new
    return None


def estimate_columns(Y: np.ndarray, columns: np.ndarray, names, output_std: np.ndarray | None = None
                     ) -> np.ndarray:
    """:func:`estimate` for each of the m right-hand sides ``columns`` (N, k, m) on the same
    ``Y`` (N, k, n), on one factorisation of it: (n, m). A NaN leaves its row out, and must
    leave it out of every column (the rows of one regressor)."""
    columns = np.asarray(columns, dtype=float)
    left_out = np.isnan(columns)
    if columns.ndim != 3 or np.any(left_out != left_out[..., :1]):
        raise ValueError(f"expected columns (N, k, m) with the same rows left out in each, got {columns.shape}")
    Y, _ = check_regression_data(Y, columns[..., 0], names)
    columns = np.where(left_out, 0.0, columns)
    if output_std is None:
        return _solve_many(Y, columns, names)[1]
    w = 1.0 / _checked_std(output_std, Y.shape[1])
    return _solve_many(Y * w[None, :, None], columns * w[None, :, None], names)[1]


def _checked_std(output_std, k: int) -> np.ndarray:
    sigma = np.asarray(output_std, dtype=float)
    if sigma.shape != (k,) or np.any(sigma <= 0):
        raise ValueError(f"output_std must be {k} positive values, got {sigma}")
    return sigma


def ols(Y: np.ndarray, tau: np.ndarray, names, lags: int | None = None) -> LeastSquaresResult:
    """Ordinary least squares on ``Y`` (N, k, n), ``tau`` (N, k), solved by QR.

    ``lags``: HAC bandwidth (module docstring); default the Newey–West rule, 0 for white residuals.
    """
    Y, tau = check_regression_data(Y, tau, names)
    solved = _solve(Y, tau, names)
    cov, sigma2, cond, lags = _statistics(Y, tau, solved, lags)
    return LeastSquaresResult(
        names=tuple(names), coef=solved.coef, covariance=cov, sigma2=sigma2, cond=cond,
        residual_rms=residual_rms(Y, tau, solved.coef), method="OLS", lags=lags, triangle=solved.R,
    )


def wls(Y: np.ndarray, tau: np.ndarray, names, output_std: np.ndarray | None = None,
        lags: int | None = None, max_iterations: int = 10, rtol: float = 1e-3) -> LeastSquaresResult:
    """Weighted least squares: each output's rows divided by its noise std.

    ``output_std`` (k,): known noise std of each output. By default it is estimated from
    the residuals, iteratively (feasible generalised least squares): start from the OLS
    residual, refit with those weights, re-estimate each output's std from the new residual,
    until the weights change by less than ``rtol`` (at most ``max_iterations`` refits).
    One step from OLS is not enough: the OLS estimate is dominated by the largest outputs
    (newtons on the carriages), so the residual of the small ones (newton-metres on the
    links) is mostly misfit, their weight comes out far too small and sigma² too small.
    ``lags``: HAC bandwidth of the covariance (module docstring).
    """
    Y, tau = check_regression_data(Y, tau, names)
    if output_std is not None:
        sigma = _checked_std(output_std, Y.shape[1])
        iterations = 1
    else:
        sigma = output_noise_std(Y, tau)
        iterations = max_iterations
    for _ in range(iterations):        # the statistics once, of the last solution
        w = 1.0 / sigma
        Yw, tauw = Y * w[None, :, None], tau * w
        solved = _solve(Yw, tauw, names)
        coef = solved.coef
        if output_std is not None:
            break
        new_sigma = output_noise_std(Y, tau, coef)
        converged = np.all(np.abs(new_sigma / sigma - 1.0) < rtol)
        sigma = new_sigma
        if converged:
            break
    cov, sigma2, cond, used_lags = _statistics(Yw, tauw, solved, lags)
    return LeastSquaresResult(
        names=tuple(names), coef=coef, covariance=cov, sigma2=sigma2, cond=cond,
        residual_rms=residual_rms(Y, tau, coef), output_std=1.0 / w, method="WLS", lags=used_lags,
        triangle=solved.R,
    )


def compensated(fit: LeastSquaresResult, Y: np.ndarray, tau: np.ndarray, draws: Sequence[np.ndarray]
                ) -> LeastSquaresResult:
    """``fit`` (of ``Y`` (N, k, n), ``tau`` (N, k), with its output weights) with its estimate
    corrected for the noise in the regressor: bias-compensated least squares,

        pi = (WᵀW − D)⁻¹ Wᵀy,   D = Σ_rows cov(W row),

    the covariance of each (weighted) row of the regressor estimated from ``draws`` (each
    (N, k, n)): the same motion read again by other instruments of the same kind (the encoders
    with their count edges moved), whose regressors differ from each other by that noise only.
    Noise in the regressor adds ``D`` to ``WᵀW`` on average and shrinks the plain estimate
    towards zero in the directions it excites (errors in variables): the encoders' rounding,
    differentiated twice, does so to the inertial terms. The covariance is the fit's (``D`` is
    small against ``WᵀW``; the draws' spread, which the caller adds, is the noise's own part).
    Fewer than two draws, or a ``WᵀW − D`` that is not positive definite: ``fit`` unchanged."""
    if len(draws) < 2:
        return fit
    from scipy import linalg    # on first use: the config reads this module's constants
    Y, tau = check_regression_data(Y, tau)
    kept = informative_rows(Y)[..., None]      # the rows the fit counts; the draws keep only those
    w = np.ones(Y.shape[1]) if fit.output_std is None else 1.0 / np.asarray(fit.output_std)
    W, y = stack(Y * w[None, :, None], tau * w)
    rows = np.array([stack(np.where(kept, Yk, 0.0) * w[None, :, None], tau)[0] for Yk in draws])
    spread = rows - rows.mean(axis=0)
    D = np.einsum("drn,drm->nm", spread, spread) / (len(draws) - 1)
    s = 1.0 / np.sqrt(np.maximum(np.einsum("rn,rn->n", W, W), np.finfo(float).tiny))
    try:
        factor = linalg.cho_factor(s[:, None] * (W.T @ W - D) * s[None, :])
    except linalg.LinAlgError:
        return fit
    coef = s * linalg.cho_solve(factor, s * (W.T @ y))
    return replace(fit, coef=coef, residual_rms=residual_rms(Y, tau, coef))


def residual_rms(Y: np.ndarray, tau: np.ndarray, coef: np.ndarray) -> np.ndarray:
    """RMS (k,) of each output's residual over its informative rows."""
    rows = np.maximum(informative_rows(Y).sum(axis=0), 1)
    return np.sqrt(np.sum((tau - Y @ coef) ** 2, axis=0) / rows)
