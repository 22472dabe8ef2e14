"""Ordinary and weighted least squares with the statistics of seed 004 (eqs. 10–12).

Data convention (the whole package): a regressor ``Y`` of shape (N, k, n) — N samples,
k outputs (actuator torques/forces), n parameters — and outputs ``tau`` (N, k) with
``tau ≈ Y @ pi``. :func:`stack` turns them into ``W`` (k·N, n) and ``y`` (k·N,), with the
rows of one output kept together (output-major), as seed 004 arranges them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import linalg

#: A parameter whose relative standard deviation exceeds this (in %) is poorly identified.
POORLY_IDENTIFIED_PERCENT = 10.0


def check_regression_data(Y: np.ndarray, tau: np.ndarray, names=None) -> tuple[np.ndarray, np.ndarray]:
    """Validate and return ``Y`` (N, k, n) and ``tau`` (N, k) as float arrays."""
    Y = np.asarray(Y, dtype=float)
    tau = np.asarray(tau, dtype=float)
    if Y.ndim != 3 or tau.shape != Y.shape[:2]:
        raise ValueError(f"expected Y (N, k, n) and tau (N, k); got Y {Y.shape}, tau {tau.shape}")
    if names is not None and len(names) != Y.shape[2]:
        raise ValueError(f"{len(names)} parameter names for a regressor with {Y.shape[2]} columns")
    if not (np.all(np.isfinite(Y)) and np.all(np.isfinite(tau))):
        raise ValueError("regressor or outputs contain NaN or infinite values")
    return Y, tau


def stack(Y: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Y`` (N, k, n), ``tau`` (N, k) → ``W`` (k·N, n), ``y`` (k·N,), output-major rows."""
    N, k, n = Y.shape
    return Y.transpose(1, 0, 2).reshape(k * N, n), tau.T.reshape(k * N)


def output_noise_std(Y: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Noise standard deviation of each output (k,), from its ordinary-least-squares residual.

    ``sigma_j² = ||rho_j||² / (N - n/k)`` (the n degrees of freedom shared out over the k
    outputs). On noise-free data the residual is at rounding level; each sigma_j is then
    floored at ``1e-9 × RMS(tau_j)`` so that weights stay finite and comparable.
    """
    Y, tau = check_regression_data(Y, tau)
    N, k, n = Y.shape
    W, y = stack(Y, tau)
    coef = linalg.lstsq(W, y, lapack_driver="gelsd")[0]
    rho = (y - W @ coef).reshape(k, N)
    sigma = np.sqrt(np.sum(rho**2, axis=1) / max(N - n / k, 1.0))
    floor = 1e-9 * np.sqrt(np.mean(tau**2, axis=0))
    sigma = np.maximum(sigma, floor)
    if np.any(sigma == 0):
        raise ValueError(f"outputs {np.flatnonzero(sigma == 0).tolist()} are identically zero: cannot weight them")
    return sigma


@dataclass(frozen=True)
class LeastSquaresResult:
    """Estimate with its statistics (seed 004).

    Attributes:
        names: parameter names (n).
        coef: estimate (n,).
        covariance: ``sigma² (WᵀW)⁻¹`` of the (weighted) problem (n, n).
        sigma2: residual variance of the (weighted) rows, ``||y − W pi||² / (r − n)``.
        cond: condition number of the (weighted) ``W``.
        residual_rms: RMS of the unweighted residual of each output (k,), output units.
        output_std: per-output standard deviations used as weights (k,), None for OLS.
        method: "OLS" or "WLS".
    """

    names: tuple[str, ...]
    coef: np.ndarray
    covariance: np.ndarray
    sigma2: float
    cond: float
    residual_rms: np.ndarray
    output_std: np.ndarray | None = None
    method: str = "OLS"
    poorly_identified_percent: float = field(default=POORLY_IDENTIFIED_PERCENT)

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

    def to_dict(self) -> dict:
        return {
            "method": self.method,
            "parameters": {
                nm: {"value": float(v), "std": float(s), "rel_std_percent": float(p)}
                for nm, v, s, p in zip(self.names, self.coef, self.std, self.rel_std_percent)
            },
            "sigma2": float(self.sigma2),
            "cond": float(self.cond),
            "residual_rms": self.residual_rms.tolist(),
            "output_std": None if self.output_std is None else self.output_std.tolist(),
            "poorly_identified": list(self.poorly_identified),
        }


def _solve_with_statistics(W: np.ndarray, y: np.ndarray, names) -> tuple[np.ndarray, np.ndarray, float, float]:
    """QR solution of ``min ||y − W pi||`` and its covariance, sigma², cond(W)."""
    r, n = W.shape
    if r <= n:
        raise ValueError(f"{r} equations for {n} parameters: need more equations than parameters")
    Q, R = linalg.qr(W, mode="economic")
    s = linalg.svdvals(R)
    tol = max(r, n) * np.finfo(float).eps * s[0]
    if s[-1] <= tol:
        raise ValueError(
            f"the regressor is rank deficient (rank {int(np.sum(s > tol))} < {n} parameters "
            f"{list(names)}): identify the base parameters instead (base_parameters / identify_base)"
        )
    coef = linalg.solve_triangular(R, Q.T @ y)
    rho = y - W @ coef
    sigma2 = float(rho @ rho) / (r - n)
    Rinv = linalg.solve_triangular(R, np.eye(n))
    return coef, sigma2 * (Rinv @ Rinv.T), sigma2, float(s[0] / s[-1])


def ols(Y: np.ndarray, tau: np.ndarray, names) -> LeastSquaresResult:
    """Ordinary least squares on ``Y`` (N, k, n), ``tau`` (N, k), solved by QR."""
    Y, tau = check_regression_data(Y, tau, names)
    W, y = stack(Y, tau)
    coef, cov, sigma2, cond = _solve_with_statistics(W, y, names)
    return LeastSquaresResult(
        names=tuple(names), coef=coef, covariance=cov, sigma2=sigma2, cond=cond,
        residual_rms=_residual_rms(Y, tau, coef), method="OLS",
    )


def wls(Y: np.ndarray, tau: np.ndarray, names, output_std: np.ndarray | None = None) -> LeastSquaresResult:
    """Weighted least squares: each output's rows divided by its noise std.

    ``output_std`` (k,) defaults to :func:`output_noise_std` (each output's OLS residual).
    """
    Y, tau = check_regression_data(Y, tau, names)
    sigma = output_noise_std(Y, tau) if output_std is None else np.asarray(output_std, dtype=float)
    if sigma.shape != (Y.shape[1],) or np.any(sigma <= 0):
        raise ValueError(f"output_std must be {Y.shape[1]} positive values, got {sigma}")
    W, y = stack(Y / sigma[None, :, None], tau / sigma)
    coef, cov, sigma2, cond = _solve_with_statistics(W, y, names)
    return LeastSquaresResult(
        names=tuple(names), coef=coef, covariance=cov, sigma2=sigma2, cond=cond,
        residual_rms=_residual_rms(Y, tau, coef), output_std=sigma, method="WLS",
    )


def _residual_rms(Y: np.ndarray, tau: np.ndarray, coef: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean((tau - Y @ coef) ** 2, axis=0))
