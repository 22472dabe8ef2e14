"""Physics of the simulated rig: units end to end, consistency with the model, payload."""

import math

import numpy as np

from drivers.sim import Plant
from ident_hw.model import ThreePRRR

from test_sim_rig import GEO, PRI, TRUE, Bench, configure_pdos, wait_until  # noqa: F401


def run_plant(plant, seconds, period, demand_fn):
    enabled = np.ones(6, bool)
    limit = np.full(6, 1e6)
    for k in range(int(round(seconds / period))):
        t = k * period
        d0, d1 = demand_fn(t), demand_fn(t + period)
        plant.step(period, d0, (d1 - d0) / period, enabled, limit)


def test_held_carriage_against_a_known_force_reports_the_hand_computed_current():
    b = Bench(sync_period=0.004)
    try:
        b.rig.start()
        node = b.nodes[3]
        configure_pdos(node, "EPOS4")
        b.rig.set_external_force([0, 0, 0, 100.0, 0, 0])      # 100 N pushing carriage 1
        node.sdo[0x6060].raw = 8
        for cw in (0x06, 0x07, 0x0F):
            node.sdo[0x6040].raw = cw
        currents = []
        node.tpdo[1].add_callback(lambda m: currents.append(m[1].raw))
        b.master.nmt.state = "OPERATIONAL"
        b.master.sync.start(0.004)
        # hand computation: F = K_m * 2 pi / p * I  ->  I = -100 N / (0.0603 * 2 pi / 0.002) = -527.8 mA
        expected_ma = -100.0 / (0.0603 * 2 * math.pi / 0.002) * 1e3
        assert wait_until(lambda: len(currents) > 150, timeout=3.0)
        assert abs(np.median(currents[-20:]) - expected_ma) <= 1.0
        # ... and back: the master's conversion gives the force
        assert abs(PRI.force_per_amp * PRI.current_from_ma(np.median(currents[-20:])) + 100.0) < 0.2
    finally:
        b.close()


def test_logged_forces_equal_the_lagrange_inverse_dynamics_of_the_logged_motion():
    robot = ThreePRRR(GEO)
    plant = Plant(robot, TRUE)
    home = plant.Theta.copy()
    amp = np.array([0.1, -0.1, 0.05, 0.01, -0.01, 0.005])
    run_plant(plant, 0.5, 0.002, lambda t: home + amp * np.sin(2 * np.pi * 2 * t))
    tr = plant.truth()
    X, Xd, Xdd = robot.pose_motion(tr["Theta"], tr["Thetad"], tr["Thetadd"], np.zeros(3))
    tau = robot.inverse_dynamics(X, Xd, Xdd, tr["Theta"][:, 3:], tr["Thetad"][:, 3:], tr["Thetadd"][:, 3:], TRUE)
    scale = np.abs(tr["force"]).max(axis=0)
    assert np.all(scale > 0)
    assert np.all(np.abs(tau - tr["force"]).max(axis=0) / scale < 1e-9)
    # the robot followed the demand (position loop works)
    assert np.abs(tr["Theta"][-1] - (home + amp * np.sin(2 * np.pi * 2 * tr["t"][-1]))).max() < 0.2 * amp.max()


def test_payload_changes_the_forces_as_the_model_predicts():
    robot = ThreePRRR(GEO)
    plant = Plant(robot, TRUE)
    plant.set_payload(0.5, 0.002)
    home = plant.Theta.copy()
    amp = np.array([0.1, -0.1, 0.05, 0.0, 0.0, 0.0])
    run_plant(plant, 0.3, 0.002, lambda t: home + amp * np.sin(2 * np.pi * 2 * t))
    tr = plant.truth()
    X, Xd, Xdd = robot.pose_motion(tr["Theta"], tr["Thetad"], tr["Thetadd"], np.zeros(3))
    args = (X, Xd, Xdd, tr["Theta"][:, 3:], tr["Thetad"][:, 3:], tr["Thetadd"][:, 3:])
    heavy = TRUE.replace(m_ee=TRUE.m_ee + 0.5, I_ee=TRUE.I_ee + 0.002)
    err_heavy = np.abs(robot.inverse_dynamics(*args, heavy) - tr["force"]).max()
    err_nominal = np.abs(robot.inverse_dynamics(*args, TRUE) - tr["force"]).max()
    assert err_heavy < 1e-9 * np.abs(tr["force"]).max()
    assert err_nominal > 1e3 * err_heavy
