"""Each axis's gain against its own model refitted (``ident_hw.identification.axis_gain``), on
regressors built here whose truth is known: a gain put on one axis's forces comes back on that
axis, however unequal the axes' friction and noise; a correct model names none; two axes the data
cannot tell apart are named together."""

from __future__ import annotations

import numpy as np
import pytest

from ident_hw.identification.axis_gain import RANK_RTOL, SIGMAS, _outside_columns, _with_gains, axis_gains, sharing_axes

AXES = ("a1", "a2", "a3")


def three_axes(n: int = 4000):
    """A regressor (n, 3, 8) of three axes sharing two inertial parameters (each axis sees them
    through its own motion) and with viscous and Coulomb friction of its own, and the
    parameters: friction of the three axes unequal (1 : 3 : 0.5), as a real robot's joints."""
    t = np.arange(n) * 0.01
    Y = np.zeros((n, 3, 8))
    for j in range(3):
        q_dd = np.sin((0.7 + 0.4 * j) * t) + 0.5 * np.sin((1.9 + 0.3 * j) * t + j)
        q_d = np.cos((0.5 + 0.3 * j) * t + 0.2 * j)
        Y[:, j, 0] = q_dd                                   # shared inertia, through this axis's motion
        Y[:, j, 1] = (1.0 + 0.5 * j) * np.cos(0.9 * t + j)  # a shared coupling term
        Y[:, j, 2 + j] = q_d                                # viscous friction, own
        Y[:, j, 5 + j] = np.tanh(q_d / 1e-2)                # Coulomb friction, own
    pi = np.array([2.0, 0.8, 0.1, 0.3, 0.05, 0.2, 0.6, 0.1])
    return Y, pi


def fit(Y, tau):
    """Least squares of every parameter on (Y, tau) (NaN: a row left out), each axis weighted by
    the RMS of its residual, as the weighted fits of the project do."""
    ok = np.isfinite(tau)
    coef = np.linalg.lstsq(Y[ok], tau[ok], rcond=None)[0]
    w = 1.0 / np.sqrt(np.nanmean((tau - Y @ coef) ** 2, axis=0))
    A = (Y * w[None, :, None])[ok]
    return np.linalg.lstsq(A, (tau * w)[ok], rcond=None)[0]


def forces(Y, pi, gain, noise, seed=5):
    rng = np.random.default_rng(seed)
    return (Y @ pi) * (1.0 + np.asarray(gain)) + noise * rng.normal(size=(Y.shape[0], 3))


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_gain_on_one_axis_comes_back_on_that_axis(axis):
    """3 % on one axis's forces (its torque constant 3 % off), unequal noise on the three: the
    fit bends its parameters towards it, the refit with that axis's gain free gives the 3 %
    back (to first order: within 3 % of it), and that axis alone is named."""
    Y, pi = three_axes()
    gain = np.zeros(3)
    gain[axis] = 0.03
    tau = forces(Y, pi, gain, noise=np.array([0.002, 0.02, 0.005]))
    found = axis_gains(Y, tau, fit(Y, tau), range(8), AXES, limit=2.0)
    assert [n.axis for n in found.named] == [AXES[axis]]
    assert found.named[0].percent == pytest.approx(3.0, rel=0.03)
    assert found.gains[AXES[axis]].percent == pytest.approx(3.0, rel=0.03)
    for other in set(range(3)) - {axis}:       # the others back on their model
        assert abs(found.gains[AXES[other]].percent) < 0.2, found.gains


def test_a_correct_model_with_unequal_axes_names_none():
    """No gain, friction and noise unequal by a factor 10 between axes: every gain within a few
    of its standard errors of zero, nothing named."""
    Y, pi = three_axes()
    tau = forces(Y, pi, np.zeros(3), noise=np.array([0.002, 0.02, 0.005]))
    found = axis_gains(Y, tau, fit(Y, tau), range(8), AXES, limit=2.0)
    assert found.named == ()
    for g in found.gains.values():
        assert abs(g.percent) < SIGMAS * g.sigma_percent and g.determined(2.0), found.gains


def test_rows_left_out_are_not_judged_and_an_axis_absorbing_its_gain_is_not_determined():
    """NaN rows (an axis near rest) take no part, whatever their forces would have been; an axis
    whose forces are its own parameters alone (no shared column) has a gain its own parameters
    absorb: not determined, not named, though 5 % off."""
    Y, pi = three_axes()
    Y[:, 2, :2] = 0.0                          # the third axis sees no shared parameter
    tau = forces(Y, pi, np.array([0.0, 0.0, 0.05]), noise=0.003)
    tau[::3, 0] = np.nan                       # a third of the first axis's rows left out
    coef = fit(Y, tau)
    found = axis_gains(Y, tau, coef, range(8), AXES, limit=2.0)
    assert not found.gains["a3"].determined(2.0) and found.named == ()
    assert found.gains["a1"].determined(2.0) and abs(found.gains["a1"].percent) < 0.2


def test_two_axes_the_data_cannot_tell_apart_are_named_together():
    """A serial arm's first joint carries every parameter, its second a part: 5 % on the first
    fits as well as every parameter 5 % up and the second's gain 1/1.05 - 1 = -4.76 %. The first
    is named with the second beside it. The refit is linearised about the fit's parameters, so
    a gain comes back to first order: 5 % as 4.9 % here."""
    rng = np.random.default_rng(1)
    n = 3000
    t = np.arange(n) * 0.01
    Y = np.zeros((n, 2, 3))
    Y[:, 0, 0] = np.sin(1.1 * t)
    Y[:, 0, 1] = np.cos(0.7 * t)
    Y[:, 0, 2] = np.sin(0.4 * t + 1)
    Y[:, 1, 1] = np.sin(1.7 * t)
    Y[:, 1, 2] = np.cos(0.3 * t)
    pi = np.array([1.0, 0.5, 0.2])
    tau = (Y @ pi) * np.array([1.05, 1.0]) + 1e-4 * rng.normal(size=(n, 2))
    found = axis_gains(Y, tau, np.linalg.lstsq(Y.reshape(-1, 3), tau.ravel(), rcond=None)[0], range(3),
                       ("shoulder", "elbow"), limit=2.0)
    assert len(found.named) == 1
    named = found.named[0]
    alike = dict(named.alike)
    both = {named.axis: named.percent, **alike}
    assert set(both) == {"shoulder", "elbow"}
    assert both["shoulder"] == pytest.approx(5.0, rel=0.03) and both["elbow"] == pytest.approx(-4.76, rel=0.03)


def test_sharing_axes_by_their_columns():
    Y, _ = three_axes()
    assert sharing_axes(Y, range(8), AXES) == {"a1": ("a2", "a3"), "a2": ("a1", "a3"), "a3": ("a1", "a2")}
    assert sharing_axes(Y, range(2, 8), AXES) == {"a1": (), "a2": (), "a3": ()}


@pytest.mark.parametrize("rows", [4000, 18])
def test_the_part_outside_the_parameters_columns_is_the_svd_projections(rows):
    """``_outside_columns`` (one triangle of ``[A B]``) against the projection written out with
    NumPy's thin SVD of the column-scaled ``A``: on a tall ``A`` whose columns span eight
    decades, with a zero column and two columns combinations of others (rank 13 of 16), and on
    one with fewer rows than columns, the same rank, the same Gram matrix of what is left of
    ``B`` (rows, 4), and the same gains, residual and standard errors of ``_with_gains``."""
    rng = np.random.default_rng(7)
    A = rng.normal(size=(rows, 16)) * np.logspace(-4, 4, 16)
    A[:, 3] = 0.0
    A[:, 7] = 2.0 * A[:, 1] - 1e-3 * A[:, 9]
    A[:, 12] = A[:, 0] + A[:, 15]
    B = rng.normal(size=(rows, 4))
    B[:, 1] += A @ rng.normal(size=16) * 1e-2         # a column mostly inside A's space
    B[:, 2] = 1e3 * B[:, 2] + A[:, 5]
    norm = np.linalg.norm(A, axis=0)
    U, s, _ = np.linalg.svd(A[:, norm > 0] / norm[norm > 0], full_matrices=False)
    basis = U[:, s > RANK_RTOL * s[0]]
    left = B - basis @ (basis.T @ B)                   # (rows, 4): the projection itself
    outside, rank = _outside_columns(A, B)
    assert rank == basis.shape[1] == min(13, rows)
    gram, expected = outside.T @ outside, left.T @ left
    assert np.allclose(gram, expected, rtol=0, atol=1e-11 * np.linalg.norm(B, axis=0).max() ** 2)
    if rows > 100:
        assert np.allclose(gram, expected, rtol=1e-9, atol=0)
        G_norm = np.linalg.norm(B[:, 1:], axis=0)
        for which in ([0], [1, 2], [2, 0, 1]):
            mine = _with_gains(outside[:, 1:], G_norm, outside[:, 0], which, rows - rank)
            theirs = _with_gains(left[:, 1:], G_norm, left[:, 0], which, rows - rank)
            for a, b in zip(mine, theirs):
                assert np.allclose(a, b, rtol=1e-9, atol=0)
