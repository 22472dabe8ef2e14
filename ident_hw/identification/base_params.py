"""Base parameters by SVD (the SVD-DLS paper, sec. 6.1, eqs. 66 and 78–80).

From the stacked regressor ``W`` (r, n): ``W D = U S Vᵀ`` with ``D = diag(scale)`` (columns
expressed as torque contributions of parameters of the given typical size), rank = number of
singular values above ``rtol × s_max``. The null space of ``W`` is ``N = D V_nul``. QR with
column pivoting on ``V_nulᵀ`` picks the ``n − rank`` parameters to eliminate (their rows
``N2`` of ``N`` are then best conditioned); with ``N1`` the rows of the kept ones,

    W pi = W1 (pi1 − N1 N2⁻¹ pi2),   base parameters  pi_b = H pi,  H = [I, −N1 N2⁻¹]

(columns of ``H`` in the original parameter order). ``H`` does not depend on the basis chosen
for the null space.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import linalg

from ident_hw.model.base_basis import BaseBasis

from .least_squares import LeastSquaresResult, check_regression_data, ols, stack, wls

#: Default rank tolerance, relative to the largest singular value of the scaled regressor.
DEFAULT_RTOL = 1e-8


@dataclass(frozen=True)
class BaseParameters(BaseBasis):
    """Result of :func:`base_parameters`: the model layer's base basis found from the data, with
    the figures of its rank decision (stored in a results folder as
    :class:`ident_hw.records.BaseAnalysis`).

    Attributes:
        names, kept, H: the basis (:class:`~ident_hw.model.base_basis.BaseBasis`): the n physical
            parameter names, the rank names carrying a base parameter, ``H`` (rank, n).
        rank: numerical rank of the regressor.
        rtol: rank tolerance used, relative to the largest singular value.
        singular_values: of the column-scaled regressor (n,), descending.
        eliminated: names regrouped into the kept ones, or not excited at all (n − rank).
        null_space: (n, n − rank) basis of the null space of ``W`` in physical units.
    """

    rank: int
    rtol: float
    singular_values: np.ndarray
    eliminated: tuple[str, ...]
    null_space: np.ndarray

    @property
    def unexcited(self) -> tuple[str, ...]:
        """Eliminated parameters that appear in no base parameter: the data says nothing of them."""
        scale = np.max(np.abs(self.H), axis=0) if self.rank else np.zeros(len(self.names))
        return tuple(nm for nm in self.eliminated if scale[self.names.index(nm)] <= 1e-10)


def on_kept(names, kept, values) -> np.ndarray:
    """A physical vector (..., n) that predicts what base values ``values`` (..., r) predict:
    each value on its kept parameter (``kept`` (r,) among ``names`` (n,)), every other
    parameter 0. Row i of a base matrix ``H`` has 1 at ``kept[i]`` and 0 at the other kept
    parameters, so ``H @`` it gives ``values`` back."""
    values = np.asarray(values, dtype=float)
    names = list(names)
    out = np.zeros(values.shape[:-1] + (len(names),))
    out[..., [names.index(k) for k in kept]] = values
    return out


@dataclass(frozen=True)
class Triangle:
    """The triangle of a stacked regressor ``W`` (r, n) scaled by columns: ``W diag(scale) = Q R``,
    ``R`` (min(r, n), n), ``scale`` (n,). Its singular values and right singular vectors are those
    of ``W diag(scale)``, and ``R diag(other / scale)`` is the triangle of ``W diag(other)``: one
    factorisation of ``W`` serves every :func:`base_parameters` of it, whatever its scale."""

    R: np.ndarray
    scale: np.ndarray

    @classmethod
    def of(cls, W: np.ndarray, scale: np.ndarray) -> Triangle:
        """The triangle of ``W`` (r, n) scaled by ``scale`` (n,) (Householder QR, Q not formed)."""
        scale = np.asarray(scale, dtype=float)
        return cls(np.asarray(np.linalg.qr(W * scale, mode="r")), scale)

    def rescaled(self, scale: np.ndarray) -> np.ndarray:
        """The triangle of ``W diag(scale)`` (min(r, n), n)."""
        return self.R * (np.asarray(scale, dtype=float) / self.scale)

    def scaled_condition(self, columns: Sequence[int]) -> float:
        """:func:`~ident_hw.identification.base_params.scaled_condition` of the regressor's
        ``columns`` (indices among its n), from the triangle instead of the tall ``W``:
        ``R[:, columns] / scale[columns]`` has the singular values of ``W[:, columns]``, and its
        column norms are the columns' RMS times one factor for all (the rows counted), which no
        condition number sees."""
        R = self.R[:, list(columns)] / self.scale[list(columns)]
        if not R.size or not np.any(R):
            return float("inf")
        return float(np.linalg.cond(R * _inverse_rms(np.linalg.norm(R, axis=0))))


def base_parameters(W: np.ndarray, names, rtol: float = DEFAULT_RTOL, scale=None,
                    triangle: Triangle | None = None) -> BaseParameters:
    """Rank, null space and base parameters of a stacked regressor ``W`` (r, n).

    Args:
        W: stacked regressor (r, n) (:func:`~ident_hw.identification.least_squares.stack`),
            or a per-sample regressor (N, k, n), which is stacked here.
        names: the n parameter names.
        rtol: singular values below ``rtol × s_max`` count as zero.
        scale: (n,) typical magnitude of each parameter (e.g. the CAD values), so that the
            rank decision compares torque contributions, not raw units; default ones.
        triangle: the :class:`Triangle` of this ``W`` already computed (with any scale), so
            that the regressor is not factorised again; None: factorised here.
    """
    W = np.asarray(W, dtype=float)
    if W.ndim == 3:
        W = W.reshape(-1, W.shape[2])
    names = tuple(names)
    n = W.shape[1]
    if len(names) != n:
        raise ValueError(f"{len(names)} names for a regressor with {n} columns")
    scale = np.ones(n) if scale is None else np.abs(np.asarray(scale, dtype=float))
    if scale.shape != (n,) or np.any(scale == 0):
        raise ValueError(f"scale must be {n} non-zero magnitudes, got {scale}")
    # QR first: the SVD of the small triangle R has the singular values and V of W.
    R = triangle.rescaled(scale) if triangle is not None else np.linalg.qr(W * scale, mode="r")
    _, s, Vt = linalg.svd(R, full_matrices=True)
    s = np.concatenate([s, np.zeros(n - s.size)])
    rank = int(np.sum(s > rtol * s[0])) if s[0] > 0 else 0
    V_nul = Vt[rank:].T  # (n, n_w), scaled coordinates
    if rank == n:
        piv = np.arange(n)
    else:
        _, _, piv = linalg.qr(V_nul.T, pivoting=True, mode="economic")
    n_w = n - rank
    eliminated_idx = np.sort(piv[:n_w])
    kept_idx = np.array([i for i in range(n) if i not in set(eliminated_idx)], dtype=int)
    N = V_nul * scale[:, None]  # null space of W in physical units
    H = np.zeros((rank, n))
    H[np.arange(rank), kept_idx] = 1.0
    if n_w:
        H[:, eliminated_idx] = -N[kept_idx] @ np.linalg.inv(N[eliminated_idx])
    return BaseParameters(
        names=names, rank=rank, rtol=rtol, singular_values=s, kept=tuple(names[i] for i in kept_idx),
        eliminated=tuple(names[i] for i in eliminated_idx), H=H, null_space=N,
    )


def with_basis(numeric: BaseParameters, basis: BaseBasis) -> BaseParameters | None:
    """The base parameters ``numeric`` found by SVD, written in a basis the robot's model gives
    (e.g. the Delta's readable combinations; its columns put in ``numeric``'s order), or None when
    the data does not identify all of them (numeric rank below the basis's) or the basis does not
    span the data's identifiable space.

    Raises:
        ValueError: the basis is over other parameters than ``numeric``.
    """
    H = np.asarray(basis.on_columns(numeric.names), dtype=float)
    if numeric.rank != len(basis.kept):
        return None
    # the data's null space must be the basis's: H annihilates it
    if np.abs(H @ numeric.null_space).max(initial=0.0) > 1e-6 * np.abs(H).max() * np.abs(numeric.null_space).max(initial=1.0):
        return None
    return BaseParameters(
        names=numeric.names, rank=numeric.rank, rtol=numeric.rtol, singular_values=numeric.singular_values,
        kept=tuple(basis.kept), eliminated=tuple(n for n in numeric.names if n not in basis.kept), H=H,
        null_space=numeric.null_space)


def identify_base(
    Y: np.ndarray, tau: np.ndarray, names, rtol: float = DEFAULT_RTOL, scale=None, weighted: bool = False,
    basis: BaseBasis | None = None, triangle: Triangle | None = None,
) -> tuple[BaseParameters, LeastSquaresResult]:
    """Base parameters of the data and their OLS (or WLS) estimate with statistics.

    ``W pi = W1 pi_b`` with ``W1`` the columns of the kept parameters, so the estimate of
    ``pi_b`` is the least-squares fit on those columns. The result's names are the readable
    expressions of the base parameters. ``basis``: the robot model's base parameters, used
    where the data identifies all of them (:func:`with_basis`). ``triangle``: the
    :class:`Triangle` of the stacked ``Y`` (its rows left out zeroed), when already computed.
    """
    Y, tau = check_regression_data(Y, tau, names)
    # given the triangle, base_parameters reads only the regressor's shape: no stacked copy of it
    base = base_parameters(Y if triangle is not None else stack(Y, tau)[0], names, rtol=rtol, scale=scale,
                           triangle=triangle)
    if basis is not None:
        base = with_basis(base, basis) or base
    cols = [base.names.index(k) for k in base.kept]
    fit = (wls if weighted else ols)(Y[:, :, cols], tau, base.expressions)
    return base, fit


#: a regressor column whose RMS is below this fraction of the largest column's is rounding (a
#: structurally zero column computed through the kinematics), not data: it is not scaled up
NUMERICALLY_ZERO = 1e-10


def column_scale(Y: np.ndarray) -> np.ndarray:
    """(n,) inverse RMS of each regressor column over all samples and outputs (1 for a zero
    column, or one below :data:`NUMERICALLY_ZERO` of the largest): scaling by it makes the rank
    decision of the base parameters unit-free without lifting rounding to unit size."""
    return _inverse_rms(np.sqrt(np.mean(Y.reshape(-1, Y.shape[-1]) ** 2, axis=0)))


def _inverse_rms(rms: np.ndarray) -> np.ndarray:
    """:func:`column_scale` of columns whose RMS (or any one multiple of it) is ``rms`` (n,)."""
    real = rms > NUMERICALLY_ZERO * (rms.max() if rms.size else 0.0)     # never a zero column
    return np.divide(1.0, rms, out=np.ones_like(rms), where=real)


def scaled_condition(Y: np.ndarray, tau: np.ndarray) -> float:
    """Condition number of the stacked regressor ``Y`` (N, 6, n) with unit-RMS columns, over the
    rows the fit uses (``tau`` not NaN): unit-free, unlike cond(W) of kg next to kg·m²."""
    W, _ = stack(*check_regression_data(Y, tau))
    W = W[np.any(W != 0.0, axis=1)]
    if not len(W):
        return float("inf")
    return float(np.linalg.cond(W * column_scale(W[:, None, :])))
