"""Online (streaming) estimators: SVD-DLS (the SVD-DLS paper, eqs. 61–83) and two RLS baselines.

Interface (scikit-learn style, one convention for all three)::

    est = SVDDLS(n_params=18, forgetting=0.998, threshold=100, scale=cad, output_std=sigma)
    est.warm_start(coef, information)      # optional: from an offline fit
    est.partial_fit(Y, tau)                # Y (k, n), tau (k,) for one sample,
                                           # or Y (N, k, n), tau (N, k) for a block
    est.coef_                              # (n,) current estimate, physical units
    est.predict(Y)                         # Y @ coef_
    est.covariance_                        # (n, n) current parameter covariance (physical units)

``Y`` is the per-sample regressor as the model returns it (``tau = Y @ pi``); the paper's
``D_t`` is ``Y_tᵀ`` (n, k). A block is processed sample by sample, in order, exactly as if
each sample had been passed alone.

Scaling. Inside, every estimator works on ``theta = pi / scale`` and on outputs divided by
``output_std``: ``D_t = diag(scale) Y_tᵀ diag(1/output_std)``. With ``scale`` the typical
magnitudes of the parameters (CAD values) and ``output_std`` each output's noise level,
the entries of ``R_t`` are signal-to-noise ratios of comparable parameters, so kilograms of
carriage and kg·m² of link inertia, newtons and newton-metres share one scale and one
eigenvalue threshold means the same for every direction. (RLS is invariant to this scaling
apart from its initial covariance; SVD-DLS's threshold is not.)

Information matrix with forgetting ``lambda`` (eq. 65): ``R_t = lambda R_{t−1} + D_t D_tᵀ``.

- :class:`RLS`: recursive least squares with exponential forgetting, covariance form
  (``P = R⁻¹`` updated by the matrix inversion lemma, a k × k solve per sample). In directions
  the data stops exciting, ``P`` grows as ``lambda^−t``: the classic wind-up.
- :class:`DampedRLS`: regularised RLS (Gunnarsson 1996): ``R_t = lambda R_{t−1} + D_t D_tᵀ
  + (1 − lambda) delta I`` with the same term pulling towards a prior (the warm-start
  estimate): it minimises ``sum lambda^{t−T} ||e_T||² + delta ||theta − theta_prior||²``, so
  the covariance stays below ``1/delta``, at the price of a bias towards the prior.
- :class:`SVDDLS`: the estimate moves only inside the excited subspace of ``R_t``
  (eigenvalues at or above ``threshold``):
  ``theta_t = theta_{t−1} + V_p Lambda_p⁻¹ V_pᵀ D_t e_t`` (eq. 77), which is eq. 83 (the
  projector removes nothing from a vector already in span V_p): the component in the
  unexcited directions is held. The excited subspace is recomputed at every sample, so it is
  never stale: with few held directions LAPACK ``dsyevr`` finds only those and the rest is a
  Cholesky solve, otherwise the full decomposition (``dsyevd``) is used; the update's cost is
  in ``benchmarks/README.md``.
  Threshold (absolute, in the scaled units above): a direction ``v`` of ``R_t`` with
  eigenvalue ``mu`` is known to a standard deviation ``1/sqrt(mu)`` in units of the
  parameter scale (outputs in units of their noise). It counts as excited while
  ``mu >= threshold``; the default ``100`` holds every direction whose recent data would
  pin it down no better than 10 % of a typical parameter value. A pure relative threshold
  (``mu / mu_max``) would not do: when the excitation stops, every old direction decays at
  the same rate ``lambda^t`` and their ratios never change.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve, lapack, solve

class RecursiveEstimator:
    """The recursive estimators' common part (:class:`RLS`, :class:`DampedRLS`, :class:`SVDDLS`):
    shapes, scaling, block handling, prediction, warm start.

    Args:
        n_params: n. forgetting: lambda in (0, 1].
        scale: (n,) typical magnitude of each parameter (non-zero), default ones.
        output_std: (k,) noise level of each output, default ones (k from the first data).
    """

    def __init__(self, n_params: int, forgetting: float = 0.999, scale=None, output_std=None):
        if n_params < 1:
            raise ValueError(f"n_params must be >= 1, got {n_params}")
        if not 0 < forgetting <= 1:
            raise ValueError(f"forgetting factor must lie in (0, 1], got {forgetting}")
        self.n_params = int(n_params)
        self.forgetting = float(forgetting)
        self.scale = np.ones(self.n_params) if scale is None else np.abs(np.asarray(scale, dtype=float))
        if self.scale.shape != (self.n_params,) or np.any(self.scale == 0):
            raise ValueError(f"scale must be {self.n_params} non-zero magnitudes, got {scale}")
        self.output_std = None if output_std is None else np.asarray(output_std, dtype=float)
        if self.output_std is not None and (self.output_std.ndim != 1 or np.any(self.output_std <= 0)):
            raise ValueError(f"output_std must be a vector of positive values, got {output_std}")
        self._theta = np.zeros(self.n_params)  # scaled estimate pi / scale
        self.n_samples_seen_ = 0

    @property
    def covariance_(self) -> np.ndarray:
        """(n, n) the current parameter covariance in physical units: each estimator's own."""
        raise NotImplementedError

    @property
    def coef_(self) -> np.ndarray:
        """Current estimate (n,), physical units."""
        return self._theta * self.scale

    def partial_fit(self, Y: np.ndarray, tau: np.ndarray) -> "RecursiveEstimator":
        """Update with one sample (``Y`` (k, n), ``tau`` (k,)) or a block (N, k, n), (N, k)."""
        Y = np.asarray(Y, dtype=float)
        tau = np.asarray(tau, dtype=float)
        if Y.ndim == 2:
            Y, tau = Y[None], tau[None]
        if Y.ndim != 3 or Y.shape[2] != self.n_params or tau.shape != Y.shape[:2]:
            raise ValueError(
                f"expected Y (k, {self.n_params}) and tau (k,), or blocks (N, k, {self.n_params}) and (N, k); "
                f"got {Y.shape} and {tau.shape}"
            )
        if self.output_std is not None:
            if self.output_std.shape != (Y.shape[1],):
                raise ValueError(f"output_std has {self.output_std.size} values for {Y.shape[1]} outputs")
            Y = Y / self.output_std[:, None]
            tau = tau / self.output_std
        D_all = (Y * self.scale).transpose(0, 2, 1).copy()  # (N, n, k), contiguous per sample
        for D, s in zip(D_all, tau):
            self._update(D, s)
        self.n_samples_seen_ += len(Y)
        return self

    def predict(self, Y: np.ndarray) -> np.ndarray:
        """Predicted outputs ``Y @ coef_``: (k,) for one sample, (N, k) for a block."""
        return np.asarray(Y, dtype=float) @ self.coef_

    def warm_start(self, coef: np.ndarray, information: np.ndarray) -> "RecursiveEstimator":
        """Start from an offline estimate ``coef`` (n,) and its information matrix (n, n).

        ``information`` is the ``R`` the stream would have built, in physical units (with the
        outputs divided by ``output_std``); from an offline block use :func:`offline_information`.
        """
        coef = np.asarray(coef, dtype=float)
        information = np.asarray(information, dtype=float)
        if coef.shape != (self.n_params,) or information.shape != (self.n_params, self.n_params):
            raise ValueError(f"warm start needs coef ({self.n_params},) and information ({self.n_params}, {self.n_params})")
        self._theta = coef / self.scale
        R = information * np.outer(self.scale, self.scale)
        self._set_information(0.5 * (R + R.T))
        return self

    def _update(self, D: np.ndarray, s: np.ndarray) -> None:
        raise NotImplementedError

    def _set_information(self, R: np.ndarray) -> None:
        raise NotImplementedError


def offline_information(Y: np.ndarray, forgetting: float, output_std=None) -> np.ndarray:
    """Information matrix (physical units) for a warm start from an offline block ``Y`` (N, k, n).

    ``mean_t(Y_tᵀ Y_t) / (1 − lambda)`` (outputs divided by ``output_std`` if given): the
    stationary value of ``R_t`` if the stream kept exciting as the offline data did (with
    ``lambda = 1``: the plain sum ``WᵀW``).
    """
    Y = np.asarray(Y, dtype=float)
    if output_std is not None:
        Y = Y / np.asarray(output_std, dtype=float)[:, None]
    W = Y.reshape(-1, Y.shape[-1])
    if forgetting >= 1:
        return W.T @ W
    return (W.T @ W) / (len(Y) * (1.0 - forgetting))


class RLS(RecursiveEstimator):
    """Recursive least squares with exponential forgetting (covariance form).

    Args:
        n_params, forgetting, scale, output_std: see :class:`SVDDLS`.
        initial_covariance: ``P_0 = initial_covariance × I`` (scaled units) without a warm start.
    """

    def __init__(self, n_params: int, forgetting: float = 0.999, initial_covariance: float = 1e6,
                 scale=None, output_std=None):
        super().__init__(n_params, forgetting, scale, output_std)
        self._P = initial_covariance * np.eye(self.n_params)

    @property
    def covariance_(self) -> np.ndarray:
        """``R_t⁻¹`` in physical units (n, n)."""
        return self._P * np.outer(self.scale, self.scale)

    def _set_information(self, R):
        self._P = np.linalg.inv(R)

    def _update(self, D, s):
        P = self._P
        PD = P @ D  # (n, k)
        S = self.forgetting * np.eye(D.shape[1]) + D.T @ PD
        K = solve(S, PD.T, assume_a="pos", check_finite=False).T  # (n, k) gain
        self._theta = self._theta + K @ (s - D.T @ self._theta)
        P = (P - K @ PD.T) / self.forgetting
        self._P = 0.5 * (P + P.T)


class DampedRLS(RecursiveEstimator):
    """Regularised (damped) RLS: bounded covariance ``<= 1/delta``, biased towards a prior.

    Args:
        n_params, forgetting, scale, output_std: see :class:`SVDDLS`.
        damping: delta, in the scaled units of ``R``.
        prior: pi_prior (n,) physical units, default zeros; a warm start replaces it by the
            offline estimate.
    """

    def __init__(self, n_params: int, forgetting: float = 0.999, damping: float = 1e-3, prior=None,
                 scale=None, output_std=None):
        super().__init__(n_params, forgetting, scale, output_std)
        if damping <= 0:
            raise ValueError(f"damping must be positive, got {damping}")
        self.damping = float(damping)
        prior = np.zeros(self.n_params) if prior is None else np.asarray(prior, dtype=float)
        self._prior = prior / self.scale
        self._theta = self._prior.copy()
        self._R = self.damping * np.eye(self.n_params)

    @property
    def covariance_(self) -> np.ndarray:
        """``R_t⁻¹`` in physical units (n, n)."""
        return np.linalg.inv(self._R) * np.outer(self.scale, self.scale)

    def warm_start(self, coef, information):
        super().warm_start(coef, information)
        self._prior = self._theta.copy()
        return self

    def _set_information(self, R):
        self._R = R + self.damping * np.eye(self.n_params)

    def _update(self, D, s):
        reg = (1.0 - self.forgetting) * self.damping
        R = self.forgetting * self._R + D @ D.T
        R[np.diag_indices_from(R)] += reg
        self._R = R
        rhs = D @ (s - D.T @ self._theta) + reg * (self._prior - self._theta)
        c, info = lapack.dpotrf(R, lower=1, clean=0)
        self._theta = self._theta + lapack.dpotrs(c, rhs, lower=1)[0]


class SVDDLS(RecursiveEstimator):
    """SVD-based damped recursive least squares (the SVD-DLS paper, eqs. 65–83).

    Args:
        n_params: n. forgetting: lambda in (0, 1].
        threshold: eigenvalues of the scaled ``R_t`` below it are unexcited directions, in
            which the estimate is held: ``100`` ⇔ 10 % relative standard deviation (module
            docstring; meaningful with ``scale`` and ``output_std`` given).
        scale: (n,) typical parameter magnitudes (e.g. CAD values), default ones.
        output_std: (k,) output noise levels (N·m, N), default ones.
    """

    def __init__(self, n_params: int, forgetting: float = 0.999, threshold: float = 100.0,
                 scale=None, output_std=None):
        super().__init__(n_params, forgetting, scale, output_std)
        if not threshold > 0:
            raise ValueError(f"threshold must be positive, got {threshold}")
        self.threshold = float(threshold)
        self._R = np.zeros((self.n_params, self.n_params))
        self.rank_ = 0

    def _excited(self) -> tuple[np.ndarray, np.ndarray]:
        """Eigenvalues and eigenvectors of ``R_t`` at or above the threshold (ascending)."""
        lam, V, info = lapack.dsyevd(self._R, compute_v=1, lower=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"dsyevd failed with info={info}")
        first = int(np.searchsorted(lam, self.threshold, side="left"))
        self.rank_ = self.n_params - first
        return lam[first:], V[:, first:]

    def held_directions(self) -> np.ndarray:
        """(n, n − rank) the unit directions of the scaled parameters in which the estimate is
        held (eigenvectors of ``R_t`` below the threshold)."""
        lam, V, info = lapack.dsyevd(self._R, compute_v=1, lower=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"dsyevd failed with info={info}")
        return V[:, lam < self.threshold]

    @property
    def covariance_(self) -> np.ndarray:
        """Pseudo-inverse of ``R_t`` on the excited subspace, physical units (n, n)."""
        lam, Vp = self._excited()
        return ((Vp / lam) @ Vp.T) * np.outer(self.scale, self.scale)

    def _set_information(self, R):
        self._R = R.copy()

    def _update(self, D, s):
        R = self._R
        R *= self.forgetting
        R += D @ D.T
        # eq. 77. With few held directions (the previous sample's rank tells) only they are
        # computed (LAPACK dsyevr, about half the cost of the full decomposition): lifting them to
        # the threshold gives a positive definite R' whose inverse is V_p Lambda_p^-1 V_p^T on the
        # excited subspace plus U U^T / threshold on the held one, which is then taken away.
        below = np.nextafter(self.threshold, -np.inf)
        n = self.n_params
        if 2 * self.rank_ < n:     # many held: the full decomposition (faster than dsyevr's subset here)
            lam, Vp = self._excited()
            if lam.size:
                g = D @ (s - D.T @ self._theta)
                self._theta = self._theta + Vp @ ((Vp.T @ g) / lam)
            return
        lam, U, m, _, info = lapack.dsyevr(R, compute_v=1, range="V", vl=-np.inf, vu=below, lower=1)
        _check(info)
        self.rank_ = n - m
        if not self.rank_:
            return
        g = D @ (s - D.T @ self._theta)
        if m:
            U = U[:, :m]
            lifted = R + (U * (self.threshold - lam[:m])) @ U.T
            step = cho_solve(cho_factor(lifted, lower=True, check_finite=False), g, check_finite=False)
            step -= U @ (U.T @ g) / self.threshold
        else:
            step = cho_solve(cho_factor(R, lower=True, check_finite=False), g, check_finite=False)
        self._theta = self._theta + step


def _check(info: int) -> None:
    if info != 0:
        raise np.linalg.LinAlgError(f"LAPACK dsyevr failed with info={info}")


@dataclass(frozen=True)
class StreamTrace:
    """What an online estimator did on a stream (:func:`run_stream`).

    Attributes:
        predictions: (N, k) a-priori predictions ``Y_t @ coef_{t−1}`` (before sample t is used).
        coef: (N, n) estimate after each sample, physical units.
        covariance_trace: (N,) trace of the scaled covariance (``R_t⁻¹``, or its pseudo-inverse
            on the excited subspace for SVD-DLS) after each sample.
        rank: (N,) excited directions after each sample (n for the RLS variants).
        seconds_per_sample: wall time of one update (prediction and bookkeeping included).
    """

    predictions: np.ndarray
    coef: np.ndarray
    covariance_trace: np.ndarray
    rank: np.ndarray
    seconds_per_sample: float


def run_stream(estimator: RecursiveEstimator, Y: np.ndarray, tau: np.ndarray) -> StreamTrace:
    """Feed ``Y`` (N, k, n), ``tau`` (N, k) to ``estimator`` one sample at a time, recording
    the a-priori prediction, the estimate and the covariance after each sample."""
    Y = np.asarray(Y, dtype=float)
    tau = np.asarray(tau, dtype=float)
    N = len(Y)
    pred = np.empty(tau.shape)
    coef = np.empty((N, estimator.n_params))
    trace = np.empty(N)
    rank = np.full(N, estimator.n_params)
    unit = np.outer(estimator.scale, estimator.scale)
    start = time.perf_counter()
    for i in range(N):
        pred[i] = estimator.predict(Y[i])
        estimator.partial_fit(Y[i], tau[i])
        coef[i] = estimator.coef_
        trace[i] = np.trace(estimator.covariance_ / unit)
        rank[i] = getattr(estimator, "rank_", estimator.n_params)
    return StreamTrace(pred, coef, trace, rank, (time.perf_counter() - start) / max(N, 1))
