"""The synthetic identification data of ``ident_scenarios`` checked against the model."""

import numpy as np
import pytest

from ident_scenarios import COUNTS_PER_UNIT, FORCE_PER_AMP, RICH, ROBOT, TRUE, make_motion, measure, sines


def test_motion_stays_in_the_workspace_and_regressor_matches_inverse_dynamics():
    m = make_motion(duration=4.0, rate=200.0)
    assert np.all(np.abs(m.X[:, :2]) <= 0.06) and np.all(np.abs(m.X[:, 2]) <= 0.3) and np.all(np.abs(m.zeta) <= 0.05)
    margins = ROBOT.singularity_margins(m.X, m.zeta)
    assert margins.cond_A.max() < 50 and margins.serial.min() > 0.1
    q, qd, qdd = sines(RICH, m.t)
    tau = ROBOT.inverse_dynamics(q[:, :3], qd[:, :3], qdd[:, :3], q[:, 3:], qd[:, 3:], qdd[:, 3:], TRUE)
    np.testing.assert_allclose(m.tau, tau, rtol=1e-9, atol=1e-9 * np.abs(tau).max())


def test_measurement_is_quantised():
    m = make_motion(duration=1.0, rate=100.0)
    Theta, current = measure(m, np.random.default_rng(0))
    np.testing.assert_allclose(Theta * COUNTS_PER_UNIT, np.round(Theta * COUNTS_PER_UNIT), atol=1e-6)
    np.testing.assert_allclose(current * 1e3, np.round(current * 1e3), atol=1e-9)
    assert np.all(np.abs(Theta - m.Theta).max(axis=0) <= 1.5 / COUNTS_PER_UNIT + 1e-12)  # half a count + the offset
    with pytest.raises(AssertionError):  # the noise is really there
        np.testing.assert_allclose(current, m.tau / FORCE_PER_AMP, atol=2e-3)
