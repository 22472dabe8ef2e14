"""Offline identification on model-made data with known truth: base parameters, OLS/WLS, SQP."""

from __future__ import annotations

import numpy as np
import pytest

from ident_hw.identification.base_params import base_parameters, identify_base
from ident_hw.model.combinations import format_combination
from ident_hw.identification.least_squares import ols, wls
from ident_hw.identification.mass_fit import sqp_fit
from ident_scenarios import CAD, GEOMETRY, NAMES, RICH, TRUE, make_motion

TRUTH = TRUE.as_vector()
SCALE = CAD.as_vector()


@pytest.fixture(scope="module")
def rich():
    return make_motion(duration=10.0, rate=200.0)


def symmetric_null_vector() -> np.ndarray:
    """The structural null direction of the symmetric 3PRRR, derived by hand.

    Link 2 (mass 1, centre at s2 from B) equals a point mass (1 − s2/l2) at B, a point mass
    s2/l2 at C and a rotational remainder. The point at B is absorbed by link 1 and the
    carriage (first moment about A, inertia about A, translating mass), the points at the
    three C_i by the end-effector (symmetric platform: at its centre, at radius h).
    """
    g = GEOMETRY
    m_B, m_C = 1 - g.s2 / g.l2, g.s2 / g.l2
    d_ml1 = -m_B * g.l1 / g.s1
    v = np.zeros(len(NAMES))
    v[NAMES.index("m_l2")] = 1.0
    v[NAMES.index("I_l2")] = m_C * g.l2**2 - g.s2**2
    v[NAMES.index("m_l1")] = d_ml1
    v[NAMES.index("m_c")] = -m_B - d_ml1
    v[NAMES.index("I_l1")] = -m_B * g.l1**2 - d_ml1 * g.s1**2
    v[NAMES.index("m_ee")] = -3 * m_C
    v[NAMES.index("I_ee")] = -3 * m_C * g.h**2
    return v


def test_symmetric_robot_has_one_structural_null_direction(rich):
    base = base_parameters(rich.Y, NAMES, scale=SCALE)
    assert base.rank == len(NAMES) - 1
    v = symmetric_null_vector()
    n = base.null_space[:, 0]
    np.testing.assert_allclose(n / n[NAMES.index("m_l2")], v, rtol=1e-8, atol=1e-10)
    # every base parameter is blind to the null direction, and reproduces the torques
    np.testing.assert_allclose(base.H @ v, 0, atol=1e-9)
    kept = [NAMES.index(k) for k in base.kept]
    np.testing.assert_allclose(rich.Y[:, :, kept] @ base.reduce(TRUTH), rich.tau, rtol=1e-9, atol=1e-9)


def test_blocked_carriages_name_the_unexcited_parameters():
    spec = [terms if j < 3 else [] for j, terms in enumerate(RICH)]  # zeta = 0: the five squares' case
    m = make_motion(spec, duration=10.0, rate=200.0)
    base = base_parameters(m.Y, NAMES, scale=SCALE)
    zeta_friction = tuple(n for n in NAMES if n.startswith(("fv_zeta", "fc_zeta")))
    assert base.rank == len(NAMES) - 1 - 1 - 6
    assert set(base.unexcited) == {"m_c", *zeta_friction}
    assert len(set(base.eliminated) - set(base.unexcited)) == 1  # the structural regrouping
    for expr in base.expressions:
        assert "m_c" not in expr and "zeta" not in expr


def test_format_combination_reads_like_algebra():
    assert format_combination(np.array([1.0, 0.25, 0.0]), ["m_l1", "m_l2", "m_c"]) == "m_l1 + 0.25 m_l2"
    assert format_combination(np.array([-1.0, 1.0]), ["a", "b"]) == "-a + b"
    assert format_combination(np.array([2.0, -0.0225]), ["I_l1", "m_l1"]) == "2 I_l1 - 0.0225 m_l1"


def test_noise_free_base_parameters_exact(rich):
    base, fit = identify_base(rich.Y, rich.tau, NAMES, scale=SCALE)
    np.testing.assert_allclose(fit.coef, base.reduce(TRUTH), rtol=1e-6)
    assert fit.names == base.expressions
    assert np.all(fit.residual_rms < 1e-9 * np.sqrt(np.mean(rich.tau**2, axis=0)))


def test_full_set_is_rank_deficient_with_a_clear_error(rich):
    with pytest.raises(ValueError, match="rank deficient.*base"):
        ols(rich.Y, rich.tau, NAMES)


def test_noise_free_sqp_lsq_linear_and_ols_recover_the_identifiable_subset(rich):
    # I_l2 held at its true value breaks the structural null direction (its I_l2 entry is non-zero).
    free = [n for n in NAMES if n != "I_l2"]
    initial = CAD.replace(I_l2=TRUE.I_l2).as_vector()
    fit = sqp_fit(rich.Y, rich.tau, NAMES, initial, free=free)
    assert fit.success
    np.testing.assert_allclose(fit.coef, TRUTH, rtol=1e-6)
    np.testing.assert_allclose(fit.coef_lsq, TRUTH, rtol=1e-6)
    assert fit.max_rel_difference < 1e-6 and fit.iterations > 1 and fit.at_bounds == ()
    cols = [NAMES.index(n) for n in free]
    tau_rest = rich.tau - rich.Y[:, :, NAMES.index("I_l2")] * TRUE.I_l2
    np.testing.assert_allclose(ols(rich.Y[:, :, cols], tau_rest, free).coef, TRUTH[cols], rtol=1e-6)


def test_sqp_subset_carriage_mass_only(rich):
    """The carriage-sweep use: only m_c free, everything else held (at the truth here)."""
    initial = TRUTH.copy()
    initial[0] = 780.0
    fit = sqp_fit(rich.Y, rich.tau, NAMES, initial, free=["m_c"], bounds={"m_c": (100.0, 1000.0)})
    assert fit.coef[0] == pytest.approx(TRUE.m_c, rel=1e-9)
    np.testing.assert_array_equal(fit.coef[1:], TRUTH[1:])


def test_sqp_active_bound_agrees_with_lsq_linear(rich):
    initial = TRUTH.copy()
    fit = sqp_fit(rich.Y, rich.tau, NAMES, initial, free=["m_c", "m_ee"], bounds={"m_c": (700.0, 900.0)})
    assert fit.coef[0] == pytest.approx(700.0) and fit.at_bounds == ("m_c",)
    assert fit.max_rel_difference < 1e-6


def test_sqp_rejects_bad_names(rich):
    with pytest.raises(ValueError, match="m_x"):
        sqp_fit(rich.Y, rich.tau, NAMES, TRUTH, free=["m_x"])
    with pytest.raises(ValueError, match="I_ee"):
        sqp_fit(rich.Y, rich.tau, NAMES, TRUTH, free=["m_c"], bounds={"I_ee": (0, 1)})


@pytest.mark.slow
def test_statistics_against_monte_carlo():
    """On white noise, both covariances match the spread of the estimates over noise draws:
    the power-model paper's sigma² (WᵀW)⁻¹ (lags=0) and the default HAC sandwich."""
    rng = np.random.default_rng(7)
    m = make_motion(duration=2.0, rate=100.0)
    cols = [NAMES.index(n) for n in NAMES if n != "I_l2"]
    names = [NAMES[c] for c in cols]
    Y = m.Y[:, :, cols]
    sigma = np.array([0.01] * 3 + [5.0] * 3)
    noisy = [m.tau + rng.normal(size=m.tau.shape) * sigma for _ in range(100)]
    white = [wls(Y, tau, names, sigma, lags=0) for tau in noisy]
    spread = np.std([d.coef for d in white], axis=0)
    predicted = white[0].std / np.sqrt(white[0].sigma2)  # known sigma: covariance (W^T W)^-1
    np.testing.assert_allclose(spread, predicted, rtol=0.3)  # 100 draws: ~7 % sampling error on a std
    hac = [wls(Y, tau, names, sigma) for tau in noisy[:20]]
    assert hac[0].lags == 4
    np.testing.assert_allclose(np.sqrt(np.mean([d.std**2 for d in hac], axis=0)), predicted, rtol=0.3)
