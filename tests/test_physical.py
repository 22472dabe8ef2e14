"""The physically consistent parameters (ident_hw.identification.physical) against independent
computations: the nearest positive-semidefinite matrix by eigenvalue clipping, the closed-form
posterior of a linear-Gaussian model, the bounds of planar bodies and drive terms."""

from __future__ import annotations

import numpy as np
import pytest

from ident_hw.identification.physical import consistent_parameters
from ident_hw.model.pseudo_inertia import SPATIAL, PhysicalBody, margin, planar_pseudo_inertia, pseudo_inertia

ROOT2 = np.sqrt(2.0)
#: upper-triangle entries of a 4x4 symmetric matrix
UPPER = [(i, j) for i in range(4) for j in range(i, 4)]


def frobenius_map() -> np.ndarray:
    """T (10, 10): a body's values (SPATIAL order) → the upper triangle of its pseudo-inertia,
    off-diagonal entries times √2, so that ``|T π|`` is the Frobenius norm of ``J(π)``; built
    column by column from :func:`pseudo_inertia` (linear)."""
    T = np.empty((10, 10))
    for k in range(10):
        J = pseudo_inertia(np.eye(10)[k])
        T[:, k] = [J[i, j] * (1.0 if i == j else ROOT2) for i, j in UPPER]
    return T


def values_of(J: np.ndarray) -> np.ndarray:
    """A body's values (SPATIAL order) of a pseudo-inertia ``J`` (4, 4): ``I = tr(Σ) 1 − Σ``."""
    sigma = J[:3, :3]
    inertia = np.trace(sigma) * np.eye(3) - sigma
    return np.array([J[3, 3], *J[:3, 3], inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2], inertia[1, 2],
                     inertia[2, 2]])


def test_pseudo_inertia_of_a_box_is_its_second_moments():
    """A uniform box (a, b, c) of mass m centred at p: J = ∫ [r; 1][r; 1]ᵀ dm by its closed form."""
    m, (a, b, c), p = 2.0, (0.3, 0.2, 0.1), np.array([0.1, -0.05, 0.2])
    second = m * np.diag([a * a, b * b, c * c]) / 12.0 + m * np.outer(p, p)
    inertia = np.trace(second) * np.eye(3) - second
    values = [m, *(m * p), inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2], inertia[1, 2], inertia[2, 2]]
    expected = np.block([[second, m * p[:, None]], [m * p[None, :], np.array([[m]])]])
    np.testing.assert_allclose(pseudo_inertia(values), expected, rtol=0, atol=1e-15)
    assert margin(PhysicalBody("box", tuple(range(10))), values) > 0


def test_unphysical_body_goes_to_the_nearest_psd_pseudo_inertia():
    """Identified base parameters = the body's values themselves, isotropic in the Frobenius
    norm of J, prior negligible: the consistent body is the eigenvalue-clipped J (the nearest
    positive-semidefinite matrix in that norm, Higham 1988)."""
    T = frobenius_map()
    rng = np.random.default_rng(3)
    A = rng.normal(size=(4, 4))
    J_bad = A @ A.T - 0.3 * np.eye(4)               # two eigenvalues negative
    w, V = np.linalg.eigh(J_bad)
    assert w[0] < 0
    J_near = (V * np.maximum(w, 0.0)) @ V.T
    bad = values_of(J_bad)
    body = PhysicalBody("b", tuple(range(10)))
    out = consistent_parameters(SPATIAL, ("",) * 10, T, T @ bad, 1e-6 * np.eye(10), bad, np.ones(10), [body],
                                metric="euclidean", prior_relative=1e6)
    np.testing.assert_allclose(pseudo_inertia(out.values), J_near, atol=2e-6)
    assert out.bodies[0].margin >= 0.0 and out.physical
    assert not out.reproduces_base          # a clipped eigenvalue of 0.3 is far beyond σ = 1e-3


def test_linear_gaussian_posterior_when_no_constraint_is_active():
    """Inside the constraints the euclidean problem is linear-Gaussian: its answer and the
    reported σ and prior share are the textbook posterior (H, C, prior N(π₀, (ρ s)²))."""
    rng = np.random.default_rng(7)
    body = PhysicalBody("b", tuple(range(10)))
    prior = values_of(np.diag([0.02, 0.01, 0.005, 1.0]) + 0.001)       # a well-inside body
    scale = np.abs(prior) + 0.01
    H = rng.normal(size=(6, 10))                                         # 6 base parameters of 10
    C = np.diag(rng.uniform(1e-3, 4e-3, 6)) ** 2
    beta = H @ (prior + 0.002 * rng.normal(size=10))
    rho = 0.5
    out = consistent_parameters(SPATIAL, ("",) * 10, H, beta, C, prior, scale, [body], metric="euclidean",
                                prior_relative=rho)
    P0 = np.diag((rho * scale) ** 2)
    post = np.linalg.inv(H.T @ np.linalg.inv(C) @ H + np.linalg.inv(P0))
    mean = prior + post @ H.T @ np.linalg.inv(C) @ (beta - H @ prior)
    assert margin(body, mean) > 0                                       # the constraint is inactive
    np.testing.assert_allclose(out.values, mean, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(out.sigma, np.sqrt(np.diag(post)), rtol=1e-9)
    # the prior's share of each error variance: the part the data do not see over the whole
    # (posterior mean error = -(post P0^-1) (pi - prior) + noise term)
    from_prior = post @ np.linalg.inv(P0) @ post
    np.testing.assert_allclose(out.prior_share, np.diag(from_prior) / np.diag(post), rtol=1e-9)
    residual = H @ out.values - beta
    assert out.chi2 == pytest.approx(residual @ np.linalg.solve(C, residual), rel=1e-6)


def test_planar_bodies_drive_terms_and_held_values():
    """The 3PRRR's kind of body (planar, centre of mass at the frame origin): an identified
    negative inertia and a negative friction come out at their bounds (0); a parameter no base
    parameter holds stays at its CAD value, decided by the prior; a held one keeps its value."""
    names = ("m", "I", "fv", "m2", "held")
    body = PhysicalBody("link", (0, -1, -1, 1), planar=True)
    other = PhysicalBody("ee", (3, -1, -1, -1), planar=True)
    H = np.array([[1.0, 0, 0, 0, 0], [0, 1.0, 0, 0, 0], [0, 0, 1.0, 0, 0]])
    beta = np.array([0.5, -0.002, -0.01])
    prior = np.array([0.4, 0.003, 0.0, 0.7, 2.0])
    out = consistent_parameters(names, ("kg", "kg m2", "N s/m", "kg", "kg"), H, beta, np.diag([1e-4, 1e-5, 1e-3]) ** 2,
                                prior, np.array([0.4, 0.003, 0.01, 0.7, 2.0]), [body, other], held={4: 2.5},
                                metric="euclidean")
    assert out.values[0] == pytest.approx(0.5, abs=1e-6)
    assert out.values[1] == pytest.approx(0.0, abs=1e-9) and out.values[2] == pytest.approx(0.0, abs=1e-8)
    assert out.values[3] == pytest.approx(0.7, rel=1e-6) and out.decided_by[3] == "prior"
    assert out.values[4] == pytest.approx(2.5, rel=1e-9) and out.decided_by[4] == "held"
    assert out.decided_by[:3] == ("data", "data", "data")
    assert np.linalg.eigvalsh(planar_pseudo_inertia([out.values[0], 0, 0, out.values[1]]))[0] >= -1e-9
    assert out.physical and not out.reproduces_base


def test_entropic_prior_keeps_a_body_realisable_and_reproduces_consistent_data():
    """The entropic prior on a body whose mass and first moment the data set: the implied base
    parameters match (χ² far below its quantile) and the body stays strictly inside."""
    body = PhysicalBody("b", tuple(range(10)))
    prior = values_of(np.diag([0.02, 0.01, 0.005, 1.0]))
    truth = prior.copy()
    truth[0] *= 1.2                                  # 20 % heavier, same second moments: still physical
    truth[1] = 0.05
    H = np.eye(10)[:4]                               # m and the first moment are identified
    out = consistent_parameters(SPATIAL, ("",) * 10, H, H @ truth, np.diag([1e-4] * 4) ** 2, prior,
                                np.abs(prior) + 0.01, [body], metric="entropic")
    assert out.reproduces_base and out.chi2 < 1e-3 * out.chi2_limit
    assert out.bodies[0].margin > 0


def test_bad_arguments():
    body = PhysicalBody("b", tuple(range(10)))
    with pytest.raises(ValueError, match="metric"):
        consistent_parameters(SPATIAL, ("",) * 10, np.eye(10), np.zeros(10), np.eye(10), np.zeros(10), np.ones(10),
                              [body], metric="manhattan")
    with pytest.raises(ValueError, match="scale"):
        consistent_parameters(SPATIAL, ("",) * 10, np.eye(10), np.zeros(10), np.eye(10), np.zeros(10), np.zeros(10),
                              [body])
    with pytest.raises(ValueError, match="indices"):
        PhysicalBody("b", (0, 1, 2))


def test_the_configs_delta_is_physical_and_table_1_as_printed_is_not():
    """Table 1's products of inertia, read as printed, make the arm and the rod unrealisable: no
    consistent set could reproduce a simulation of them. The configs' Delta is realisable."""
    from ident_hw.model.delta import Delta, nominal_parameters, physical_parameters

    bodies = Delta().physical_bodies()
    printed = {b.name: margin(b, nominal_parameters()) for b in bodies}
    assert printed["arm1"] < 0 and printed["rod1"] < 0
    assert all(margin(b, physical_parameters()) > 0 for b in bodies if b.name != "plat")
    assert margin(bodies[-1], physical_parameters()) >= 0                  # the platform: a point mass


def test_a_prior_on_the_boundary_of_physical_bodies_solves():
    """A CAD body an earlier consistent set left almost on its boundary (smallest eigenvalue of
    its pseudo-inertia 1e-8 of the largest, as an exported file's can be) as the entropic
    prior: the program still solves (that body keeps the euclidean term; with the log-det term
    Clarabel failed) and gives the data back."""
    body = PhysicalBody("b", tuple(range(10)))
    prior = values_of(np.diag([1e-8, 0.01, 0.005, 1.0]))
    assert 0 < margin(body, prior) < 1e-7
    truth = prior.copy()
    truth[0] = 1.1
    H = np.eye(10)[:4]
    out = consistent_parameters(SPATIAL, ("",) * 10, H, H @ truth, np.diag([1e-4] * 4) ** 2, prior,
                                np.abs(prior) + 0.01, [body], metric="entropic")
    assert out.reproduces_base and out.physical
