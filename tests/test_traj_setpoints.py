"""What ``ident-hw check`` accepts, ``ident-hw run`` streams without a limit stop (issue 31).

The set-points the check validates are the array the runner hands to ``run_cyclic``
(:func:`ident_hw.experiment.plan.setpoints`, one row per SYNC period), and the check applies
``run_cyclic``'s own test of them (:func:`drivers.axis.outside_position_limits`, the drives'
software position limits). Every shipped config with trajectories is held to it, the HIL ones
included: their triangle once passed the check (the 3PRRR check compared the carriages with
``robot.stroke``, 0.10 m, and the carriage schedule was optimised within it) and stopped
``run_cyclic`` at the end of the campaign: ``axis 'zeta1' sample 6615 = 0.0900106 outside its
limits [-0.09, 0.09]``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import trajectories
from drivers.errors import ConfigError
from drivers.stream import setpoint_counts
from trajectories.paths import home_actuators
from ident_hw.config import load_config
from ident_hw.experiment.plan import PlanInputs, build, check, plan, setpoints, sync_period
from ident_hw.config.robots import model_of
from ident_hw.experiment.robot_trajectories import feasibility_limits
from recorded_data import needs_datasets

CONFIGS = Path(__file__).resolve().parent.parent / "configs"
#: every shipped config with trajectories (the robot-*.yaml bases have none); the Stewart's
#: campaign takes half a minute to plan and check (its closure solved at every sample)
CAMPAIGNS = ["hil-3prrr-epos2.yaml", "hil-3prrr-epos4.yaml", "sim-2r.yaml", "sim-3prrr.yaml", "sim-delta.yaml",
             pytest.param("sim-stewart.yaml", marks=pytest.mark.slow), "udp-3prrr.yaml", "vcan-3prrr.yaml"]


def test_the_list_is_every_shipped_config_with_trajectories():
    # a config naming the datasets' folder identifies recordings made elsewhere: nothing to stream
    streamed = [p for p in CONFIGS.glob("*.yaml") if not needs_datasets(p.read_text())]
    shipped = {p.name for p in streamed if any(not t.recorded for t in load_config(p).trajectories)}
    listed = {c if isinstance(c, str) else c.values[0] for c in CAMPAIGNS}
    assert listed == shipped


@pytest.fixture(scope="module", params=CAMPAIGNS)
def campaign(request):
    """A config and its campaign as ``ident-hw check`` and ``ident-hw run`` plan it."""
    config = load_config(CONFIGS / request.param)
    return config, plan(config, online=True)


@pytest.mark.slow
def test_check_accepts_every_trajectory_and_run_cyclic_streams_it_without_a_limit_stop(campaign):
    config, planned = campaign
    axes = PlanInputs.of(config).axes
    for p in planned:
        assert p.ok, p.describe()
        targets = setpoints(p.trajectory)
        # one sample per SYNC period: the grid the set-points are checked on is the one streamed
        np.testing.assert_allclose(np.diff(p.trajectory.t), sync_period(config.bus), rtol=0, atol=1e-9)
        # run_cyclic's check and conversion of the set-points (a ConfigError is the run's limit stop)
        counts = setpoint_counts(axes, targets)
        # whole counts within the drives' own software position limits (0x607D, written in counts)
        for j, a in enumerate(axes):
            low, high = a.scaling.counts_from_position(a.position_min), a.scaling.counts_from_position(a.position_max)
            assert low <= counts[:, j].min() and counts[:, j].max() <= high, (p.config.name, a.name)


@pytest.mark.slow
def test_run_streams_byte_for_byte_the_set_points_check_validated(campaign):
    """``ident-hw run`` plans in its own process: the same set-points, bit for bit, as the check's."""
    config, planned = campaign
    again = plan(config, online=True)
    assert [p.config.name for p in again] == [p.config.name for p in planned]
    for checked, streamed in zip(planned, again):
        a, b = setpoints(checked.trajectory), setpoints(streamed.trajectory)
        assert a.dtype == b.dtype == np.float64 and a.shape == b.shape
        assert a.tobytes() == b.tobytes(), checked.config.name


def test_check_and_run_cyclic_draw_each_limit_at_the_same_place():
    """A set-point on a drive's limit passes both; one ulp beyond fails both, naming the sample."""
    config = load_config(CONFIGS / "vcan-3prrr.yaml")
    sweep = build(PlanInputs.of(config), config.trajectories[0])
    axes = PlanInputs.of(config).axes
    k = 100
    for j, bound, beyond in ((3, axes[3].position_max, np.inf), (0, axes[0].position_min, -np.inf)):
        for value, outside in ((bound, False), (np.nextafter(bound, beyond), True)):
            Theta = sweep.Theta.copy()
            Theta[k, j] = value
            traj = dataclasses.replace(sweep, Theta=Theta)
            found = [v for v in check(PlanInputs.of(config), traj).violations if v.quantity == "set-point"]
            if not outside:
                assert found == []
                setpoint_counts(axes, setpoints(traj))
                continue
            assert [(v.sample, v.name, v.value, v.limit) for v in found] == [(k, axes[j].name, value, bound)]
            with pytest.raises(ConfigError, match=f"axis '{axes[j].name}' sample {k} "):
                setpoint_counts(axes, setpoints(traj))


def test_check_refuses_a_carriage_move_beyond_the_drives_limits_within_the_stroke(tmp_path):
    """The HIL rig: carriage drives limited to +-0.09 m on a 0.10 m stroke. A trajectory file
    taking carriage 1 to 0.095 m passes the stroke, not the drive: the check says so, at the
    sample and value ``run_cyclic`` would stop on."""
    config = load_config(CONFIGS / "hil-3prrr-epos4.yaml")
    robot = model_of(config.robot)
    home = home_actuators(robot)
    wide = home.copy()
    wide[3] = 0.095
    trajectories.save(trajectories.actuator_trajectory(robot, "wide", np.array([home, wide, home]),
                                                       feasibility_limits(config.robot), rate=100.0),
                      tmp_path / "wide.npz")
    (tmp_path / "wide.yaml").write_text(
        f"extends: {CONFIGS / 'hil-3prrr-epos4.yaml'}\n"
        "trajectories:\n  - {name: wide, kind: file, path: wide.npz}\n"
        "identification:\n  steps: [{name: carriages, trajectories: [wide], parameters: [m_c]}]\n"
        "  validation: []\n")
    config = load_config(tmp_path / "wide.yaml")
    (planned,) = plan(config)
    assert not planned.ok and planned.report.first.quantity == "set-point"
    k = planned.report.first.sample
    assert planned.describe().startswith(f"wide: INFEASIBLE: t = {planned.trajectory.t[k]:.4f} s: set-point zeta1 = ")
    assert planned.describe().endswith(" m exceeds limit 0.09 m")
    with pytest.raises(ConfigError, match=f"axis 'zeta1' sample {k} = .* outside its limits"):
        setpoint_counts(PlanInputs.of(config).axes, setpoints(planned.trajectory))
