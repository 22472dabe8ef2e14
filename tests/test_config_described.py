"""Configs of robots read from their description files (``robot.kind: described``): what they
load into, and every mistake named by file, key and line."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from ident_hw.config import ConfigError, load_config
from ident_hw.config.robots import KINDS, initial_parameters, kind_of, model_of, true_parameters
from ident_hw.model.described import DescribedRobot

CONFIGS = Path(__file__).resolve().parent.parent / "configs"
ROBOT_2R = (CONFIGS / "robot-2r.yaml").read_text()
SIM_2R = (CONFIGS / "sim-2r.yaml").read_text()


def setup(tmp_path: Path, robot: str = ROBOT_2R, sim: str = SIM_2R) -> Path:
    """The 2R configs, possibly changed, in ``tmp_path`` beside a copy of the description and
    of the optimised excitations."""
    (tmp_path / "robots").mkdir()
    shutil.copy(CONFIGS / "robots" / "2r.urdf", tmp_path / "robots" / "2r.urdf")
    shutil.copytree(CONFIGS / "excitations", tmp_path / "excitations")
    (tmp_path / "robot-2r.yaml").write_text(robot)
    (tmp_path / "sim-2r.yaml").write_text(sim)
    return tmp_path / "sim-2r.yaml"


def expect_error(path: Path, key: str, needle: str, *words: str) -> None:
    """``load_config(path)`` fails at ``key``, on the line of the file that holds ``needle``."""
    with pytest.raises(ConfigError) as info:
        load_config(path)
    err = info.value
    assert err.key == key, str(err)
    text = Path(err.file).read_text().splitlines()
    assert needle in text[err.line - 1], (str(err), text[err.line - 1])
    for word in words:
        assert word in str(err)


def test_the_2r_config_is_its_description_with_the_config_s_actuators(tmp_path):
    cfg = load_config(setup(tmp_path))
    model = model_of(cfg.robot)
    assert isinstance(model, DescribedRobot)
    assert model.actuator_names == ("shoulder", "elbow")
    assert model.actuated_joints == ("joint1", "joint2")
    assert model.path == tmp_path / "robots" / "2r.urdf"     # relative to the robot file that names it
    np.testing.assert_array_equal(model.home_actuated(), [0.0, 1.2])
    names = model.parameter_names
    cad, truth = initial_parameters(cfg.robot), true_parameters(cfg)
    # CAD: the file's link 2 (2.0 kg at 0.15 m), the config's rotor inertias; truth: the factors
    assert cad[names.index("link2.m")] == pytest.approx(2.0)
    assert cad[names.index("link2.mx")] == pytest.approx(0.3)
    assert cad[names.index("Jm_shoulder")] == 0.002 and cad[names.index("fv_elbow")] == 0.0
    assert truth[names.index("link2.m")] == pytest.approx(2.2)
    assert truth[names.index("fc_shoulder")] == 0.40 and truth[names.index("Jm_elbow")] == 0.0012
    assert kind_of(cfg.robot) is KINDS["described"]


def test_a_perturbed_truth_is_drawn_on_the_model_given(tmp_path, monkeypatch):
    """``true_parameters`` with the robot's model (the runner has it) builds no other; without it,
    one, the same: a described robot's model is read from its file."""
    import ident_hw.config.robots as robots
    setup(tmp_path)
    (tmp_path / "perturbed.yaml").write_text("extends: sim-2r.yaml\nsim: {perturb: 0.1, seed: 4}\n")
    cfg = load_config(tmp_path / "perturbed.yaml")
    model, built = model_of(cfg.robot), true_parameters(cfg)
    assert not np.array_equal(built, true_parameters(load_config(tmp_path / "sim-2r.yaml")))

    def no_second_model(robot):
        raise AssertionError("a second model built")
    monkeypatch.setattr(robots, "model_of", no_second_model)
    monkeypatch.setattr(robots, "described_model", no_second_model)
    assert np.array_equal(true_parameters(cfg, model), built)


def test_a_path_in_a_base_config_holds_in_the_config_extending_it(tmp_path):
    sub = tmp_path / "runs"
    setup(tmp_path)
    sub.mkdir()
    (sub / "mine.yaml").write_text("extends: ../sim-2r.yaml\n")
    assert model_of(load_config(sub / "mine.yaml").robot).path == tmp_path / "robots" / "2r.urdf"


@pytest.mark.parametrize("old, new, key, needle, words", [
    ("description: robots/2r.urdf", "description: robots/3r.urdf", "robot.description",
     "description:", ("no such description file",)),
    ("joint: joint2", "joint: joint3", "robot.actuators[1].joint", "joint: joint3",
     ("no joint 'joint3' to actuate", "joint1")),
    # the description's own errors point at the key that does not fit it (they all named the file's key)
    ("home: {joint1: 0.0, joint2: 1.2}", "home: {joint1: 0.0, elbow: 1.2}", "robot.described.home", "home:",
     ("home names no joint 'elbow'", "joint2")),
    ("end_effector: tool", "end_effector: hand", "robot.described.end_effector", "end_effector:",
     ("no body or site 'hand' to carry a payload",)),
    ("      kind: revolute\n", "      kind: prismatic\n      screw_lead: 0.005\n", "robot.actuators[0].kind", "kind: prismatic",
     ("joint 'joint1' of 2r.urdf is revolute",)),
    ("cad: {Jm: [0.002, 0.001]}", "cad: {Jm: [0.002, 0.001, 0.003]}", "robot.described.cad.Jm", "cad:",
     ("one value per actuator (2: shoulder, elbow)",)),
    ("cad: {Jm: [0.002, 0.001]}", "cad: {factors: {link3.m: 1.1}}", "robot.described.cad.factors.link3.m", "cad:",
     ("unknown parameter of 2r.urdf", "link1", "link2")),
])
def test_robot_mistakes_name_file_key_and_line(tmp_path, old, new, key, needle, words):
    assert old in ROBOT_2R
    expect_error(setup(tmp_path, robot=ROBOT_2R.replace(old, new, 1)), key, needle, *words)


@pytest.mark.parametrize("old, new, key, needle, words", [
    ("factors: {link2.m: 1.1,", "factors: {link2.mass: 1.1,", "sim.parameters.factors.link2.mass", "factors:",
     ("unknown parameter",)),
    ("fv: [0.30, 0.15]", "fv: [0.30]", "sim.parameters.fv", "fv:", ("one value per actuator",)),
    ("  parameters:               #", "  truth:                    #", "sim.truth.factors", "factors:",
     ("unknown key",)),
    # (without the excitation's keys: those a square does not read are refused first, each by its key)
    ("kind: joint_excitation, duration: 60.0, bandwidth: 1.5, seed: 1, path: excitations/2r.json",
     "kind: square, size: 0.1, bandwidth: 1.5",
     "trajectories[1].kind",
     "square", ("not one of the described's", "joint_excitation")),
    ("duration: 20.0, bandwidth: 1.5, seed: 2}", "duration: 20.0, bandwidth: 1.5, seed: 2, amplitude: [1, 1, 1]}",
     "trajectories[2].amplitude", "amplitude", ("one amplitude per actuator (2)",)),
])
def test_sim_and_trajectory_mistakes_name_file_key_and_line(tmp_path, old, new, key, needle, words):
    assert old in SIM_2R
    expect_error(setup(tmp_path, sim=SIM_2R.replace(old, new, 1)), key, needle, *words)


def test_a_section_of_another_robot_kind_is_refused(tmp_path):
    text = ROBOT_2R.replace("  coulomb_width: 0.01", "  stroke: 0.1\n  coulomb_width: 0.01", 1)
    expect_error(setup(tmp_path, robot=text), "robot.stroke", "stroke", "robot.kind 'described'", "described")


def test_the_retired_described_description_names_file_line_and_the_key_to_write(tmp_path):
    """``robot.described.description`` (the described robots' own key until the 3PRRR and the
    Delta took ``robot.description``) is refused at its line, saying what to write instead."""
    old = "  description: robots/2r.urdf"
    assert old in ROBOT_2R
    text = ROBOT_2R.replace(old, "  described:\n    description: robots/2r.urdf", 1).replace(
        "  described:                      # the settings", "                                   # the settings", 1)
    assert text.count("described:") == 1 and "    description: robots/2r.urdf" in text
    expect_error(setup(tmp_path, robot=text), "robot.described.description", "    description: robots/2r.urdf",
                 "no longer a key", "robot.description", "kind: described")
    assert "robot-2r.yaml" in str(pytest.raises(ConfigError, load_config, tmp_path / "sim-2r.yaml").value)


def test_a_described_robot_without_its_description_file_is_refused(tmp_path):
    text = ROBOT_2R.replace("  description: robots/2r.urdf", "", 1)
    with pytest.raises(ConfigError) as info:
        load_config(setup(tmp_path, robot=text))
    assert info.value.key == "robot.description" and "missing key" in str(info.value), str(info.value)


def test_the_described_section_may_be_left_out(tmp_path):
    """A described robot needs only ``robot.description``: without ``robot.described`` its settings
    take their defaults (home every joint 0, no rotor inertia in the CAD values)."""
    start = ROBOT_2R.index("  described:")
    end = ROBOT_2R.index("  coulomb_width:")
    setup(tmp_path, robot=ROBOT_2R[:start] + ROBOT_2R[end:])
    cfg = load_config(tmp_path / "robot-2r.yaml")
    assert cfg.robot.described is None
    model = model_of(cfg.robot)
    assert model.path == tmp_path / "robots" / "2r.urdf"
    np.testing.assert_array_equal(model.home_actuated(), [0.0, 0.0])
    cad = initial_parameters(cfg.robot)
    assert cad[model.parameter_names.index("Jm_shoulder")] == 0.0
    assert cad[model.parameter_names.index("link2.m")] == pytest.approx(2.0)
