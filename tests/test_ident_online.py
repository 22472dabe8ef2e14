"""Online estimators on one stream with known truth: SVD-DLS against RLS (same forgetting factor,
same data) and the damped RLS, warm-started from an offline WLS fit (scenario:
``ident_scenarios.online_scenario``: rich motion, a slow small circle, rich motion with a 0.5 kg
payload on the end-effector)."""

from __future__ import annotations

import numpy as np
import pytest

from ident_hw.identification import RLS, SVDDLS, DampedRLS, offline_information, run_stream, validation_metrics, wls
from ident_scenarios import CAD, NAMES, PAYLOAD_KG, TRUE, online_scenario

FORGETTING = 0.998  # memory 1/(1 − lambda) = 500 samples = 2.5 s at 200 Hz
#: Time within which SVD-DLS must reach the new m_ee to 5 % after the payload is added, s.
PAYLOAD_TRACKING_S = 1.0


def estimators(scenario):
    """Warm-started estimators on the same scaling: CAD magnitudes, outputs by their noise."""
    Y_off, tau_off = scenario.offline
    fit = wls(Y_off, tau_off, scenario.names)
    free = [NAMES.index(n) for n in scenario.names]
    scale = CAD.as_vector()[free]
    kw = dict(scale=scale, output_std=fit.output_std)
    info = offline_information(Y_off, FORGETTING, fit.output_std)
    ests = {"RLS": RLS(len(free), FORGETTING, **kw), "DampedRLS": DampedRLS(len(free), FORGETTING, damping=1.0, **kw),
            "SVD-DLS": SVDDLS(len(free), FORGETTING, threshold=100.0, **kw)}
    return {name: est.warm_start(fit.coef, info) for name, est in ests.items()}


def run_all(scenario):
    return {name: run_stream(est, scenario.Y, scenario.tau) for name, est in estimators(scenario).items()}


def j_rmse_table(scenario, traces) -> dict:
    """J_RMSE (the SVD-DLS paper, eq. 87) of the a-priori torque predictions against the noise-free
    forces, per method and phase (N and N·m mixed, as in the paper)."""
    return {name: [validation_metrics(scenario.tau_ref[scenario.phase == p], tr.predictions[scenario.phase == p]).j_rmse
                   for p in range(3)] for name, tr in traces.items()}


@pytest.fixture(scope="module")
def run():
    scenario = online_scenario()
    return scenario, run_all(scenario)


def test_both_converge_with_rich_excitation(run):
    sc, traces = run
    end_rich = np.flatnonzero(sc.phase == 0)[-1]
    for name in ("RLS", "SVD-DLS"):
        coef = traces[name].coef[end_rich]
        rel = np.abs(coef / sc.truth[end_rich] - 1)
        well = [sc.names.index(n) for n in ("m_c", "m_ee", "fv_zeta1", "fc_zeta1", "fv_theta1")]
        assert np.all(rel[well] < 0.05), (name, dict(zip(np.array(sc.names)[well], rel[well])))
    # and predict the forces to a small fraction of their size (noise of the data: 3 % per output)
    rich = sc.phase == 0
    force = np.sqrt(np.mean(np.sum(sc.tau_ref[rich] ** 2, axis=1)))
    for name, j in j_rmse_table(sc, traces).items():
        assert j[0] < 0.01 * force, (name, j[0], force)


def test_poor_excitation_winds_up_rls_but_not_svd_dls(run):
    sc, traces = run
    a_end, b_end = np.flatnonzero(sc.phase == 0)[-1], np.flatnonzero(sc.phase == 1)[-1]
    rls, svd = traces["RLS"], traces["SVD-DLS"]
    assert rls.covariance_trace[b_end] > 100 * rls.covariance_trace[a_end]  # wind-up: lambda^-t
    assert svd.covariance_trace[b_end] <= 2 * svd.covariance_trace[a_end]  # bounded
    assert svd.rank[b_end] < svd.rank[a_end]  # unexcited directions frozen
    # SVD-DLS keeps predicting the forces through the poor stretch and right after it
    table = j_rmse_table(sc, traces)
    assert table["SVD-DLS"][1] <= 1.05 * table["RLS"][1]
    assert table["SVD-DLS"][2] < table["RLS"][2]


def test_svd_dls_tracks_the_payload(run):
    sc, traces = run
    i_ee = sc.names.index("m_ee")
    target = TRUE.m_ee + PAYLOAD_KG
    c = sc.phase == 2
    t, m_ee = sc.t[c] - sc.t[c][0], traces["SVD-DLS"].coef[c, i_ee]
    outside = np.flatnonzero(np.abs(m_ee / target - 1) >= 0.05)
    settle = t[outside[-1] + 1] if outside.size else 0.0
    assert settle <= PAYLOAD_TRACKING_S, f"m_ee within 5 % of {target} kg only after {settle:.2f} s"
    assert abs(m_ee[-1] / target - 1) < 0.05


def test_svd_dls_with_everything_excited_is_rls_and_rls_ignores_the_scaling():
    """Identities of the algebra: with no direction below the threshold, eq. 77 is the RLS step
    (V_p Λ_p⁻¹ V_pᵀ = R_t⁻¹); RLS does not depend on the parameter scaling; output_std weights."""
    rng = np.random.default_rng(3)
    n, k = 7, 3
    Y = rng.normal(size=(400, k, n)) * np.logspace(-2, 2, n)
    tau = Y @ rng.normal(size=n) + 0.01 * rng.normal(size=(400, k))
    info = offline_information(Y[:50], 0.99)
    coef0 = np.linalg.lstsq(Y[:50].reshape(-1, n), tau[:50].reshape(-1), rcond=None)[0]
    svd = SVDDLS(n, 0.99, threshold=1e-12).warm_start(coef0, info).partial_fit(Y[50:], tau[50:])
    rls = RLS(n, 0.99).warm_start(coef0, info).partial_fit(Y[50:], tau[50:])
    scaled = RLS(n, 0.99, scale=np.logspace(3, -3, n)).warm_start(coef0, info).partial_fit(Y[50:], tau[50:])
    # output_std is a weighting: the same as feeding the weighted data
    w = np.array([0.1, 1.0, 10.0])
    weighted = RLS(n, 0.99, output_std=w).warm_start(coef0, offline_information(Y[:50], 0.99, w))
    by_hand = RLS(n, 0.99).warm_start(coef0, offline_information(Y[:50] / w[:, None], 0.99))
    weighted.partial_fit(Y[50:], tau[50:])
    by_hand.partial_fit(Y[50:] / w[:, None], tau[50:] / w)
    np.testing.assert_allclose(weighted.coef_, by_hand.coef_, rtol=1e-8)
    np.testing.assert_allclose(svd.coef_, rls.coef_, rtol=1e-8)
    np.testing.assert_allclose(svd.covariance_, rls.covariance_, rtol=1e-6)
    np.testing.assert_allclose(scaled.coef_, rls.coef_, rtol=1e-8)
    assert svd.rank_ == n and svd.n_samples_seen_ == 350


@pytest.mark.parametrize("held", [0, 6, 30])
def test_svd_dls_update_is_eq_77_with_the_full_eigendecomposition(held):
    """The update computes only the eigenpairs on one side of the threshold; a direct
    implementation of eq. 77 (full eigen-decomposition of R_t each sample) gives the same
    estimates and ranks, with 0, 6 or 30 of 40 directions never excited."""
    rng = np.random.default_rng(held)
    n, k, samples, forgetting, threshold = 40, 3, 400, 0.99, 50.0
    Y = rng.normal(size=(samples, k, n))
    Y[:, :, :held] = 0.0
    tau = Y @ rng.normal(size=n) + 0.1 * rng.normal(size=(samples, k))
    est = SVDDLS(n, forgetting, threshold=threshold)
    R, theta = np.zeros((n, n)), np.zeros(n)
    for i in range(samples):
        est.partial_fit(Y[i], tau[i])
        D = Y[i].T
        R = forgetting * R + D @ D.T
        lam, V = np.linalg.eigh(R)
        Vp, lp = V[:, lam >= threshold], lam[lam >= threshold]
        theta = theta + Vp @ ((Vp.T @ (D @ (tau[i] - D.T @ theta))) / lp)
        assert est.rank_ == len(lp)
        np.testing.assert_allclose(est.coef_, theta, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(theta).max()))
