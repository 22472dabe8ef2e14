"""Physics of the simulated rig: consistency with the model, energy balance, jam, units, payload."""

import gc
import math

import numpy as np

from drivers.sim import Plant, PlantJammed, TruthLog
import nominal
from ident_hw.model import Delta, ThreePRRR
from ident_hw.model.delta import N_BODY_PARAMS, nominal_parameters
from ident_hw.model.dynamics import friction
from ident_hw.filtering import central_derivatives

from ident_scenarios import follow_targets
from test_sim_rig import PRI, Bench, configure_pdos, wait_until

ROBOT = ThreePRRR(nominal.GEOMETRY)
TRUE = nominal.TRUE_PARAMS


def task_space_demand(t):
    """A large motion inside the workspace (cond_A < 11): x, y +-5/4 cm, alpha +-0.25 rad, carriages +-3 cm."""
    t = np.atleast_1d(t)
    X = np.stack([0.05 * np.sin(2 * np.pi * 2 * t), 0.04 * np.sin(2 * np.pi * 3 * t + 1),
                  0.25 * np.sin(2 * np.pi * 1.5 * t)], -1)
    zeta = np.stack([0.03 * np.sin(2 * np.pi * t + k) for k in range(3)], -1)
    theta, _ = ROBOT.inverse_kinematics(X, zeta)
    return np.concatenate([theta, zeta], -1)


def run_plant(plant, seconds, period, demand_fn):
    enabled = np.ones(6, bool)
    limit = np.full(6, 1e6)
    for k in range(int(round(seconds / period))):
        d0, d1 = demand_fn(np.array([k * period, (k + 1) * period]))
        plant.step(period, [d0, (d1 - d0) / period], enabled, limit)
    return plant.truth()


def lagrange_forces(tr, params):
    pose = ROBOT.pose_motion(tr["Theta"], tr["Thetad"], tr["Thetadd"], tr["X"])
    return ROBOT.inverse_dynamics(pose.q, pose.qd, pose.qdd, tr["Theta"][:, 3:], tr["Thetad"][:, 3:], tr["Thetadd"][:, 3:], params)


def test_large_motion_logged_forces_equal_the_lagrange_inverse_dynamics_of_the_logged_motion():
    plant = Plant(ROBOT, TRUE, Theta0=task_space_demand(0.0)[0])
    tr = run_plant(plant, 1.0, 0.002, task_space_demand)
    assert np.ptp(tr["Theta"][:, :3], axis=0).min() > 0.4          # links sweep > 0.4 rad
    assert np.ptp(tr["X"][:, 2]) > 0.45                             # platform turns by ~0.5 rad
    tau = lagrange_forces(tr, TRUE)
    scale = np.abs(tr["force"]).max(axis=0)
    assert np.all(np.abs(tau - tr["force"]).max(axis=0) / scale < 1e-9)
    # the plant's pose is the model's forward kinematics of its joints (same assembly mode throughout)
    assert np.abs(ROBOT.forward_kinematics(tr["Theta"], tr["X"]) - tr["X"]).max() < 1e-12
    # the robot followed the demand after the start transient
    late = tr["t"] > 0.2
    err = np.abs(tr["Theta"] - task_space_demand(tr["t"]))[late].max(axis=0)
    assert np.all(err[:3] < 0.01) and np.all(err[3:] < 1e-4), err


def test_energy_balance_of_the_integrated_motion_closes_at_second_order():
    """Work of actuators and friction = change of the model's kinetic energy (independent route),
    up to the trapezoid rule on the logged samples, whose error falls as period^2."""
    misfit = []
    for period in (0.001, 0.002):
        tr = run_plant(Plant(ROBOT, TRUE, Theta0=task_space_demand(0.0)[0]), 0.5, period, task_space_demand)
        pose = ROBOT.pose_motion(tr["Theta"], tr["Thetad"], tr["Thetadd"], tr["X"])
        energy = ROBOT.kinetic_energy(pose.q, pose.qd, tr["Theta"][:, 3:], tr["Thetad"][:, 3:], TRUE)
        power = np.einsum("nj,nj->n", tr["force"] - friction(tr["Thetad"], TRUE, ROBOT.coulomb_width), tr["Thetad"])
        work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * period)])
        misfit.append(np.abs(energy - energy[0] - work).max())
        assert misfit[-1] < 0.05 * energy.max()
    assert 3.0 < misfit[1] / misfit[0] < 5.0, misfit


def test_integration_step_converges_at_fourth_order():
    """``max_substep`` (``sim.max_substep``, which a slow host may raise): against a reference at
    1/16 ms, the motion's error falls sixteenfold when the step halves (classical Runge-Kutta;
    measured 17.5x from 1 ms to 0.5 ms). Without Coulomb friction: its ``tanh`` (1 mm/s, 1 mrad/s)
    is stiffer near zero speed than these steps resolve, and keeps the error from being asymptotic."""
    smooth = TRUE.replace(f_c=(0.0,) * 6)

    def motion(step):
        plant = Plant(ROBOT, smooth, Theta0=task_space_demand(0.0)[0], max_substep=step)
        return run_plant(plant, 0.5, 0.01, task_space_demand)["Theta"]

    reference = motion(0.01 / 160)
    coarse, fine = (np.abs(motion(step) - reference).max() for step in (0.001, 0.0005))
    assert 12.0 < coarse / fine < 20.0, (coarse, fine)


def test_accelerations_differenced_from_the_sampled_positions_are_the_plant_s_own():
    """What identification relies on: the second difference of the positions sampled at 250 Hz
    (the fourth-order stencil of ``ident_hw.filtering``) is the acceleration the plant logs with the
    forces, ``M^-1 (F - c)`` at the SYNC instant, to 1e-4 of its RMS away from the Coulomb
    switches. The Delta at the SYNC rate of its campaign, under the drives' cyclic demand (a cubic
    B-spline of the targets) and 20 Hz position loops, arms at up to 2.7 rad/s and 21 rad/s².
    Measured 1.0e-5 to 2.2e-5 per arm; with ``M^-1`` and the velocity terms extrapolated linearly
    over the period and Heun's method at 0.5 ms, 1.2e-3."""
    robot = Delta()
    params = nominal_parameters(robot.geometry)
    params[N_BODY_PARAMS:] = [0.08, 0.07, 0.09, 0.2, 0.25, 0.15, 0.01, 0.011, 0.009]   # fv, fc, Jm per arm
    period = 0.004
    t = np.arange(int(6.0 / period)) * period
    fade = np.minimum(t / 1.0, 1.0)[:, None]
    w = 2 * np.pi * np.array([[0.5, 1.3], [0.7, 1.1], [0.6, 1.7]])            # rad/s, two sines per arm
    targets = fade * (0.3 * np.sin(w[:, 0] * t[:, None]) + 0.15 * np.sin(w[:, 1] * t[:, None] + 1.0))
    plant = Plant(robot, params, targets[0])
    follow_targets(plant, targets, period, force_limit=1e3)
    tr = plant.truth()
    _, differenced = central_derivatives(tr["Theta"], tr["t"])
    moving = (np.abs(tr["Thetad"]) > 0.2).all(axis=1) & (tr["t"] > 1.5)
    moving[-3:] = False
    assert moving.sum() > 500 and np.abs(tr["Thetadd"][moving]).max() > 10.0
    rms = np.sqrt(np.mean(tr["Thetadd"][moving] ** 2, axis=0))
    error = np.sqrt(np.mean((differenced - tr["Thetadd"])[moving] ** 2, axis=0))
    assert np.all(error < 1e-4 * rms), error / rms


def test_commanding_the_robot_through_its_parallel_singularity_never_passes_it():
    """All three links turned together turn the platform towards a type II singularity (~0.175 rad
    on the nominal rig), beyond which no pose closes the chains. The plant never gets past it:
    either the mass matrix, growing without bound, stalls the links short of the demand (a
    following error for the drives), or a period steps over it and the plant jams at rest at the
    last pose that closed the chains (:class:`PlantJammed`; ``test_sim_faults`` has that case
    through the drives)."""
    plant = Plant(ROBOT, TRUE)
    home = plant.Theta.copy()
    push = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0]) * 0.3
    demand = lambda t: home + push * np.minimum(t / 0.5, 1.0)[:, None]       # noqa: E731
    try:
        run_plant(plant, 2.0, 0.004, demand)
        jammed = False
    except PlantJammed as exc:
        assert "jammed" in str(exc) and np.all(plant.Thetad == 0)
        jammed = True
    tr = plant.truth()
    assert ROBOT.closure_residual(tr["X"], tr["Theta"]).max() < 1e-9            # every logged pose closes
    assert np.all(tr["Theta"][:, :3] - home[:3] < 0.176)                         # never past the singularity
    cond = [ROBOT.singularity_margins(X[None], Th[None, 3:]).cond_A[0]
            for X, Th in ((np.zeros(3), home), (plant.X, plant.Theta))]
    assert cond[1] > 2 * cond[0] and np.all(plant.Theta[:3] - home[:3] > 0.1)   # it went towards it
    if not jammed:
        assert np.all(home[:3] + 0.3 - plant.Theta[:3] > 0.1)                    # stalled short of the demand


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


def test_payload_changes_the_forces_as_the_model_predicts():
    plant = Plant(ROBOT, TRUE, Theta0=task_space_demand(0.0)[0])
    plant.set_payload(0.5, 0.002)
    tr = run_plant(plant, 0.3, 0.002, task_space_demand)
    heavy = TRUE.replace(m_ee=TRUE.m_ee + 0.5, I_ee=TRUE.I_ee + 0.002)
    err_heavy = np.abs(lagrange_forces(tr, heavy) - tr["force"]).max()
    err_nominal = np.abs(lagrange_forces(tr, TRUE) - tr["force"]).max()
    assert err_heavy < 1e-9 * np.abs(tr["force"]).max()
    assert err_nominal > 1e3 * err_heavy


def test_truth_log_keeps_the_last_rows_in_numpy_chunks():
    """The log of a long run is bounded and holds no Python object per period (garbage collector)."""
    log = TruthLog(5000, n=6, pose_size=3)
    for k in range(9000):
        log.append(float(k), np.full(3, k), np.full(6, k), np.full(6, -k), np.full(6, 2 * k), np.full(6, 3 * k))
    kept = np.arange(4000, 9000, dtype=float)
    arrays = log.arrays()
    assert len(log) == 5000 and len(log._chunks) <= 5000 // TruthLog.CHUNK + 2
    np.testing.assert_array_equal(arrays["t"], kept)
    for name, sign in (("X", 1), ("Theta", 1), ("Thetad", -1), ("Thetadd", 2), ("force", 3)):
        np.testing.assert_array_equal(arrays[name], sign * np.repeat(kept[:, None], arrays[name].shape[1], 1))
    assert not any(gc.is_tracked(chunk) for chunk in log._chunks)
    assert TruthLog(3, n=6, pose_size=3).arrays()["force"].shape == (0, 6)
