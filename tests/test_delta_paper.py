"""The SVD-DLS paper's Delta paths and its offline analysis, against the figures of the Delta
spec: the ranges of the verification (eq. 60) and training (Table 2) paths, the condition numbers
of the column-normalised base regressor, the base regressor's defining identity, and the rank
lost when arm 3 is held."""

import numpy as np
import pytest

from ident_hw.model.delta import PARAM_NAMES, Delta, closed_form_base
from trajectories.delta_paper import delta_trajectory, held_arm_path, training_path, verification_path

ROBOT = Delta()


@pytest.mark.parametrize("path, seconds, samples, q_deg, c_deg, serial, cond_D, tau_max", [
    (verification_path, 10.0, 1001, 28.6, 16.0, 0.425, 1.66, 10.88),
    (training_path, 30.0, 301, 17.5, 7.2, 0.620, None, 9.17),
])
def test_path_ranges(path, seconds, samples, q_deg, c_deg, serial, cond_D, tau_max):
    from ident_hw.model.delta import nominal_parameters
    t = np.linspace(0.0, seconds, samples)
    m = path(t)
    q, qd, qdd = m.q, m.qd, m.qdd
    _, c = ROBOT.rod_angles(q)
    measure, cond = ROBOT.singularity(q)
    assert np.degrees(np.abs(q).max()) == pytest.approx(q_deg, abs=0.05)
    assert np.degrees(np.abs(c).max()) == pytest.approx(c_deg, abs=0.05)
    assert measure.min() == pytest.approx(serial, abs=5e-4)
    if cond_D is not None:
        assert cond.max() == pytest.approx(cond_D, abs=5e-3)
    tau = ROBOT.inverse_dynamics(q, qd, qdd, nominal_parameters())
    assert np.abs(tau).max() == pytest.approx(tau_max, abs=5e-3)
    if path is verification_path:
        z = ROBOT.fk(q)[:, 2]
        assert (z.min(), z.max()) == pytest.approx((-0.566, -0.331), abs=1e-3)   # the spec's 3 decimals


@pytest.mark.parametrize("path, seconds, samples, cond", [
    (training_path, 30.0, 301, 2.699e3),
    (verification_path, 10.0, 101, 9.421e2),
])
def test_condition_of_the_column_normalised_base_regressor(path, seconds, samples, cond):
    base = closed_form_base(ROBOT.geometry, drive_terms=False)
    m = path(np.linspace(0.0, seconds, samples))
    q, qd, qdd = m.q, m.qd, m.qdd
    W = ROBOT.regressor(q, qd, qdd).reshape(-1, len(PARAM_NAMES))[:, [PARAM_NAMES.index(k) for k in base.kept]]
    assert np.linalg.matrix_rank(W) == 34
    assert np.linalg.cond(W / np.linalg.norm(W, axis=0)) == pytest.approx(cond, rel=5e-4)


def test_base_regressor_predicts_every_parameter_vector():
    """``Y pi = Y[:, :, kept] (H pi)`` for any pi: the eliminated columns are the combinations H says."""
    base = closed_form_base(ROBOT.geometry)
    m = training_path(np.linspace(0.0, 30.0, 301))
    q, qd, qdd = m.q, m.qd, m.qdd
    Y = ROBOT.regressor(q, qd, qdd)
    kept = [PARAM_NAMES.index(k) for k in base.kept]
    for seed in range(3):
        pi = np.random.default_rng(seed).normal(size=len(PARAM_NAMES))
        np.testing.assert_allclose(Y[:, :, kept] @ (base.H @ pi), Y @ pi, atol=1e-11 * np.abs(Y @ pi).max())


def test_holding_arm_3_loses_two_base_parameters():
    m = held_arm_path(np.linspace(0.0, 10.0, 401))
    q, qd, qdd = m.q, m.qd, m.qdd
    assert np.all(q[:, 2] == 0.0)
    W = ROBOT.regressor(q, qd, qdd)[:, :, :70].reshape(-1, 70)
    norms = np.linalg.norm(W, axis=0)
    W = W[:, norms > 1e-10 * norms.max()]
    s = np.linalg.svd(W / np.linalg.norm(W, axis=0), compute_uv=False)
    assert int(np.sum(s > 1e-9 * s[0])) == 32


def test_per_arm_amplitudes_scale_each_arm_s_angles_and_rates():
    robot = Delta()
    one = delta_trajectory(robot, "delta_training", 5.0, 100.0)
    scaled = delta_trajectory(robot, "delta_training", 5.0, 100.0, amplitude=(2.0, 1.0, 0.5))
    for a, b in ((one.Theta, scaled.Theta), (one.Thetad, scaled.Thetad), (one.Thetadd, scaled.Thetadd)):
        np.testing.assert_allclose(b, a * [2.0, 1.0, 0.5], rtol=0, atol=1e-15)
    assert scaled.metadata["amplitude"] == [2.0, 1.0, 0.5]
