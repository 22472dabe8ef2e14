"""Trajectories on the nominal rig (configs/robot-3prrr.yaml): the paper set, continuity,
feasibility check, files."""

from pathlib import Path

import numpy as np
import pytest

from ident_hw.config import load_config
from ident_hw.config.robots import model_of
from trajectories import (InfeasibleTrajectory, Trajectory, TrajectoryFileError, carriage_sweep, check_trajectory,
                          five_squares, load, pose_trajectory, save, validation_triangle)
from trajectories.paths import home_actuators
from trajectories.motion import SampledMotion
from trajectories.timing import rest_to_rest_path
from ident_hw.experiment.robot_trajectories import feasibility_limits

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "robot-3prrr.yaml"


@pytest.fixture(scope="module")
def rig():
    cfg = load_config(CONFIG).robot
    return model_of(cfg), feasibility_limits(cfg)


@pytest.fixture(scope="module")
def paper_set(rig):
    robot, limits = rig
    return {"sweep": carriage_sweep(robot, limits), "squares": five_squares(robot, limits),
            "triangle": validation_triangle(robot, limits)}


def rest_indices(traj):
    """Samples where every actuator is at rest (speed and acceleration 0)."""
    still = np.all(np.abs(traj.Thetad) < 1e-12, axis=1) & np.all(np.abs(traj.Thetadd) < 1e-9, axis=1)
    return np.flatnonzero(still)


def rest_points(traj, columns):
    """Distinct values of ``columns`` (N, k) at the rest samples, in order of visit."""
    values = columns[rest_indices(traj)]
    keep = np.r_[True, np.any(np.abs(np.diff(values, axis=0)) > 1e-9, axis=1)]
    return values[keep]


# -- the paper set ------------------------------------------------------------------------------
def test_paper_set_is_feasible_on_the_nominal_rig(rig, paper_set):
    robot, limits = rig
    for traj in [paper_set["sweep"], *paper_set["squares"], paper_set["triangle"]]:
        report = check_trajectory(traj, robot, limits)
        assert report.ok, str(report)
        report.raise_if_failed()


def test_carriage_sweep_amplitudes_and_held_rotary_actuators(rig, paper_set):
    robot, _ = rig
    sweep = paper_set["sweep"]
    home = home_actuators(robot)
    assert np.all(sweep.Theta[:, :3] == home[:3]) and np.all(sweep.Thetad[:, :3] == 0)
    visited = rest_points(sweep, sweep.zeta)
    expected = [[0, 0, 0]]
    for chains in ([0], [1], [2], [0, 1, 2]):
        for value in (-0.06, 0.06, 0.0):
            point = np.zeros(3)
            point[chains] = value
            expected.append(point)
    np.testing.assert_allclose(visited, expected, atol=1e-15)
    # the pose (by the model's FK) closes the chains at every sample
    assert robot.closure_residual(sweep.X, sweep.Theta).max() < 1e-12
    # spec: all three carriages together rotate the platform by up to about 40 deg, cond(A) <= 21
    assert 35 < np.degrees(np.abs(sweep.X[:, 2]).max()) < 45
    assert robot.singularity_margins(sweep.X, sweep.zeta).cond_A.max() < 21


def test_five_squares_geometry(paper_set):
    for i, sq in enumerate(paper_set["squares"]):
        assert np.all(sq.zeta == 0) and np.all(sq.X[:, 2] == 0)
        corners = rest_points(sq, sq.X[:, :2])[1:-1]  # home, 4 corners, first corner again, home
        assert len(corners) == 5
        np.testing.assert_allclose(corners[0], corners[4], atol=1e-15)
        sides = corners[1:] - corners[:-1]
        np.testing.assert_allclose(np.linalg.norm(sides, axis=1), 0.12, rtol=1e-12)
        np.testing.assert_allclose(corners[:4].mean(axis=0), 0, atol=1e-15)  # centred at the origin
        # rotation of the first side by hand: unrotated it points along -x
        angle = np.degrees(np.arctan2(sides[0, 1], sides[0, 0])) - 180.0
        assert np.isclose((angle + 180) % 360 - 180, 10 * i, atol=1e-9)


def test_validation_triangle_geometry_and_all_six_actuators_move(paper_set):
    tri = paper_set["triangle"]
    poses = rest_points(tri, tri.X)
    np.testing.assert_allclose(poses[1:4, :2], [[0, 0.12], [-0.1039, -0.06], [0.1039, -0.06]], atol=5e-5)
    np.testing.assert_allclose(poses[1:5, 2], np.radians(-20), atol=1e-15)
    np.testing.assert_allclose(poses[[0, -1]], 0, atol=1e-15)
    # all six actuators move while the platform goes round the triangle
    at_v1 = np.flatnonzero(np.all(np.isclose(tri.X, poses[1], atol=1e-15), axis=1))
    start, end = at_v1[0], at_v1[-1]
    assert np.all(np.ptp(tri.Theta[start:end + 1], axis=0) > 1e-2)


def test_carriage_schedule_improves_the_singularity_margins(rig, paper_set):
    robot, limits = rig
    optimised = paper_set["triangle"]
    blocked = validation_triangle(robot, limits, carriages=np.zeros((6, 3)))

    def margin(traj):
        m = robot.singularity_margins(traj.X, traj.zeta)
        return min(m.serial.min() / limits.min_serial_margin, (limits.max_cond_A / m.cond_A).min())

    assert margin(optimised) > 1.2 * margin(blocked)
    assert np.abs(optimised.zeta).max() <= limits.carriage_stroke


# -- continuity and derivatives -----------------------------------------------------------------
@pytest.mark.parametrize("which", ["sweep", "square", "triangle"])
def test_actuator_motion_is_continuous_and_derivatives_match_finite_differences(rig, paper_set, which):
    robot, _ = rig
    traj = {"sweep": paper_set["sweep"], "square": paper_set["squares"][2], "triangle": paper_set["triangle"]}[which]
    # regenerate on a fine grid from the generator itself (not interpolated)
    if which == "sweep":
        traj = carriage_sweep(robot, rig[1], rate=2000.0)
    elif which == "square":
        traj = five_squares(robot, rig[1], rate=2000.0)[2]
    else:
        traj = validation_triangle(robot, rig[1], rate=2000.0)
    dt = 1 / 2000.0
    for pos, vel, acc in ((traj.Theta, traj.Thetad, traj.Thetadd), (traj.X, traj.Xd, traj.Xdd)):
        fd_v = (pos[2:] - pos[:-2]) / (2 * dt)
        fd_a = (vel[2:] - vel[:-2]) / (2 * dt)
        # Taylor bounds of central differences for a C2 signal with bounded (piecewise continuous)
        # jerk J: |fd_v - v| <= dt^2 J / 6, |fd_a - a| <= dt J / 2; J estimated from the data.
        jerk = np.abs(np.diff(acc, axis=0)).max(axis=0) / dt
        assert np.all(np.abs(fd_v - vel[1:-1]) <= dt**2 * jerk / 6 * 1.05 + 1e-12)
        assert np.all(np.abs(fd_a - acc[1:-1]) <= dt * jerk / 2 * 1.05 + 1e-9)
        assert np.all(np.abs(fd_a - acc[1:-1]) <= 0.01 * np.abs(acc).max(axis=0) + 1e-9)
        # no jumps: each step is bounded by the next derivative's peak times dt
        assert np.all(np.abs(np.diff(pos, axis=0)).max(axis=0) <= np.abs(vel).max(axis=0) * dt * 1.01 + 1e-15)
        assert np.all(np.abs(np.diff(vel, axis=0)).max(axis=0) <= np.abs(acc).max(axis=0) * dt * 1.01 + 1e-15)


def test_resample_reproduces_the_generating_path(rig, paper_set):
    robot, limits = rig
    sweep = paper_set["sweep"]  # actuator space: Theta is the timed path itself
    path = rest_to_rest_path(np.array(sweep.metadata["waypoints"]), lambda q, qd, qdd: SampledMotion(q, qd, qdd), limits.max_speed,
                             limits.max_accel, time_step=1 / 250)
    for rate in (250.0, 500.0, 1000.0):
        r = sweep.resample(rate)
        assert np.allclose(np.diff(r.t), 1 / rate)
        assert r.t[-1] <= sweep.t[-1] and sweep.t[-1] - r.t[-1] < 1 / rate
        exact = path.evaluate(r.t)
        for got, want in zip((r.Theta, r.Thetad, r.Thetadd), (exact.q, exact.qd, exact.qdd)):
            np.testing.assert_allclose(got, want, atol=1e-9 * np.abs(want).max())


# -- rejection of bad trajectories ---------------------------------------------------------------
def test_out_of_reach_is_rejected_naming_time_and_chain(rig, paper_set):
    robot, limits = rig
    sq = paper_set["squares"][0]
    k = 123
    X = sq.X.copy()
    X[k:] = [0.0, -0.36, 0.0]  # beyond the reach of chain 1 (its guide is at y = +a)
    bad = Trajectory("reach", sq.t, X, sq.Xd, sq.Xdd, sq.Theta, sq.Thetad, sq.Thetadd)
    # independent check of the chain: distance from A_1 to C_1 against l1 + l2
    g = robot.geometry
    C1 = X[k, :2] + g.h * np.array([-np.sin(g.gamma[0]), np.cos(g.gamma[0])])
    A1 = g.a * np.array([-np.sin(g.gamma[0]), np.cos(g.gamma[0])])
    assert np.linalg.norm(C1 - A1) > g.l1 + g.l2
    report = check_trajectory(bad, robot, limits)
    first = report.first
    assert (first.quantity, first.sample, first.time, first.chain) == ("reach", k, sq.t[k], 1)
    with pytest.raises(InfeasibleTrajectory, match=rf"t = {sq.t[k]:.4f} s, chain 1: pose out of reach"):
        report.raise_if_failed()


def test_path_through_a_serial_singularity_is_rejected(rig):
    robot, limits = rig
    loose = type(limits)(**{**vars(limits), "min_serial_margin": 1e-3})
    traj = pose_trajectory(robot, "to-singularity", [[0, 0, 0], [0, 0.27, 0]], loose)
    # by hand: |sin(beta_1 - theta_1)| from the inverse kinematics of each sample
    theta, beta = robot.inverse_kinematics(traj.X, traj.zeta)
    margin = np.abs(np.sin(beta - theta))
    sample, chain = np.argwhere(margin < limits.min_serial_margin)[0]
    report = check_trajectory(traj, robot, limits)
    first = report.first
    assert (first.quantity, first.sample, first.chain) == ("serial margin", sample, chain + 1)
    assert first.value == pytest.approx(margin[sample, chain]) and first.limit == limits.min_serial_margin
    assert f"t = {traj.t[sample]:.4f} s, chain {chain + 1}: serial margin" in str(first)


def test_carriage_over_the_stroke_is_rejected(rig):
    robot, limits = rig
    long_stroke = type(limits)(**{**vars(limits), "carriage_stroke": 0.2})
    traj = pose_trajectory(robot, "stroke", np.zeros((2, 3)), long_stroke, carriages=[[0, 0, 0], [0, 0.12, 0]])
    sample = int(np.argmax(traj.zeta[:, 1] > limits.carriage_stroke))
    first = check_trajectory(traj, robot, limits).first
    assert (first.quantity, first.sample, first.chain, first.name) == ("stroke", sample, 2, "zeta2")
    assert first.limit == limits.carriage_stroke and first.value > limits.carriage_stroke
    assert check_trajectory(traj, robot, long_stroke).ok


def test_too_fast_is_rejected(rig, paper_set):
    robot, limits = rig
    sq = paper_set["squares"][1]
    fast = Trajectory("fast", sq.t / 2, sq.X, 2 * sq.Xd, 4 * sq.Xdd, sq.Theta, 2 * sq.Thetad, 4 * sq.Thetadd)
    over_v = np.abs(fast.Thetad) > limits.max_speed
    over_a = np.abs(fast.Thetadd) > limits.max_accel
    first_v, first_a = np.argwhere(over_v)[0], np.argwhere(over_a)[0]
    sample, col = min(tuple(first_v), tuple(first_a))
    first = check_trajectory(fast, robot, limits).first
    quantity = "speed" if tuple(first_v) <= tuple(first_a) else "acceleration"
    assert (first.quantity, first.sample, first.chain) == (quantity, sample, col % 3 + 1)


def test_hand_edited_jump_is_caught(rig, paper_set):
    robot, limits = rig
    sq = paper_set["squares"][0]
    Theta = sq.Theta.copy()
    Theta[200:, 0] += 0.05  # a step of 0.05 rad in theta1, derivatives unchanged
    edited = Trajectory("edited", sq.t, sq.X, sq.Xd, sq.Xdd, Theta, sq.Thetad, sq.Thetadd)
    report = check_trajectory(edited, robot, limits)
    assert report.first.sample == 200 and report.first.time == sq.t[200]
    assert {v.quantity for v in report.violations} >= {"consistency", "speed"}


# -- files ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_save_load_round_trip_is_exact(tmp_path, paper_set, suffix):
    traj = paper_set["triangle"]
    back = load(save(traj, tmp_path / f"tri{suffix}"))
    assert back.name == traj.name and back.metadata == traj.metadata
    for key in ("t", "X", "Xd", "Xdd", "Theta", "Thetad", "Thetadd"):
        assert np.array_equal(getattr(back, key), getattr(traj, key)), key


def test_csv_header_names_columns_with_units(tmp_path, paper_set):
    path = save(paper_set["squares"][0], tmp_path / "sq.csv")
    header = path.read_text().splitlines()[3].split(",")
    assert header[:4] == ["t[s]", "x[m]", "y[m]", "alpha[rad]"] and header[-1] == "zeta3dd[m/s^2]"
    assert len(header) == 28


def test_malformed_files_give_clear_errors(tmp_path, paper_set):
    good = save(paper_set["squares"][0], tmp_path / "good.csv").read_text().splitlines()
    cases = {
        "magic": (["nonsense"] + good[1:], r"line 1: expected"),
        "column": (good[:3] + [good[3].replace("theta2[rad]", "theta2[deg]")] + good[4:],
                   r"line 4: bad column header \(missing \['theta2\[rad\]'\]"),
        "value": (good[:10] + [",".join(c if i != 5 else "abc" for i, c in enumerate(good[10].split(",")))]
                  + good[11:],
                  r"line 11, column yd\[m/s\]: 'abc' is not a number"),
        "short": (good[:10] + [",".join(good[10].split(",")[:-1])] + good[11:], r"line 11: 27 values, expected 28"),
        "time": (good[:10] + [good[9]] + good[11:], r"time is not strictly increasing at sample 6"),
        "meta": (good[:2] + ["# metadata: {not json"] + good[3:], r"metadata is not valid JSON"),
    }
    for name, (lines, message) in cases.items():
        path = tmp_path / f"{name}.csv"
        path.write_text("\n".join(lines) + "\n")
        with pytest.raises(TrajectoryFileError, match=message) as info:
            load(path)
        assert str(path) in str(info.value), name
    np.savez(tmp_path / "bad.npz", t=np.arange(3.0))
    with pytest.raises(TrajectoryFileError, match=r"bad.npz: missing array\(s\) name, metadata, X"):
        load(tmp_path / "bad.npz")
    with pytest.raises(TrajectoryFileError, match="no such trajectory file"):
        load(tmp_path / "absent.csv")


def test_plot_writes_a_png(tmp_path, rig, paper_set):
    from trajectories.plot import plot_trajectory

    robot, _ = rig
    out = plot_trajectory(paper_set["triangle"], robot, tmp_path / "tri.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000
