"""The Delta behind the simulated rig: the plant moves any robot model (ident_hw.model.interface),
and three emulated EPOS4 drives stream it to the real canopen master in lockstep.

The checks are independent of the plant's integration: the logged forces against the Delta's
regressor (virtual work), the base parameters of the truth recovered from the logged motion by
least squares, the recorded currents against the forces through ``K_m`` and the gear ratio."""

import itertools

import numpy as np
import pytest

from drivers.axis import AxisConfig, HomingConfig
from drivers.bus import BusConfig, open_network
from drivers.epos import DriveGroup
from drivers.sim.lockstep import LockstepSync
from drivers.sim import Plant, SimulatedRig
from drivers.units import AxisScaling
from ident_hw.model import Delta
from ident_hw.model.delta import N_BODY_PARAMS, closed_form_base, nominal_parameters
from ident_hw.model.interface import RobotModel
from trajectories.delta_paper import training_path

ROBOT = Delta()
#: the simulated truth: the nominal bodies, and drive terms per arm (fv N·m·s/rad, fc N·m, Jm kg·m²)
TRUTH = nominal_parameters().copy()
TRUTH[N_BODY_PARAMS:] = [0.08, 0.07, 0.09, 0.20, 0.25, 0.15, 0.010, 0.011, 0.009]
SCALING = AxisScaling("revolute", 2048, 0.0369, gear_ratio=26.0)
PERIOD = 0.004
_channels = itertools.count()


def _faded_training_path(t, fade=1.0):
    """Table 2's path, faded in over ``fade`` s so that the arms leave their rest: (N, 3) rad."""
    q = training_path(t).q
    window = np.clip(t / fade, 0.0, 1.0)
    return q * (window**3 * (10 - 15 * window + 6 * window**2))[:, None]


def _demand(t, period):
    """The cubic of each period (4, 3) through the faded path: position, velocity, acceleration / 2, jerk / 6."""
    h = 1e-4
    samples = _faded_training_path(np.array([t - 2 * h, t - h, t, t + h, t + 2 * h]))
    d1 = (samples[3] - samples[1]) / (2 * h)
    d2 = (samples[3] - 2 * samples[2] + samples[1]) / h**2
    d3 = (samples[4] - 2 * samples[3] + 2 * samples[1] - samples[0]) / (2 * h**3)
    return np.stack([samples[2], d1, d2 / 2, d3 / 6])


def test_the_delta_is_a_robot_model():
    assert isinstance(ROBOT, RobotModel)
    assert ROBOT.actuator_names == ("q1", "q2", "q3") and len(ROBOT.parameter_names) == TRUTH.size


def test_the_plant_moves_the_delta_and_its_log_is_the_regressors_inverse_dynamics():
    """Four seconds of the faded training path under the position loops: the logged forces are
    ``Y(q, qd, qdd) pi`` of the logged motion (virtual work, friction and rotor inertia included),
    the plant followed the demand, and least squares on the logged rows gives the truth's base
    parameters."""
    plant = Plant(ROBOT, TRUTH)
    enabled, limit = np.ones(3, bool), np.full(3, 50.0)
    steps = round(4.0 / PERIOD)
    for k in range(steps):
        plant.step(PERIOD, _demand(k * PERIOD, PERIOD), enabled, limit)
    log = plant.truth()
    tau = ROBOT.inverse_dynamics(log["Theta"], log["Thetad"], log["Thetadd"], TRUTH)
    np.testing.assert_allclose(log["force"], tau, rtol=1e-9, atol=1e-9 * np.abs(tau).max())
    np.testing.assert_allclose(log["X"], ROBOT.fk(log["Theta"]), atol=1e-12)
    # the loops followed (20 Hz bandwidth: a lag of a few mrad on a path of ~0.3 rad)
    path = _faded_training_path(log["t"])
    assert np.abs(log["Theta"] - path).max() < 0.02 and np.ptp(log["Theta"], axis=0).min() > 0.1
    # least squares on the base columns recovers H pi of the truth
    base = closed_form_base(drive_terms=True)
    kept = [ROBOT.parameter_names.index(name) for name in base.kept]
    Y = ROBOT.regressor(log["Theta"], log["Thetad"], log["Thetadd"])[:, :, kept].reshape(-1, len(kept))
    estimate, *_ = np.linalg.lstsq(Y, log["force"].reshape(-1), rcond=None)
    np.testing.assert_allclose(estimate, base.H @ TRUTH, rtol=1e-6, atol=1e-9)


def test_a_payload_on_the_platform_raises_the_torques_by_its_weight():
    """Standing still, a 0.5 kg payload at the platform adds ``J^T [0, 0, m g]`` to the arm torques
    (statics through the Delta's Jacobian ``pd = J qd``: an independent route from the regressor)."""
    q = np.array([0.2, -0.1, 0.3])
    zero = np.zeros(3)
    loaded = ROBOT.with_payload(TRUTH, 0.5)
    bias = ROBOT.plant_dynamics(q, zero, TRUTH).bias
    bias_loaded = ROBOT.plant_dynamics(q, zero, loaded).bias
    J = ROBOT.jacobian(q)
    np.testing.assert_allclose(bias_loaded - bias, J.T @ np.array([0.0, 0.0, 0.5 * 9.81]), rtol=1e-9)


@pytest.fixture
def delta_rig():
    channel = f"delta-rig-{next(_channels)}"
    axes = [AxisConfig(name, node_id, "epos4", SCALING, position_min=-1.2, position_max=1.2, max_velocity=5.0,
                       max_current=10.0, following_error_window=0.05, homing=HomingConfig(37))
            for node_id, name in enumerate(ROBOT.actuator_names, start=1)]
    rig = SimulatedRig.build(ROBOT, TRUTH, [(a.node_id, a.profile, a.scaling) for a in axes], seed=3,
                             lockstep=True, sync_period=PERIOD, interface="virtual", channel=channel,
                             ignore_config=True).start()
    network = open_network(BusConfig("virtual", channel, ignore_config=True))
    group = DriveGroup(network, axes, sdo_timeout=0.5, sync=LockstepSync(PERIOD))
    try:
        group.bring_up()
        group.home()
        yield rig, group
    finally:
        group.close()
        network.disconnect()
        rig.stop()


def test_three_epos4_drives_stream_the_delta_over_canopen(delta_rig):
    """The master streams three seconds of the path to the Delta rig: every cycle complete, each
    recorded current is the plant's force at that SYNC through ``K_m`` and the gear ratio (to the
    drive's 1 mA), each position the plant's to one count."""
    rig, group = delta_rig
    t = np.arange(round(3.0 / PERIOD)) * PERIOD
    start_step = len(rig.plant.truth()["t"])
    recording = group.run_cyclic(_faded_training_path(t), PERIOD)
    assert recording.n_invalid == 0 and recording.metadata.sync == "lockstep"
    truth = rig.plant.truth()
    rows = slice(start_step, start_step + len(t))
    torque = ROBOT.inverse_dynamics(truth["Theta"][rows], truth["Thetad"][rows], truth["Thetadd"][rows], TRUTH)
    torque_per_amp = SCALING.torque_constant * SCALING.gear_ratio
    assert np.abs(recording.current * 1e3 - torque / torque_per_amp * 1e3).max() <= 0.5 + 1e-6
    np.testing.assert_allclose(recording.position, truth["Theta"][rows], atol=1.0 / SCALING.counts_per_unit)
    assert np.abs(torque).max() > 0.5                  # the arms carried load
