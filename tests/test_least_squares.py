"""The least squares (ident_hw.identification.least_squares) and the base parameters' shared
triangle (ident_hw.identification.base_params.Triangle) against independent computations:
NumPy's SVD-based ``lstsq`` for the estimates, the covariance formulas written out with
``numpy.linalg.pinv``, NumPy's SVD for singular values, on data whose columns differ in size
by orders of magnitude (kg next to kg·m², as the robots' regressors do)."""

import numpy as np
import pytest

from ident_hw.identification.base_params import Triangle, base_parameters, column_scale, scaled_condition
from ident_hw.identification.least_squares import check_regression_data, stack
from ident_hw.identification import least_squares
from ident_hw.identification.least_squares import estimate, estimate_columns, ols, wls


def _data(seed=0, N=400, k=3, n=7, spread=1e4):
    rng = np.random.default_rng(seed)
    Y = rng.standard_normal((N, k, n)) * np.logspace(0, np.log10(spread), n)   # columns 1 .. 1e4
    coef = rng.uniform(0.5, 2.0, n) / np.logspace(0, np.log10(spread), n)
    noise = np.array([0.01, 0.1, 1.0])[:k]
    tau = Y @ coef + rng.standard_normal((N, k)) * noise
    tau[5, 1] = np.nan          # a row left out
    return Y, tau, [f"p{i}" for i in range(n)]


def _stacked(Y, tau, w):
    keep = ~np.isnan(tau)
    Yw, tw = Y * w[None, :, None], np.where(keep, tau, 0.0) * w
    Yw = np.where(keep[..., None], Yw, 0.0)
    return Yw.transpose(1, 0, 2).reshape(-1, Y.shape[2]), tw.T.reshape(-1)


def _close(a, b, rtol=1e-9):
    assert np.max(np.abs(a - b) / np.abs(b)) < rtol


def test_ols_estimate_and_white_covariance_match_lstsq_and_pinv():
    Y, tau, names = _data()
    fit = ols(Y, tau, names, lags=0)
    W, y = _stacked(Y, tau, np.ones(Y.shape[1]))
    ref = np.linalg.lstsq(W, y, rcond=None)[0]
    _close(fit.coef, ref)
    r, n = int(np.sum(np.any(W != 0, axis=1))), W.shape[1]
    sigma2 = np.sum((y - W @ ref) ** 2) / (r - n)
    _close(fit.covariance.diagonal(), sigma2 * np.linalg.pinv(W.T @ W).diagonal())
    _close(np.array(fit.sigma2), np.array(sigma2))
    _close(estimate(Y, tau, names), ref)


def test_wls_with_known_weights_matches_lstsq_and_the_hac_sandwich():
    Y, tau, names = _data(seed=1)
    std = np.array([0.01, 0.1, 1.0])
    fit = wls(Y, tau, names, output_std=std, lags=3)
    W, y = _stacked(Y, tau, 1.0 / std)
    ref = np.linalg.lstsq(W, y, rcond=None)[0]
    _close(fit.coef, ref)
    _close(estimate(Y, tau, names, std), ref)
    # the Newey-West sandwich written out (per-sample scores of all outputs, Bartlett weights)
    N, k, n = Y.shape
    Wt, yt = W.reshape(k, N, n), y.reshape(k, N)
    g = np.einsum("jtn,jt->tn", Wt, yt - Wt @ ref)
    meat = sum((1 - abs(lag) / 4) * (g[max(lag, 0):N + min(lag, 0)].T @ g[max(-lag, 0):N - max(lag, 0)])
               for lag in range(-3, 4))
    bread = np.linalg.pinv(W.T @ W)
    r = int(np.sum(np.any(W != 0, axis=1)))
    _close(fit.covariance.diagonal(), (bread @ meat @ bread * r / (r - n)).diagonal())


def test_feasible_wls_converges_to_a_fixed_point_of_its_weights():
    Y, tau, names = _data(seed=2)
    fit = wls(Y, tau, names, rtol=1e-12, max_iterations=50)
    W, y = _stacked(Y, tau, 1.0 / fit.output_std)
    _close(fit.coef, np.linalg.lstsq(W, y, rcond=None)[0])


def test_rank_deficient_regressor_is_refused():
    Y, tau, names = _data(seed=3)
    Y[:, :, 1] = 2.0 * Y[:, :, 0]
    with pytest.raises(ValueError, match="rank deficient"):
        ols(Y, tau, names)


def test_several_right_hand_sides_on_one_factorisation_match_lstsq_each():
    Y, tau, names = _data(seed=4)
    std = np.array([0.01, 0.1, 1.0])
    rng = np.random.default_rng(5)
    columns = rng.standard_normal(tau.shape + (4,)) * std[None, :, None]
    columns[np.isnan(tau)] = np.nan            # the rows tau leaves out, in every column
    got = estimate_columns(Y, columns, names, std)
    for m in range(columns.shape[2]):
        W, y = _stacked(Y, columns[:, :, m], 1.0 / std)
        _close(got[:, m], np.linalg.lstsq(W, y, rcond=None)[0])
    with pytest.raises(ValueError, match="same rows left out"):
        columns[7, 0, 2] = np.nan
        estimate_columns(Y, columns, names, std)


def test_one_triangle_serves_the_base_parameters_at_any_scale():
    """A regressor with a regrouping (column 2 = column 0 + 3 column 1) and an unexcited column:
    the base parameters from a triangle factorised at one scale, used at another, are those of
    the regressor factorised at that scale, and their singular values NumPy's SVD's."""
    rng = np.random.default_rng(6)
    W = rng.standard_normal((300, 6)) * np.logspace(0, 3, 6)
    W[:, 2] = W[:, 0] + 3.0 * W[:, 1]
    W[:, 5] = 0.0
    names = [f"p{i}" for i in range(6)]
    cad = np.array([2.0, 0.1, 1e-3, 5.0, 0.3, 1.0])
    triangle = Triangle.of(W, column_scale(W[:, None, :]))
    shared = base_parameters(W, names, scale=cad, triangle=triangle)
    direct = base_parameters(W, names, scale=cad)
    assert shared.rank == direct.rank == 4 and shared.kept == direct.kept
    np.testing.assert_allclose(shared.H, direct.H, rtol=1e-9, atol=1e-12)
    s = np.linalg.svd(W * cad, compute_uv=False)
    np.testing.assert_allclose(shared.singular_values[:4], s[:4], rtol=1e-12)
    assert np.all(shared.singular_values[4:] < 1e-8 * s[0])


def test_the_triangle_gives_the_scaled_condition_of_any_columns():
    """The scaled condition of some of a regressor's columns from the triangle of all of them
    (factorised at another column scale, with rows left out) against NumPy's SVD of the tall
    stacked columns scaled to unit RMS over the rows kept: within 1e-9."""
    Y, tau, names = _data(seed=3, N=500, k=3, n=7)
    tau[40:60, 2] = np.nan
    W, _ = stack(*check_regression_data(Y, tau))
    triangle = Triangle.of(W, np.logspace(0, 2, 7))
    for columns in ([0, 1, 2, 3, 4, 5, 6], [6, 1, 3], [2]):
        tall = W[:, columns][np.any(W[:, columns] != 0, axis=1)]
        tall = tall / np.sqrt(np.mean(tall ** 2, axis=0))
        s = np.linalg.svd(tall, compute_uv=False)
        assert triangle.scaled_condition(columns) == pytest.approx(s[0] / s[-1], rel=1e-9)
        assert triangle.scaled_condition(columns) == pytest.approx(scaled_condition(Y[:, :, columns], tau), rel=1e-9)


def test_a_refit_near_a_fit_iterates_on_its_triangle_to_lstsq(monkeypatch):
    """Data read again (the regressor moved by noise 1e-3 of each column's size, columns over
    four decades, a row left out) refitted on the first fit's triangle (``estimate(near=)``):
    NumPy's lstsq of the moved data within 1e-9, weighted and not, in a few iterations; with
    too few iterations allowed, the refit falls back to a factorisation of its own, still lstsq's."""
    Y, tau, names = _data(seed=8, N=2000)
    std = np.array([0.01, 0.1, 1.0])
    rng = np.random.default_rng(9)
    moved = Y * (1.0 + 1e-3 * rng.standard_normal(Y.shape))
    monkeypatch.setattr(least_squares, "PRECONDITIONED_FROM", 1)      # these 7 columns iterate too
    for output_std in (std, None):
        fit = wls(Y, tau, names, output_std=std) if output_std is not None else ols(Y, tau, names)
        assert fit.triangle is not None
        W, y = _stacked(moved, tau, np.ones(3) if output_std is None else 1.0 / std)
        expected = np.linalg.lstsq(W, y, rcond=None)[0]
        _close(estimate(moved, tau, names, output_std, near=fit.triangle), expected)
        monkeypatch.setattr(least_squares, "PRECONDITIONED_ITERATIONS", 6)
        _close(least_squares._preconditioned(W, y, fit.triangle), expected)
        monkeypatch.setattr(least_squares, "PRECONDITIONED_ITERATIONS", 1)
        assert least_squares._preconditioned(W, y, fit.triangle) is None
        _close(estimate(moved, tau, names, output_std, near=fit.triangle), expected)
        monkeypatch.setattr(least_squares, "PRECONDITIONED_ITERATIONS", 40)
