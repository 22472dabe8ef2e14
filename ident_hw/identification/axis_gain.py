"""Which one actuator's gain the data ask for: a torque constant, gear ratio or screw lead
checked against the model itself, with no twin axis to compare with.

A drive's force per ampere off by ``g`` on axis ``i`` makes its measured forces ``(1 + g)``
times what the robot exerts. The identified parameters bend towards it where they can (an
axis's own friction scales with it exactly; parameters shared with other axes only in part),
so what the fit leaves on that axis, and on the axes sharing its parameters, is what the
parameters could not take. Refitting every fitted parameter together with one axis's gain
gives that gain back: ``tau = Y (pi + delta) + g_i e_i (Y pi)_i``, linearised about the fit's
parameters ``pi`` (``e_i`` selects axis ``i``'s rows), by least squares over the rows the fits
used (an axis near rest gives none), each axis's rows weighted by the inverse RMS of its own
residual (its forces and units are its own). Nothing of another axis is assumed alike: on a
correct model every axis's gain is zero within its statistics, however unequal the axes'
friction, rotor inertia or noise.

Several axes' gains at once are not determined: every parameter scaled by ``s`` and every
gain by ``1/s`` give the same forces, so only gains relative to the others held at 1 mean
something. :func:`axis_gains` therefore names axes one at a time, greedily: of the axes not
named yet, the one whose gain, freed beside those already named, explains most of what is
left (the largest drop of the weighted residual sum of squares) is named when its gain is
beyond the limit and beyond :data:`SIGMAS` standard errors; then the next is looked for with
it free. An axis whose gain explains nearly as much as the named one's
(:data:`AS_GOOD` of its drop) is reported beside it: the data cannot tell the two apart (on a
serial arm whose first joint carries every parameter, that joint's gain and the opposite gain
of the other joint fit alike). On the 3PRRR a third link's torque constant 3 % off leaves the
other two links 2 % off their own model; its gain alone explains 2.6 times what theirs do, and
it is named.

The standard error of a gain is the white-residual one; the residual of filtered, decimated
data is correlated over a few samples, so it is a lower bound, used only to keep a gain the
data barely determine from being named (and to say so: :attr:`AxisGain.determined`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

#: a gain counts when it is beyond its limit and this many of its standard errors
SIGMAS = 5.0
#: an axis whose freed gain removes at least this fraction of what the named axis's removes is
#: named beside it: the data do not tell the two apart
AS_GOOD = 0.9
#: singular values of the column-scaled regressor below this fraction of the largest: rank
RANK_RTOL = 1e-8
#: a gain column of which less than this fraction is left once the parameters took their part:
#: the axis's own parameters absorb its gain (not determined)
ABSORBED = 1e-6


@dataclass(frozen=True)
class AxisGain:
    """One axis's gain in the model the verdict ends with (the named axes' gains free):
    ``percent`` (``g`` × 100: its forces are ``1 + g`` times the model's), its white-residual
    standard error ``sigma_percent`` (inf: not determined, the axis's own parameters absorb any
    gain of it) and ``explained``: the fraction of the weighted residual sum of squares (of
    the fit with every parameter refitted) that freeing it removes."""

    percent: float
    sigma_percent: float
    explained: float

    def determined(self, limit: float, sigmas: float = SIGMAS) -> bool:
        """The data resolve a gain of ``limit`` % on this axis: ``sigmas`` standard errors are within it."""
        return bool(np.isfinite(self.sigma_percent) and sigmas * self.sigma_percent < limit)

    def beyond(self, limit: float, sigmas: float = SIGMAS) -> bool:
        """Beyond ``limit`` % and beyond ``sigmas`` standard errors."""
        return abs(self.percent) > limit and abs(self.percent) > sigmas * self.sigma_percent


@dataclass(frozen=True)
class NamedGain:
    """An axis the data say is off by its gain, and the axes whose gain fits the data about as
    well (``alike``: their gain in its place, %; empty when it stands alone)."""

    axis: str
    percent: float
    sigma_percent: float
    alike: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class AxisGains:
    """What :func:`axis_gains` found: per axis with rows its :class:`AxisGain`, the axes
    ``named`` in the order they were found, and the rows and parameters of the refit."""

    gains: dict[str, AxisGain]
    named: tuple[NamedGain, ...] = ()
    rows: int = 0
    rank: int = 0


def axis_gains(Y: np.ndarray, tau: np.ndarray, coef: np.ndarray, free: Sequence[int], axes: Sequence[str],
               limit: float, judged: Sequence[str] | None = None) -> AxisGains:
    """Each judged axis's gain against the model with every ``free`` parameter refitted, and
    the axes whose gain is off by more than ``limit`` % (see the module docstring).

    Args:
        Y: (N, a, n) regressor of the fitted trajectories, stacked.
        tau: (N, a) their measured forces, NaN where a row is left out of the fits.
        coef: (n,) the fit's parameters (its prediction is ``Y @ coef``).
        free: the columns some step fitted (refitted here); the others stay at ``coef``.
        axes: (a,) the actuators' names.
        limit: %, the gain beyond which an axis is named.
        judged: the axes whose gain is judged (None: every axis with rows); the others' rows
            still take part in the refit.
    """
    Y = np.asarray(Y, dtype=float)
    tau = np.asarray(tau, dtype=float)
    predicted = Y @ coef
    residual = tau - predicted
    used = np.isfinite(residual)
    judged = list(axes) if judged is None else list(judged)
    with np.errstate(invalid="ignore"):
        rms = np.sqrt(np.array([np.mean(residual[used[:, j], j] ** 2) if used[:, j].any() else np.nan
                                for j in range(len(axes))]))
    weight = np.where(np.isfinite(rms) & (rms > 0), 1.0 / np.where(rms > 0, rms, 1.0), 0.0)
    rows, cols = np.nonzero(used & (weight > 0))
    if not len(rows):
        return AxisGains(gains={})
    b = residual[rows, cols] * weight[cols]
    A = Y[rows, cols][:, list(free)] * weight[cols, None]
    # one column per axis: its prediction on its own rows, weighted
    G = np.zeros((len(b), len(axes)))
    for j in range(len(axes)):
        mine = cols == j
        G[mine, j] = predicted[rows[mine], j] * weight[j]
    # what the parameters cannot take of the residual and of each gain column
    outside, rank = _outside_columns(A, np.column_stack([b, G]))
    b_left, G_left = outside[:, 0], outside[:, 1:]
    total = float(b_left @ b_left)
    G_norm = np.linalg.norm(G, axis=0)
    candidates = [j for j, name in enumerate(axes) if name in judged and np.any(cols == j)]
    dof = len(b) - rank
    named: list[NamedGain] = []
    chosen: list[int] = []
    while True:
        trials = {j: _with_gains(G_left, G_norm, b_left, chosen + [j], dof) for j in candidates if j not in chosen}
        if not trials:
            break
        before = _with_gains(G_left, G_norm, b_left, chosen, dof)[1] if chosen else total
        drops = {j: before - left for j, (_, left, _) in trials.items()}
        best = max(drops, key=lambda j: drops[j])
        g, _, sigma = trials[best]
        gain = AxisGain(100 * g[-1], 100 * sigma[-1], 0.0)
        if not (drops[best] > 0 and gain.beyond(limit)):
            break
        alike = tuple((axes[j], float(100 * trials[j][0][-1])) for j in trials
                      if j != best and drops[j] >= AS_GOOD * drops[best] and abs(trials[j][0][-1]) * 100 > limit)
        named.append(NamedGain(axes[best], float(gain.percent), float(gain.sigma_percent), alike))
        chosen.append(best)
    # every judged axis's gain in the end model: the chosen ones together, each other one freed beside them
    gains: dict[str, AxisGain] = {}
    end = _with_gains(G_left, G_norm, b_left, chosen, dof) if chosen else (np.zeros(0), total, np.zeros(0))
    for k, j in enumerate(chosen):
        alone = _with_gains(G_left, G_norm, b_left, [c for c in chosen if c != j], dof)[1] if len(chosen) > 1 else total
        gains[axes[j]] = AxisGain(float(100 * end[0][k]), float(100 * end[2][k]), _share(alone - end[1], total))
    for j in candidates:
        if j not in chosen:
            g, left, sigma = _with_gains(G_left, G_norm, b_left, chosen + [j], dof)
            gains[axes[j]] = AxisGain(float(100 * g[-1]), float(100 * sigma[-1]), _share(end[1] - left, total))
    return AxisGains(gains={name: gains[name] for name in axes if name in gains}, named=tuple(named),
                     rows=len(b), rank=rank)


def sharing_axes(Y: np.ndarray, free: Sequence[int], axes: Sequence[str]) -> dict[str, tuple[str, ...]]:
    """Per axis, the other axes some of the ``free`` parameters act on together with it (a
    non-zero column of ``Y`` (N, a, n) on both): where the fit can move an error of one onto
    the other."""
    acts = np.any(Y[:, :, list(free)] != 0, axis=0)            # (a, len(free))
    return {name: tuple(axes[k] for k in range(len(axes)) if k != j and np.any(acts[j] & acts[k]))
            for j, name in enumerate(axes)}


def _outside_columns(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, int]:
    """The part of the columns of ``B`` (rows, p) outside the column space of ``A`` (rows, m),
    its columns scaled to unit norm first (a zero column counts for nothing; singular values
    below :data:`RANK_RTOL` of the largest count as zero), in coordinates of an orthonormal
    basis of that complement: ``(L (k, p), rank of A)`` with ``Lᵀ L`` the Gram matrix of
    ``(I − P_A) B``. What is made of those parts by their norms, inner products and singular
    values (:func:`_with_gains`) is the same as of the (rows, p) parts themselves.

    From one Householder triangle of ``[A B]`` (Q not formed): ``[A B] = Q [[R11, R12],
    [0, R22]]``; with ``R11 = U S Vᵀ`` and ``U⊥`` the left singular vectors of the zero singular
    values, ``L = [U⊥ᵀ R12; R22]``: no (rows, rank) basis of ``A``'s columns is formed (a thin
    SVD of ``A`` forms one, and projecting ``B`` on it costs as much again)."""
    norm = np.linalg.norm(A, axis=0)
    scaled = A[:, norm > 0] / norm[norm > 0]
    m = scaled.shape[1]
    if m == 0:
        return np.array(B, dtype=float), 0
    R = np.asarray(np.linalg.qr(np.concatenate([scaled, B], axis=1), mode="r"))
    top = min(m, R.shape[0])
    U, s, _ = np.linalg.svd(R[:top, :m])
    rank = int(np.sum(s > RANK_RTOL * s[0])) if s[0] > 0 else 0
    return np.concatenate([U[:, rank:].T @ R[:top, m:], R[top:, m:]]), rank


def _with_gains(G_left: np.ndarray, G_norm: np.ndarray, b_left: np.ndarray, which: list[int], dof: int
                ) -> tuple[np.ndarray, float, np.ndarray]:
    """The gains of the axes ``which`` freed together (the parameters' part already projected
    out of their columns ``G_left`` and of ``b_left``; ``G_norm``: the columns' norms before):
    their values, the weighted residual sum of squares left and their standard errors (inf
    for a gain its own parameters absorb: less than :data:`ABSORBED` of its column is left; NaN
    and inf for the last one when the others' gains and the parameters can take it)."""
    C = G_left[:, which]
    norm = np.linalg.norm(C, axis=0)
    ok = norm > ABSORBED * G_norm[which]
    g = np.zeros(len(which))
    sigma = np.full(len(which), np.inf)
    if not ok.any():
        return g, float(b_left @ b_left), sigma
    Cn = C[:, ok] / norm[ok]
    U, s, Vt = np.linalg.svd(Cn, full_matrices=False)
    keep = s > RANK_RTOL * s[0]
    if not keep.all():          # the last gain is the others' (every parameter scaled alike): not determined
        g, left, sigma = _with_gains(G_left, G_norm, b_left, which[:-1], dof)
        return np.append(g, np.nan), left, np.append(sigma, np.inf)
    x = Vt[keep].T @ ((U[:, keep].T @ b_left) / s[keep])
    left_vec = b_left - Cn @ x
    left = float(left_vec @ left_vec)
    covariance = (Vt[keep].T / s[keep] ** 2) @ Vt[keep]
    variance = left / max(dof - int(keep.sum()), 1)
    g[ok] = x / norm[ok]
    sigma[ok] = np.sqrt(variance * np.diag(covariance)) / norm[ok]
    return g, left, sigma


def _share(drop: float, total: float) -> float:
    return float(max(drop, 0.0) / total) if total > 0 else 0.0
