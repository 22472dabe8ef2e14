"""Physically consistent parameters from identified base parameters: a small semidefinite program.

Least squares identifies base parameters ``β = H π`` (r,), combinations of the physical ones
``π`` (n,), with a covariance ``C`` (r, r). A simulator or a controller needs every body's mass,
centre of mass and inertia, and these must be physical: each body's pseudo-inertia ``J_b(π) ⪰ 0``
(:mod:`ident_hw.model.pseudo_inertia`), every drive term (friction, rotor inertia) ``≥ 0``.
The data decides the base parameters; the CAD values ``π₀`` decide the rest. Written as the most
probable ``π`` under the data and a Gaussian prior around the CAD values:

    minimise   (H π − β̂)ᵀ C⁻¹ (H π − β̂)  +  prior(π)
    subject to J_b(π) ⪰ 0 for every body, drive terms ≥ 0, held parameters at their values,

with ``prior`` either ``Σᵢ ((πᵢ − π₀ᵢ) / (ρ sᵢ))²`` (``euclidean``: ``sᵢ`` the parameter's
scale, ``ρ`` the prior's relative standard deviation) or, for the bodies, ``(2 / ρ²) Σ_b
d(J_b ‖ J_b₀)`` with the log-determinant divergence ``d(J ‖ J₀) = −log det(J₀⁻¹ J) + tr(J₀⁻¹ J)
− 4`` (``entropic``, Lee, Wensing, Park, "Geometric Robot Dynamic Identification: A Convex
Programming Approach", 2020: independent of the frames the bodies are written in; it needs a
CAD body with a positive-definite pseudo-inertia, and a body without one keeps the euclidean
term). Near ``π₀`` both terms agree to second order. A weak prior (``ρ`` of order 1) moves the
identified directions by much less than their σ and fills the rest.

cvxpy states the program; Clarabel (open source, interior point) solves it. The problem is solved
in scaled variables ``z = (π − π₀) / s``, so that kilograms, kilogram-metres and kg·m² weigh the
same. What decided each parameter is measured by the prior's share of its posterior variance (the
euclidean problem, constraints inactive). With ``P = (Aᵀ A + 1/ρ²)⁻¹`` (scaled units, ``A =
C^{-1/2} H diag(s)``) the posterior mean's error is ``−(P/ρ²) z + P Aᵀ e``: the prior's part
(what the data do not see, ``z ~ N(0, ρ²)``) has variance ``P² / ρ²``, the noise's ``P Aᵀ A P``,
together ``P``. ``share_i = (P²)_ii / (ρ² P_ii)``: near 0 the data decided parameter ``i`` (its
error is measurement noise), near 1 the prior did (its value moves with CAD values: its own, or
those of the parameters it shares a base parameter with, as the 3PRRR's ``m_ee`` moves with
``m_l2`` along the one direction no data see). A parameter is decided by the ``data`` when its
share is at most :data:`DECIDED`, by the ``prior`` when the data narrowed it by less than that
(``P_ii / ρ² ≥ 1 −`` :data:`DECIDED`), else by ``data and prior`` (narrowed by the data, the rest
set by CAD values).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import special

from ident_hw.model.pseudo_inertia import PhysicalBody, body_pseudo_inertia, pseudo_inertia

METRICS = ("euclidean", "entropic")
#: a parameter whose prior share is at most this was decided by the data; one whose variance the
#: data narrowed by less than this, by the prior
DECIDED = 0.25
#: the entropic term needs a CAD pseudo-inertia this far from singular (smallest over largest
#: eigenvalue); a body nearer the boundary (a point mass, a rod, a plate, or a body an earlier
#: consistent set left on it) keeps the euclidean term: ``J₀⁻¹`` would swamp the program
ENTROPIC_CONDITION = 1e-6
#: the quantile of the χ² test of the consistent set's base parameters against the identified ones
CHI2_QUANTILE = 0.95


def chi2_quantile(q: float, dof: int) -> float:
    """The ``q`` quantile of the χ² distribution with ``dof`` degrees of freedom: SciPy's
    ``stats.chi2.ppf`` by its own formula, without importing ``scipy.stats`` (a third of a
    second of every command's start)."""
    return float(2.0 * special.gammaincinv(dof / 2.0, q))


class ConsistencyError(RuntimeError):
    """The semidefinite program has no solution (names why: infeasible held values, solver status)."""


@dataclass(frozen=True)
class BodyMargin:
    """A body of the consistent set: its mass (kg) and the smallest eigenvalue of its
    pseudo-inertia (kg·m², kg·m or kg: ≥ 0 when physical; 0 where a constraint is active)."""

    body: str
    mass: float
    margin: float



@dataclass(frozen=True)
class ConsistentSet:
    """Physically consistent parameters (n,) nearest the CAD prior that reproduce the identified
    base parameters (module docstring).

    ``values``, ``prior`` (the CAD values), ``sigma`` (posterior standard deviation of the
    euclidean problem), ``prior_share`` (0 = the data decided, 1 = the prior did), ``truth``
    (simulation only) in the order of ``names``; ``decided_by`` per parameter ``data``, ``prior``,
    ``data and prior`` or ``held`` (a value the base step did not fit); ``bodies``: each body's
    margin; ``chi2``: ``(H π − β̂)ᵀ C⁻¹ (H π − β̂)`` of the consistent set, to compare with
    ``chi2_limit``, the 95 % quantile of χ² with ``base_count`` degrees of freedom.
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    values: np.ndarray
    prior: np.ndarray
    sigma: np.ndarray
    prior_share: np.ndarray
    decided_by: tuple[str, ...]
    bodies: tuple[BodyMargin, ...]
    chi2: float
    chi2_limit: float
    base_count: int
    metric: str
    prior_relative: float
    truth: np.ndarray | None = None

    @property
    def rel_sigma_percent(self) -> np.ndarray:
        """(n,) ``100 σ / |value|`` (NaN at a value of 0)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.values != 0, 100.0 * self.sigma / np.abs(self.values), np.nan)

    @property
    def reproduces_base(self) -> bool:
        """The implied base parameters agree with the identified ones within their covariance."""
        return self.chi2 <= self.chi2_limit

    @property
    def physical(self) -> bool:
        """Every body's pseudo-inertia is positive semidefinite."""
        return all(b.margin >= 0.0 for b in self.bodies)

    def error_percent(self) -> np.ndarray | None:
        """(n,) ``100 (value − truth) / |truth|`` (NaN where the truth is 0); None outside simulation."""
        if self.truth is None:
            return None
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.truth != 0, 100.0 * (self.values - self.truth) / np.abs(self.truth), np.nan)


def _whitener(covariance: np.ndarray) -> np.ndarray:
    """``L⁻¹`` (r, r) with ``L Lᵀ = C``: the rows that make ``C`` the identity (an eigenvalue floor
    of 1e-12 of the largest where ``C`` is numerically singular)."""
    C = 0.5 * (covariance + covariance.T)
    w, V = np.linalg.eigh(C)
    w = np.maximum(w, 1e-12 * w.max())
    return (V / np.sqrt(w)).T


def _body_map(body: PhysicalBody, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(M, c)``: the body's pseudo-inertia, flattened (k², k = 4 spatial, 3 planar), as ``M π``
    (M (k², n)): linear in the parameters, its columns the pseudo-inertias of unit values. A
    planar body's second moments are not parameters: ``c`` (k², 2) places its two free in-plane
    values (``Σ_xx``, ``Σ_xy``; ``Σ_yy = I_zz − Σ_xx``), zero for a spatial body."""
    size = 3 if body.planar else 4
    M = np.zeros((size * size, n))
    for slot, i in enumerate(body.indices):
        if i < 0:
            continue
        unit = np.zeros(len(body.indices))
        unit[slot] = 1.0
        J = _planar_matrix(unit, 0.0, 0.0) if body.planar else pseudo_inertia(unit)
        M[:, i] += J.ravel()
    slack = np.zeros((size * size, 2))
    if body.planar:
        slack[:, 0] = _planar_matrix(np.zeros(4), 1.0, 0.0).ravel()
        slack[:, 1] = _planar_matrix(np.zeros(4), 0.0, 1.0).ravel()
    return M, slack


def _planar_matrix(values, sxx: float, sxy: float) -> np.ndarray:
    """``[[Σ_xx, Σ_xy, h_x], [Σ_xy, I_zz − Σ_xx, h_y], [h_x, h_y, m]]`` of planar values (4,)."""
    m, hx, hy, izz = values
    return np.array([[sxx, sxy, hx], [sxy, izz - sxx, hy], [hx, hy, m]])


def _entropic_reference(body: PhysicalBody, prior: np.ndarray) -> np.ndarray | None:
    """The CAD body's pseudo-inertia where the entropic term can use it (spatial, positive
    definite by :data:`ENTROPIC_CONDITION`)."""
    if body.planar or any(i < 0 for i in body.indices):
        return None
    J0 = pseudo_inertia(body.values(prior))
    w = np.linalg.eigvalsh(J0)
    return J0 if w[0] > ENTROPIC_CONDITION * w[-1] else None


def consistent_parameters(names: Sequence[str], units: Sequence[str], H: np.ndarray, base: np.ndarray,
                          covariance: np.ndarray, prior: np.ndarray, scale: np.ndarray,
                          bodies: Sequence[PhysicalBody], held: dict[int, float] | None = None,
                          metric: str = "entropic", prior_relative: float = 1.0,
                          truth: np.ndarray | None = None, signed: Sequence[int] = ()) -> ConsistentSet:
    """The consistent set of the module docstring.

    Args:
        names, units: the n physical parameters and their SI units.
        H: (r, n) base parameters ``β = H π`` (zero columns for the held parameters).
        base, covariance: the identified ``β̂`` (r,) and its covariance (r, r).
        prior: (n,) CAD values; ``scale`` (n,) > 0 the typical size of each parameter.
        bodies: the model's bodies (:meth:`~ident_hw.model.interface.RobotModel.physical_bodies`);
            every parameter in none of them is a drive term, kept ≥ 0.
        held: index → value of parameters the base step held (kept at that value).
        metric: ``euclidean`` or ``entropic``; ``prior_relative``: ``ρ``.
        truth: (n,) the simulated truth, for the report only.
        signed: indices of drive terms of either sign (a friction offset ``f0``), not kept ≥ 0.

    Raises:
        ConsistencyError: no consistent set (e.g. a held value unphysical), or the solver failed.
    """
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {METRICS}, got {metric!r}")
    names = tuple(names)
    n = len(names)
    H, base, prior, scale = (np.asarray(a, dtype=float) for a in (H, base, prior, scale))
    held = dict(held or {})
    if H.shape != (len(base), n) or prior.shape != (n,) or scale.shape != (n,) or np.any(~(scale > 0)):
        raise ValueError(f"shapes: H {H.shape}, base {base.shape}, prior {prior.shape}, scale {scale.shape} "
                         f"for {n} parameters (scales must be positive)")
    whiten = _whitener(covariance)
    A = whiten @ H * scale                                 # (r, n): whitened base rows in scaled variables
    b = whiten @ (base - H @ prior)
    rho2 = prior_relative ** 2
    values, drive = _solve_program(A, b, prior, scale, bodies, held, metric, rho2, signed)
    values[drive] = np.maximum(values[drive], 0.0)          # solver rounding below 0
    share, sigma, decided = _posterior(A, scale, held, rho2)
    residual = whiten @ (H @ values - base)
    margins = tuple(BodyMargin(body.name, float(body.values(values)[0]), _margin(body, values)) for body in bodies)
    return ConsistentSet(names=names, units=tuple(units), values=values, prior=prior, sigma=sigma, prior_share=share,
                         decided_by=decided, bodies=margins, chi2=float(residual @ residual),
                         chi2_limit=chi2_quantile(CHI2_QUANTILE, len(base)), base_count=len(base),
                         metric=metric, prior_relative=float(prior_relative),
                         truth=None if truth is None else np.asarray(truth, dtype=float))


def _solve_program(A: np.ndarray, b: np.ndarray, prior: np.ndarray, scale: np.ndarray,
                   bodies: Sequence[PhysicalBody], held: dict[int, float], metric: str,
                   rho2: float, signed: Sequence[int] = ()) -> tuple[np.ndarray, list[int]]:
    """States and solves the semidefinite program in the scaled variables ``z`` (n,).

    ``A`` (r, n) and ``b`` (r,) are the whitened base rows and residual at the prior; ``signed``:
    drive terms of either sign. Returns the solution ``π`` (n, SI units), before drive terms are
    clipped at 0, and the indices of the drive terms kept ≥ 0.
    """
    import cvxpy as cp

    n = len(prior)
    z = cp.Variable(n)
    pi = prior + cp.multiply(scale, z)
    in_body = {i for body in bodies for i in body.indices if i >= 0}
    drive = [i for i in range(n) if i not in in_body and i not in held and i not in set(signed)]
    constraints = [z[i] == (value - prior[i]) / scale[i] for i, value in held.items()]
    if drive:
        constraints.append(pi[drive] >= 0)
    body_constraints, body_terms, euclidean = _body_program(z, pi, prior, scale, bodies, metric, rho2)
    constraints += body_constraints
    objective = cp.sum_squares(A @ z - b)
    if euclidean.any():
        objective = objective + cp.sum_squares(z[np.flatnonzero(euclidean)]) / rho2
    if body_terms:
        objective = objective + cp.sum(cp.hstack(body_terms))
    problem = cp.Problem(cp.Minimize(objective), constraints)
    _solve(problem, held)
    if problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or z.value is None:
        raise ConsistencyError(f"the consistent-parameter program ended {problem.status}"
                               + (" (a held value is unphysical?)" if held else ""))
    return prior + scale * np.asarray(z.value), drive


def _body_program(z, pi, prior: np.ndarray, scale: np.ndarray, bodies: Sequence[PhysicalBody], metric: str,
                  rho2: float) -> tuple[list, list, np.ndarray]:
    """The bodies' part of the program: each body's pseudo-inertia ``⪰ 0`` (or, for a planar body
    with its centre of mass at the frame origin, ``m ≥ 0`` and ``I_zz ≥ 0``) and, with the
    ``entropic`` metric, its log-determinant divergence from the CAD body.

    ``z`` is the cvxpy variable (n,), ``pi`` the expression ``π₀ + s z``. Returns the
    constraints, the entropic objective terms and a mask (n,) of the parameters that keep the
    euclidean prior term.
    """
    import cvxpy as cp

    n = len(prior)
    constraints, body_terms, euclidean = [], [], np.ones(n, dtype=bool)
    for body in bodies:
        if body.planar and body.indices[1] < 0 and body.indices[2] < 0:
            # centre of mass at the frame origin: realisable exactly when m ≥ 0 and I_zz ≥ 0
            constraints += [pi[i] >= 0 for i in (body.indices[0], body.indices[3]) if i >= 0]
            continue
        M, slack = _body_map(body, n)
        flat = (M * scale) @ z + M @ prior                  # vec J(π), π = π₀ + s z
        if body.planar:
            flat = flat + slack @ cp.Variable(2)
        size = 3 if body.planar else 4
        J = cp.reshape(flat, (size, size), order="C")
        constraints.append(0.5 * (J + J.T) >> 0)
        reference = _entropic_reference(body, prior) if metric == "entropic" else None
        if reference is not None:
            inverse = np.linalg.inv(reference)
            body_terms.append((2.0 / rho2) * (-cp.log_det(0.5 * (J + J.T)) + inverse.ravel() @ flat - size
                                              + np.linalg.slogdet(reference)[1]))
            euclidean[[i for i in body.indices if i >= 0]] = False
    return constraints, body_terms, euclidean


def _solve(problem, held: dict[int, float]) -> None:
    """Solves with Clarabel at tight gaps (1e-10), again at its own defaults (1e-8) on numerical
    trouble there (a solver error, or a solution it calls inaccurate); a solver error then is a
    :class:`ConsistencyError`. A solution still called inaccurate is kept without cvxpy's warning:
    what decides whether it reproduces the data is the caller's chi-square test of the base
    parameters."""
    import warnings

    import cvxpy as cp

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Solution may be inaccurate")
        try:
            problem.solve(solver=cp.CLARABEL, tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10)
            if problem.status == cp.OPTIMAL:
                return
        except cp.error.SolverError:
            pass
        try:                                # numerical trouble at tight gaps: Clarabel's own defaults (1e-8)
            problem.solve(solver=cp.CLARABEL)
        except cp.error.SolverError as exc:
            raise ConsistencyError(f"the consistent-parameter program failed: {exc}") from exc


def _posterior(A: np.ndarray, scale: np.ndarray, held: dict[int, float],
               rho2: float) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """What decided each parameter, from the euclidean problem's posterior (module docstring).

    ``A`` (r, n) whitened base rows in scaled variables. Returns the prior share (n,), the
    posterior standard deviation σ (n, SI units) and ``decided_by`` per parameter; held
    parameters have share and σ 0.
    """
    n = len(scale)
    free = np.array([i not in held for i in range(n)])
    Af = A[:, free]
    P = np.linalg.inv(Af.T @ Af + np.eye(free.sum()) / rho2)
    share = np.zeros(n)
    sigma = np.zeros(n)
    share[free] = np.clip(np.diag(P @ P) / (rho2 * np.diag(P)), 0.0, 1.0)
    sigma[free] = scale[free] * np.sqrt(np.diag(P))
    narrowed = np.ones(n)              # posterior over prior variance: 1 = the data said nothing
    narrowed[free] = np.diag(P) / rho2
    decided = tuple("held" if i in held else "data" if share[i] <= DECIDED
                    else "prior" if narrowed[i] >= 1 - DECIDED else "data and prior" for i in range(n))
    return share, sigma, decided


def _margin(body: PhysicalBody, values: np.ndarray) -> float:
    """The body's margin, 0 where it is rounding of an active constraint (below 1e-9 of the
    pseudo-inertia's size): the solver's tolerance, not a property of the body."""
    J = body_pseudo_inertia(body, values)
    value = float(np.linalg.eigvalsh(J)[0])
    return 0.0 if abs(value) <= 1e-9 * max(np.abs(J).max(), 1e-300) else value
