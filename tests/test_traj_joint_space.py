"""The excitation of a robot known from its description file, and its feasibility check."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ident_hw.model.described import DescribedRobot
from trajectories.feasibility import ActuatorLimits
from trajectories.joint_space import check_described_trajectory, joint_excitation

ROBOTS = Path(__file__).resolve().parent.parent / "configs" / "robots"
LEGS = tuple(f"leg{i}" for i in range(1, 7))


def stewart() -> DescribedRobot:
    return DescribedRobot(ROBOTS / "stewart.xml", LEGS)


def leg_limits(stroke=0.10, speed=0.2, accel=2.0) -> ActuatorLimits:
    return ActuatorLimits(LEGS, np.full(6, -stroke), np.full(6, stroke), np.full(6, speed), np.full(6, accel),
                          ("m",) * 6)


def test_the_excitation_leaves_home_at_rest_and_keeps_within_its_share_of_the_limits():
    robot, limits = stewart(), leg_limits()
    traj = joint_excitation(robot, limits, duration=8.0, rate=100.0, bandwidth=1.0, fraction=0.8, seed=3)
    for x, value in ((traj.Theta, 0.0), (traj.Thetad, 0.0), (traj.Thetadd, 0.0)):
        np.testing.assert_allclose(x[[0, -1]], value, atol=1e-12)
    peak = [np.max(np.abs(x), axis=0) for x in (traj.Theta, traj.Thetad, traj.Thetadd)]
    share = np.max([peak[0] / 0.10, peak[1] / 0.2, peak[2] / 2.0], axis=0)
    np.testing.assert_allclose(share, 0.8, rtol=1e-12)     # each leg: its tightest limit at 80 %
    # the rates are those of the positions: central differences within their error bound h² |jerk| / 6
    h = traj.t[1] - traj.t[0]
    bound = 1.05 * h**2 / 6 * np.max(np.abs(np.gradient(traj.Thetadd, h, axis=0)))
    assert np.max(np.abs(np.gradient(traj.Theta, h, axis=0)[2:-2] - traj.Thetad[2:-2])) < bound
    # the poses are closed tree configurations at the actuated coordinates
    assert np.max(np.abs(traj.X[:, robot.actuated_q] - traj.Theta)) < 1e-12
    assert check_described_trajectory(traj, robot, limits, max_condition=40.0).ok
    # the same seed, the same trajectory; another seed, another one
    again = joint_excitation(robot, limits, duration=8.0, rate=100.0, bandwidth=1.0, fraction=0.8, seed=3)
    np.testing.assert_array_equal(again.Theta, traj.Theta)
    other = joint_excitation(robot, limits, duration=8.0, rate=100.0, bandwidth=1.0, fraction=0.8, seed=4)
    assert np.max(np.abs(other.Theta - traj.Theta)) > 0.01


def test_the_check_names_a_limit_and_a_pose_that_does_not_close():
    robot = stewart()
    traj = joint_excitation(robot, leg_limits(), duration=6.0, rate=100.0, bandwidth=1.0, seed=1)
    assert check_described_trajectory(traj, robot, leg_limits(), max_condition=40.0).ok
    peak = np.abs(traj.Theta).max()
    tight = check_described_trajectory(traj, robot, leg_limits(stroke=0.9 * peak), max_condition=40.0)
    assert tight.first.quantity == "position"
    assert tight.first.sample == int(np.argmax(np.any(np.abs(traj.Theta) > 0.9 * peak, axis=1)))
    # beyond its share (amplitude 1.3 x 0.8 of the tightest limit of each leg)
    over = joint_excitation(robot, leg_limits(), duration=6.0, rate=100.0, bandwidth=1.0, seed=1, amplitude=1.3)
    assert not check_described_trajectory(over, robot, leg_limits(), max_condition=40.0).ok
    # legs stretched and shortened in turn beyond what the platform can follow: no assembly
    traj.Theta[300:] = np.array([0.1, -0.1] * 3)
    report = check_described_trajectory(traj, robot, leg_limits(stroke=0.2, speed=1e3, accel=1e6), 40.0)
    assert report.first.quantity == "reach" and report.first.sample == 300


def test_the_check_refuses_motion_near_a_parallel_singularity():
    robot = stewart()
    traj = joint_excitation(robot, leg_limits(), duration=6.0, rate=100.0, bandwidth=1.0, seed=1)
    cond = robot.conditions(traj.X)
    limit = float(np.median(cond))
    report = check_described_trajectory(traj, robot, leg_limits(), max_condition=limit)
    assert report.first.quantity == "closure condition"
    assert report.first.sample == int(np.argmax(cond > limit))


def test_an_excitation_beyond_the_rate_or_shorter_than_its_fades_is_refused():
    robot = stewart()
    with pytest.raises(ValueError, match="quarter of the rate"):
        joint_excitation(robot, leg_limits(), duration=6.0, rate=100.0, bandwidth=30.0)
    with pytest.raises(ValueError, match="fade"):
        joint_excitation(robot, leg_limits(), duration=1.5, rate=100.0, bandwidth=1.0, fade=1.0)
