"""Link parameters from the rig's reported data are unbiased (issue 5/6): no SYNC-rate ripple aliased.

A real canopen master streams the paper's five squares (``trajectories.five_squares``, carriages
blocked) to the six emulated EPOS4 in CSP at 250 Hz, in lockstep (``stream_lockstep`` of
``test_sim_cyclic``), with 2 mA of current noise. From the REPORTED counts and milliamps only,
``build_dataset`` of ``measured_dataset`` (low-pass, central differences, parallel filter) and
OLS fit the link parameters ``I_l1, m_l2, I_l2, m_ee, fv_theta1..3, fc_theta1..3`` on the
three link torques, the other parameters known (their contribution subtracted).

With the former C1 (cubic Hermite) demand, whose acceleration steps at every SYNC, this run gave
viscous link friction +24..+33 % and I_l1, m_l2, I_l2, m_ee off by 12 sigma: the force ripple at
the SYNC rate is caught by the current at the same phase of each period. With the C2 B-spline
demand of :mod:`drivers.sim.drive`: +8..+11 %, the four inertial parameters still 15 sigma off.
What is left is measured, not removed (hence the strict xfail):

- the integer targets: the central-difference acceleration differs from the plant's exact one by
  0.95 rad/s^2 rms (7 %), correlated at -0.7 with the rounding of the streamed targets; with 16x
  finer link encoders m_l2, I_l2, m_ee come within 0.5 sigma, fv_theta stays +6..+10 %;
- the same fit of the commanded squares themselves (exact inverse dynamics, no rig) through
  ``build_dataset`` at 250 Hz gives I_l1 +1475 %, m_ee +487 % (fv +1..+3 %): these four are nearly
  collinear on the squares (the base parameters combine them with m_ee), so a 1 % differentiation
  error moves them far and, through their correlation, the viscous friction with them.
"""

import numpy as np
import pytest

import nominal
from measured_dataset import build_dataset
from ident_hw.identification.least_squares import ols
from ident_hw.model import ThreePRRR
from trajectories import Limits, five_squares

from test_sim_cyclic import COUNTS_PER_UNIT, FORCE_PER_AMP, stream_lockstep
from test_sim_rig import Bench, wait_until

PERIOD = 0.004
ROBOT = ThreePRRR(nominal.GEOMETRY)
TRUE = nominal.TRUE_PARAMS
FITTED = ("I_l1", "m_l2", "I_l2", "m_ee", "fv_theta1", "fv_theta2", "fv_theta3",
          "fc_theta1", "fc_theta2", "fc_theta3")


@pytest.fixture(scope="module")
def squares_run():
    """The five squares one after the other (each from home back to home), streamed once."""
    Theta = np.concatenate([s.Theta for s in five_squares(ROBOT, Limits(), rate=1.0 / PERIOD)])
    home = Theta[0]
    targets = np.rint((Theta - home) * COUNTS_PER_UNIT)
    bench = Bench(sync_period=PERIOD, current_noise_ma=2.0, seed=11)
    try:
        bench.rig.start()
        counts, milliamps = stream_lockstep(bench, targets)
        assert wait_until(lambda: bench.rig.syncs_done == bench.rig.sync_count)
    finally:
        bench.close()
    return dict(counts=counts, milliamps=milliamps, home=home)


@pytest.mark.xfail(strict=True, raises=AssertionError,
                   reason="link inertias 26-30 sigma off on the squares (m_l2 comes out negative): target "
                          "rounding through a nearly collinear inertial block; the viscous friction passes")
def test_link_parameters_from_the_reported_data_are_unbiased(squares_run):
    counts = squares_run["counts"]
    t = np.arange(len(counts)) * PERIOD
    Theta = squares_run["home"] + counts / COUNTS_PER_UNIT
    data = build_dataset(ROBOT, t, Theta, squares_run["milliamps"] * 1e-3, FORCE_PER_AMP, np.zeros(3))
    names = list(TRUE.NAMES)
    fitted = [names.index(k) for k in FITTED]
    known = [k for k in range(len(names)) if k not in fitted]
    Y = data.Y[:, :3, :]                                                 # link torque rows
    rhs = data.tau[:, :3] - Y[..., known] @ TRUE.as_vector()[known]
    fit = ols(Y[..., fitted], rhs, FITTED)
    truth = TRUE.as_vector()[fitted]
    rel = fit.coef / truth - 1.0
    for name, c, s, tr, r in zip(FITTED, fit.coef, fit.std, truth, rel):
        print(f"{name:10s} {c:11.6f} ± {s:.6f}  truth {tr:.6f}  {100 * r:+6.2f} %  {(c - tr) / s:+5.1f} sigma")
    viscous = slice(4, 7)
    assert np.all(np.abs(rel[viscous]) < 0.05), "viscous link friction biased"
    masses = [FITTED.index(k) for k in ("m_l2", "I_l2", "m_ee")]
    assert np.all(np.abs(fit.coef[masses] - truth[masses]) < 3.0 * fit.std[masses])
