"""Drive gains from runs with and without a known payload: Gautier and Briot's global
identification of the joint drive gains with the dynamic parameters ("Global identification of
joint drive gains and dynamic parameters of robots", J. Dyn. Sys. Meas. Control 136(5), 2014).

A drive measures its motor current ``i_j`` (A); the joint force is ``g_j i_j`` with ``g_j`` the
drive gain (N·m/A: torque constant × gear, gear losses included), which the manufacturer rarely
publishes to better than a few percent. The dynamic model cannot tell the gains from the
parameters alone: scale every ``g_j`` and every parameter by one factor and the currents are the
same. A payload of known mass ``m`` breaks that: in the runs that carry it, the forces hold
``m`` times a known column, which does not scale. So, with ``kappa_j = 1 / g_j``::

    i_j = kappa_j (Y_j pi + P_j p + m P_jm)        (rows of the loaded runs)
    i_j = kappa_j  Y_j pi                          (rows of the others)

``Y`` the model's regressor (rigid bodies, friction, rotors: its base parameters ``pi``), ``P`` the
columns of the body that carries the payload (its unknown first moments and inertia ``p``, nine
values), ``P_m`` its mass column. The unknowns enter bilinearly; for given ``kappa`` the rest is
linear least squares, so the fit is a variable projection over the ``a`` gains (Golub and Pereyra):
the residual is the currents' (where their noise is), each actuator weighted by its own residual
level (iterated, as weighted least squares), and its normal equations are sums of per-actuator
Gram matrices, formed once. A fit in the forces instead (``Y pi = g i``) would favour small gains,
whose residual is small in proportion.

The standard deviations come from a delete-a-block jackknife: each run cut into ``blocks``
consecutive pieces, the fit done again without the k-th piece of every run. A real robot's
residual is mostly model error, slow and correlated over seconds: least-squares statistics,
which take the rows as independent, would claim a gain to a fraction of a percent that another
run moves by ten.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

#: the pieces each run is cut into for the jackknife
BLOCKS = 10
#: reweighting passes of the actuators' residual levels
WEIGHT_PASSES = 4


@dataclass(frozen=True)
class GainsRun:
    """One run's rows: ``Y`` (N, a, n) the model's regressor, ``current`` (N, a) A (NaN: left
    out), and, for a run with the payload, ``payload`` (N, a, 10) the columns of the body that
    carries it (pinocchio's order: mass first)."""

    Y: np.ndarray
    current: np.ndarray
    payload: np.ndarray | None = None


@dataclass(frozen=True)
class GainsFit:
    """The drive gains ``gains`` (a,) N·m/A | N/A with their jackknife ``sigma`` (a,); ``rank``: the
    base parameters fitted with them (model and payload); ``residual_rms`` (a,) A, the currents
    the fit leaves, and ``residual_rms_start`` with the starting gains (everything else fitted
    again); ``blocks``: the jackknife's pieces per run."""

    gains: np.ndarray
    sigma: np.ndarray
    rank: int
    residual_rms: np.ndarray
    residual_rms_start: np.ndarray
    blocks: int


class _Grams:
    """Per-actuator sums over rows of the reduced problem ``i_j ~ kappa_j (A_j theta + c_j)``:
    ``A^T A`` (a, r, r), ``A^T i``, ``A^T c`` (a, r), ``i^T i``, ``i^T c``, ``c^T c`` (a,)."""

    def __init__(self, A: np.ndarray, i: np.ndarray, c: np.ndarray):
        self.AA = np.einsum("naj,nak->ajk", A, A)
        self.Ai = np.einsum("naj,na->aj", A, i)
        self.Ac = np.einsum("naj,na->aj", A, c)
        self.ii = np.einsum("na,na->a", i, i)
        self.ic = np.einsum("na,na->a", i, c)
        self.cc = np.einsum("na,na->a", c, c)
        self.rows = np.einsum("na->a", (np.abs(A).sum(axis=2) > 0).astype(float))

    def minus(self, other: _Grams) -> _Grams:
        out = object.__new__(_Grams)
        for key in ("AA", "Ai", "Ac", "ii", "ic", "cc", "rows"):
            setattr(out, key, getattr(self, key) - getattr(other, key))
        return out

    def solve(self, kappa: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``theta`` (r,) for the gains ``1 / kappa`` (a,) and each actuator's squared residual (a,),
        actuator ``j`` weighted by ``weight[j]``."""
        w2 = weight ** 2
        lhs = np.einsum("a,ajk->jk", w2 * kappa ** 2, self.AA)
        rhs = np.einsum("a,aj->j", w2 * kappa, self.Ai) - np.einsum("a,aj->j", w2 * kappa ** 2, self.Ac)
        theta = np.linalg.lstsq(lhs, rhs, rcond=1e-12)[0]
        fitted_i = self.Ai @ theta + self.ic            # (a,): (A theta + c)^T i per actuator
        fitted2 = np.einsum("j,ajk,k->a", theta, self.AA, theta) + 2 * self.Ac @ theta + self.cc
        squares = self.ii - 2 * kappa * fitted_i + kappa ** 2 * fitted2
        return theta, np.maximum(squares, 0.0)


def fit_gains(runs: Sequence[GainsRun], mass: float, start: np.ndarray, blocks: int = BLOCKS,
              rtol: float = 1e-8) -> GainsFit:
    """The drive gains (see the module docstring) from ``runs`` (at least one with the payload of
    ``mass`` kg), starting from the gains ``start`` (a,) (the config's).

    Raises:
        ValueError: no run with the payload, or no row to fit.
    """
    if not any(r.payload is not None for r in runs):
        raise ValueError("the drive gains need a run with the payload of known mass")
    A, i, c, pieces = _rows(runs, blocks)
    c = mass * c
    if not len(i):
        raise ValueError("no row to fit the drive gains on")
    A = _reduced(A, rtol)
    whole = _Grams(A, i, c)
    kappa, weight = _fit(whole, 1.0 / np.asarray(start, dtype=float))
    _, squares = whole.solve(kappa, weight)
    _, at_start = whole.solve(1.0 / np.asarray(start, dtype=float), weight)
    jackknifed = []
    for k in range(blocks):
        rows = pieces == k
        if rows.any():
            jackknifed.append(1.0 / _fit(whole.minus(_Grams(A[rows], i[rows], c[rows])), kappa, weight)[0])
    estimates = np.array(jackknifed)
    b = len(estimates)
    sigma = np.sqrt((b - 1) / b * np.sum((estimates - estimates.mean(axis=0)) ** 2, axis=0))
    rows = np.maximum(whole.rows, 1.0)
    return GainsFit(gains=1.0 / kappa, sigma=sigma, rank=A.shape[2], residual_rms=np.sqrt(squares / rows),
                    residual_rms_start=np.sqrt(at_start / rows), blocks=b)


def _rows(runs: Sequence[GainsRun], blocks: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The stacked rows: ``A`` (N, a, n + 9) the model's columns then the payload's unknown ones
    (zero in the runs without it), currents ``i`` (N, a), the payload's mass column ``c`` (N, a)
    (the force per kilogram of payload), and each row's jackknife piece (N,). Rows left out (NaN
    current) are zero throughout."""
    parts = []
    for run in runs:
        N, a, n = run.Y.shape
        payload = np.zeros((N, a, 10)) if run.payload is None else run.payload
        left_out = ~np.isfinite(run.current)
        A = np.concatenate([run.Y, payload[:, :, 1:]], axis=2)
        A = np.where(left_out[..., None], 0.0, A)
        i = np.where(left_out, 0.0, run.current)
        c = np.where(left_out, 0.0, payload[:, :, 0])
        piece = np.minimum((np.arange(N) * blocks) // max(N, 1), blocks - 1)
        parts.append((A, i, c, piece))
    A, i, c, piece = (np.concatenate(x) for x in zip(*parts))
    return A, i, c, piece


def _reduced(A: np.ndarray, rtol: float) -> np.ndarray:
    """``A`` (N, a, m) on its independent columns (QR with column pivoting of the columns scaled
    to unit norm; a column whose independent part is below ``rtol`` of the first pivot goes):
    scaling an actuator's rows, which the gains do, leaves which columns are independent as it is."""
    from scipy.linalg import qr
    flat = A.reshape(-1, A.shape[2])
    norms = np.linalg.norm(flat, axis=0)
    used = np.flatnonzero(norms > 1e-12 * norms.max())
    _, R, perm = qr(flat[:, used] / norms[used], mode="economic", pivoting=True)
    diag = np.abs(np.diag(R))
    keep = np.sort(used[perm[:int(np.sum(diag > rtol * diag[0]))]])
    return A[:, :, keep] / norms[keep]


def _fit(grams: _Grams, kappa0: np.ndarray, weight0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``kappa`` (a,) minimising the weighted current residual of ``grams``, from ``kappa0``; the
    weights (a,) one over each actuator's residual level, iterated from ``weight0`` (None: from an
    unweighted fit). Returns the gains' inverses and the weights."""
    from scipy.optimize import minimize
    weight = np.ones_like(kappa0) if weight0 is None else weight0
    kappa = kappa0.copy()
    passes = 1 if weight0 is not None else WEIGHT_PASSES
    for _ in range(passes):
        def cost(log_kappa, w=weight):
            return float(np.sum(w ** 2 * grams.solve(np.exp(log_kappa), w)[1]))
        scale = cost(np.log(kappa)) or 1.0
        result = minimize(lambda x: cost(x) / scale, np.log(kappa), method="BFGS", options={"gtol": 1e-10})
        kappa = np.exp(result.x)
        if weight0 is None:
            _, squares = grams.solve(kappa, weight)
            weight = 1.0 / np.sqrt(np.maximum(squares / np.maximum(grams.rows, 1.0), 1e-30))
    return kappa, weight
