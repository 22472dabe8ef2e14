"""The quality verdict's noise floor (issue 30): a ``standstill`` trajectory of any robot, the
current's noise at rest through a fitted trajectory's filter, and the encoders' part from the
draws' predicted forces."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import signal as sps

from drivers.recording import Recording
from drivers.recording_metadata import RecordingMetadata
from ident_hw.config import TrajectoryConfig, load_config
from ident_hw.config.to_drivers import axis_scaling
from ident_hw.experiment.evidence import noise_floors
from ident_hw.experiment.inputs import identification_plan
from ident_hw.experiment.preparation import trajectory_filter
from ident_hw.experiment.plan import PlanInputs, check, plan
from ident_hw.config.robots import model_of

from ident_scenarios import CONFIGS

STILL = TrajectoryConfig(name="still", kind="standstill", duration=1.5)


@pytest.mark.parametrize("name", ["sim-3prrr.yaml", "sim-delta.yaml", "sim-2r.yaml"])
def test_a_standstill_holds_any_robot_at_its_home_pose(name):
    config = load_config(CONFIGS / name)
    config = dataclasses.replace(config, trajectories=tuple(config.trajectories) + (STILL,))
    robot = model_of(config.robot)
    (planned,) = plan(config, ["still"])
    traj = planned.trajectory
    assert len(traj.t) == round(1.5 * config.bus.sync_rate) + 1
    np.testing.assert_array_equal(traj.Theta, np.tile(robot.home_actuated(), (len(traj.t), 1)))
    assert not traj.Thetad.any() and not traj.Thetadd.any()
    assert check(PlanInputs.of(config), traj).ok


def test_the_floor_is_the_filtered_noise_at_rest_and_the_draws_spread_in_squares():
    """White current noise of known sigma at rest: its floor in the excitation's band is sigma
    times the root of the band's share of the zero-phase filter's power, ``int |H|^4`` (H by
    SciPy's Butterworth design, not by the code under test); two draws whose predicted forces
    differ by ``2 e`` add ``sqrt(2) e`` in squares, in the drive's current."""
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    rate = config.bus.sync_rate
    n, axes = int(120 * rate), len(config.robot.actuators)
    sigma = np.linspace(0.001, 0.004, axes)
    rng = np.random.default_rng(7)
    current = 0.3 + sigma * rng.normal(size=(n, axes))           # a constant holding current + noise
    t = np.arange(n) / rate
    rec = Recording(t=t, cycle=np.arange(n), position=np.zeros((n, axes)), velocity=np.zeros((n, axes)),
                    current=current, statusword=np.zeros((n, axes), np.int32), target=np.zeros((n, axes)),
                    valid=np.ones((n, axes), bool), metadata=RecordingMetadata(sync_period=1 / rate))
    still = TrajectoryConfig(name="still", kind="standstill")
    config = dataclasses.replace(config, trajectories=tuple(config.trajectories) + (still,))
    plan = identification_plan(config)
    settings = trajectory_filter(plan, "excitation", rate)
    sos = sps.butter(settings.order, settings.decimation_cutoff_hz, fs=rate, output="sos")
    f, h = sps.sosfreqz(sos, worN=200_000, fs=rate)
    share = np.trapezoid(np.abs(h) ** 4, f) / (rate / 2)
    e = np.array([1e-3, -5e-4, 2e-4, 0.3, 0.1, -0.05])    # N m, N: 0.3-2.2 mA through the drives, as the noise
    coef = np.ones(2)
    draws = [{"excitation": SimpleNamespace(Y=np.full((50, axes, 2), s / 2.0) * e[None, :, None])} for s in (1, -1)]
    per_amp = np.array([axis_scaling(a).force_per_amp for a in config.robot.actuators])
    (floor,) = noise_floors(plan, {"still": rec}, ["excitation"], draws, coef).values()
    expected = np.sqrt(sigma ** 2 * share + 2 * e ** 2 / per_amp ** 2)
    np.testing.assert_allclose(floor, expected, rtol=0.05)
    # on the rows the fits use only: draws that differ by 20 e on the rows at rest (the first half
    # of each axis's, where a Coulomb term flips with a count) and by 2 e elsewhere give the same floor
    half = np.arange(50)[:, None] < 25
    scale = np.where(half, 10.0, 1.0)[:, :, None]
    draws = [{"excitation": SimpleNamespace(Y=s / 2.0 * scale * e[None, :, None] * np.ones((50, axes, 2)))}
             for s in (1, -1)]
    moving = {"excitation": np.broadcast_to(~half, (50, axes))}
    (floor,) = noise_floors(plan, {"still": rec}, ["excitation"], draws, coef, moving).values()
    np.testing.assert_allclose(floor, expected, rtol=0.05)
    # nothing to hold the residuals against without a standstill, or without draws
    assert noise_floors(plan, {}, ["excitation"], draws, coef) == {}
    assert noise_floors(plan, {"still": rec}, ["excitation"], [], coef) == {}
