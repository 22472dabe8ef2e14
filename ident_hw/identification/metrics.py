"""Validation metrics of identified torques against measured ones (held-out data)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ValidationMetrics:
    """Torque-prediction quality on one data set.

    Attributes:
        rms: RMS error of each output (k,), output units (N·m or N).
        nrms_percent: ``100 × rms_j / RMS(tau_j)`` (k,).
        d_tau_percent: ``100 × mean_t(||tau_t − tau_hat_t|| / ||tau_t||)`` over the samples
            with ``||tau_t|| > 0`` (the relative error of the issue).
        j_rmse: ``sqrt(mean_t ||tau_hat_t − tau_t||²)`` (the SVD-DLS paper, eq. 87), mixed units as in the paper.
    """

    rms: np.ndarray
    nrms_percent: np.ndarray
    d_tau_percent: float
    j_rmse: float


def validation_metrics(tau: np.ndarray, tau_hat: np.ndarray) -> ValidationMetrics:
    """Compare measured ``tau`` (N, k) with predicted ``tau_hat`` (N, k)."""
    tau = np.asarray(tau, dtype=float)
    tau_hat = np.asarray(tau_hat, dtype=float)
    if tau.ndim != 2 or tau.shape != tau_hat.shape:
        raise ValueError(f"expected tau and tau_hat of one shape (N, k), got {tau.shape} and {tau_hat.shape}")
    err = tau_hat - tau
    rms = np.sqrt(np.mean(err**2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        nrms = 100.0 * rms / np.sqrt(np.mean(tau**2, axis=0))
    norm_tau = np.linalg.norm(tau, axis=1)
    moving = norm_tau > 0
    d_tau = 100.0 * float(np.mean(np.linalg.norm(err[moving], axis=1) / norm_tau[moving])) if moving.any() else np.nan
    j_rmse = float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
    return ValidationMetrics(rms=rms, nrms_percent=nrms, d_tau_percent=d_tau, j_rmse=j_rmse)
