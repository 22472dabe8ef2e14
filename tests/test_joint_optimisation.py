"""The optimised excitation of a described robot (:mod:`trajectories.joint_optimisation`, issue 48
item 3): on a planar five-bar with gravity in its plane, the optimised sines give a trajectory
within the actuator limits and the assembly limit whose base regressor is better conditioned
than the drawn one's, the conditions computed here by SVD on all the trajectory's samples (not the
criterion's instants nor its eigenvalue shortcut); a config reads the optimised file with
``path``, ``check`` says the condition before and after, and a wrong file is refused naming it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ident_hw.config import load_config
from ident_hw.config.robots import model_of
from ident_hw.experiment.robot_trajectories import actuator_limits
from ident_hw.experiment.excitation import main as optimise_main
from ident_hw.experiment.plan import plan
from test_described_jobs import FIVE_BAR_ROBOT
from test_tree_kernels import FIVE_BAR, five_bar
from trajectories.feasibility import ActuatorLimits
from trajectories.joint_optimisation import base_columns, optimise_joint_excitation
from trajectories.joint_space import JointHarmonics, check_described_trajectory, joint_excitation

DURATION, RATE, BANDWIDTH = 20.0, 250.0, 1.5


def svd_condition(robot, traj, every: int = 5) -> float:
    """cond (SVD) of the base regressor of every ``every``-th sample of ``traj``, columns at unit RMS."""
    Y, _ = robot.identification_regressor(traj.Theta[::every], traj.Thetad[::every], traj.Thetadd[::every],
                                          traj.X[0])
    W = Y.reshape(-1, Y.shape[-1])[:, base_columns(robot)]
    return float(np.linalg.cond(W / np.sqrt(np.mean(W**2, axis=0))))


@pytest.fixture(scope="module")
def optimised(tmp_path_factory):
    robot = five_bar(tmp_path_factory.mktemp("five-bar"), gravity="0 -9.81 0")
    home = robot.home_actuated()
    limits = ActuatorLimits(("a1", "a2"), home - 0.3, home + 0.3, np.array([2.0, 2.0]), np.array([20.0, 20.0]),
                            ("rad", "rad"))
    sines = optimise_joint_excitation(robot, limits, DURATION, BANDWIDTH, harmonics=3, seed=1,
                                      max_condition=60.0, samples=100, max_iter=10)
    return robot, limits, sines


def test_the_optimised_excitation_is_better_conditioned_and_feasible(optimised):
    robot, limits, sines = optimised
    drawn = joint_excitation(robot, limits, DURATION, RATE, BANDWIDTH, harmonics=3, seed=1)
    better = joint_excitation(robot, limits, DURATION, RATE, BANDWIDTH, sines=sines)
    # same frequencies, new phases and weights within their bounds
    np.testing.assert_array_equal(sines.frequencies, JointHarmonics.drawn(2, BANDWIDTH, 3, 1).frequencies)
    assert np.all((sines.weights >= 0.1) & (sines.weights <= 2.0))
    assert sines.cond_final < 0.7 * sines.cond_initial, (sines.cond_initial, sines.cond_final)
    before, after = svd_condition(robot, drawn), svd_condition(robot, better)
    assert after < 0.8 * before, (before, after)
    # the criterion's figures are those of the motion (its own instants): within a quarter
    assert before == pytest.approx(sines.cond_initial, rel=0.25) and after == pytest.approx(sines.cond_final, rel=0.25)
    # within 0.8 of the limits (the fit), the loops closed, the assembly below its limit
    report = check_described_trajectory(better, robot, limits, 60.0)
    assert report.ok, report.first
    home = robot.home_actuated()
    room = np.minimum(home - limits.low, limits.high - home)
    assert np.all(np.max(np.abs(better.Theta - home), axis=0) <= 0.8 * room + 1e-12)
    assert np.all(np.max(np.abs(better.Thetad), axis=0) <= 0.8 * limits.speed + 1e-12)
    assert better.metadata["optimised"] == {"cond_initial": sines.cond_initial, "cond_final": sines.cond_final}
    # the drawn excitation is the module's formula with the drawn frequencies and phases
    w, phi = JointHarmonics.drawn(2, BANDWIDTH, 3, 1).frequencies, JointHarmonics.drawn(2, BANDWIDTH, 3, 1).phases
    t = drawn.t[len(drawn.t) // 2]          # mid-way, the fade window is 1
    expected = home + np.array(drawn.metadata["scale"]) * np.sum(np.sin(w * t + phi) / w, axis=1)
    np.testing.assert_allclose(drawn.Theta[len(drawn.t) // 2], expected, rtol=0, atol=1e-12)


def test_a_config_reads_the_optimised_sines(optimised, tmp_path, capsys):
    robot, limits, sines = optimised
    (tmp_path / "five_bar.xml").write_text(FIVE_BAR.format(gravity="0 -9.81 0"))
    config = tmp_path / "sim-five-bar.yaml"
    config.write_text(FIVE_BAR_ROBOT.replace(
        "{name: excitation, kind: joint_excitation, duration: 30.0, bandwidth: 1.5, seed: 1}",
        "{name: excitation, kind: joint_excitation, duration: 20.0, bandwidth: 1.5, path: excitation.json}"))
    sines.save(tmp_path / "excitation.json")
    (p,) = plan(load_config(config), names=["excitation"])
    assert p.ok, p.describe()
    assert (f"optimised excitation: scaled condition of the base regressor {sines.cond_initial:.3g} drawn, "
            f"{sines.cond_final:.3g} optimised") in p.describe()
    cfg = load_config(config)
    again = joint_excitation(model_of(cfg.robot), actuator_limits(cfg.robot), DURATION, RATE, BANDWIDTH, sines=sines)
    np.testing.assert_array_equal(p.trajectory.Theta, again.Theta)

    # the tool writes what the optimisation gives (here: the config's own excitation of 20 s)
    assert optimise_main([str(config), "validation", str(tmp_path / "v.json"), "--iterations", "2"]) == 0
    written = JointHarmonics.load(tmp_path / "v.json", 2)
    assert written.optimised_for is not None and written.optimised_for.seed == 2 and written.cond_final <= written.cond_initial
    assert "optimised" in capsys.readouterr().out

    # a file for another robot, or with sines above the trajectory's bandwidth: refused, naming it
    doc = json.loads((tmp_path / "excitation.json").read_text())
    (tmp_path / "three.json").write_text(json.dumps({**doc, **{k: doc[k] + doc[k][:1] for k in
                                                               ("frequencies_rad_s", "phases_rad", "weights")}}))
    config.write_text(config.read_text().replace("path: excitation.json", "path: three.json"))
    (p,) = plan(load_config(config), names=["excitation"])
    assert not p.ok and "three.json: 3 rows of sines, the robot has 2 actuators" in p.describe()
    (tmp_path / "fast.json").write_text(json.dumps({**doc, "frequencies_rad_s": (np.array(doc["frequencies_rad_s"])
                                                                                * 2).tolist()}))
    config.write_text(config.read_text().replace("path: three.json", "path: fast.json"))
    (p,) = plan(load_config(config), names=["excitation"])
    assert not p.ok and "fast.json: sines up to" in p.describe() and "above the trajectory's bandwidth 1.5 Hz" in p.describe()
    (tmp_path / "bad.json").write_text("{}")
    config.write_text(config.read_text().replace("path: fast.json", "path: bad.json"))
    (p,) = plan(load_config(config), names=["excitation"])
    assert not p.ok and "bad.json: not a joint excitation file" in p.describe()


def test_an_excitation_file_whose_optimised_for_is_not_the_optimiser_s_is_refused_naming_it(tmp_path):
    """The record of what a set was optimised for is read back field by field; a file whose
    ``optimised_for`` lacks one (or has another) is an error naming the file, not a half record."""
    from pathlib import Path

    from trajectories.joint_space import JointHarmonics
    doc = json.loads((Path(__file__).parents[1] / "configs" / "excitations" / "2r.json").read_text())
    doc["optimised_for"] = {"seed": 1}
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"bad\.json: optimised_for is not what the optimiser writes"):
        JointHarmonics.load(bad)
