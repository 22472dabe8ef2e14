"""Config loading: every shipped config is valid; every kind of mistake names file, key and line."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

import drivers.errors

from ident_hw.config import ConfigError, load_config, resolved_yaml
from ident_hw.config.robots import initial_parameters, model_of
from ident_hw.config.to_drivers import axis_config, axis_scaling
from ident_hw.experiment.robot_trajectories import feasibility_limits
from ident_hw.model import Delta, DeltaGeometry, InertialParams, ThreePRRR
from ident_hw.model.delta import physical_parameters
from recorded_data import dataset, needs_datasets

CONFIGS = Path(__file__).resolve().parent.parent / "configs"
SHIPPED_ROBOT_TEXT = (CONFIGS / "robot-3prrr.yaml").read_text()
DESCRIPTION_LINE = "  description: robots/3prrr.xml"
#: robot-3prrr.yaml naming its description file by its absolute path: a copy of it anywhere reads the shipped file
ROBOT_TEXT = SHIPPED_ROBOT_TEXT.replace(DESCRIPTION_LINE, f"  description: {CONFIGS / 'robots' / '3prrr.xml'}")
SIM_TEXT = (CONFIGS / "sim-3prrr.yaml").read_text()


def line_of(text: str, needle: str, occurrence: int = 1) -> int:
    """1-based line of the ``occurrence``-th line containing ``needle``."""
    hits = [i + 1 for i, line in enumerate(text.splitlines()) if needle in line]
    return hits[occurrence - 1]


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def robot_with(tmp_path: Path, old: str, new: str) -> tuple[Path, str]:
    """robot-3prrr.yaml with ``old`` replaced by ``new``, written to ``tmp_path`` (its description
    file named by its absolute path)."""
    assert old in ROBOT_TEXT
    text = ROBOT_TEXT.replace(old, new, 1)
    return write(tmp_path, "robot.yaml", text), text


def expect_error(path: Path, key: str, line: int, *words: str) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        load_config(path)
    err = info.value
    assert err.file == str(path)
    assert err.key == key
    assert err.line == line
    message = str(err)
    assert str(path) in message and key in message and f"line {line}" in message
    for word in words:
        assert word in message
    return err


@pytest.mark.parametrize("name", sorted(p.name for p in CONFIGS.glob("*.yaml")))
def test_every_shipped_config_loads(name):
    if needs_datasets((CONFIGS / name).read_text()):
        dataset("ur10e")
    cfg = load_config(CONFIGS / name)
    model = model_of(cfg.robot)
    assert [a.kind for a in cfg.robot.actuators] == list(model.actuator_kinds)
    assert len(initial_parameters(cfg.robot)) == len(model.parameter_names)


def test_robot_values_map_to_model_and_drive_scaling():
    cfg = load_config(CONFIGS / "robot-3prrr.yaml")
    assert cfg.robot.description == str(CONFIGS / "robots" / "3prrr.xml")
    model = model_of(cfg.robot)
    assert isinstance(model, ThreePRRR)
    geo = model.geometry
    # read off the file by pinocchio: the guides' angles to the rounding of its rotation matrices
    assert geo.gamma == pytest.approx((0.0, 2 * math.pi / 3, 4 * math.pi / 3), rel=1e-15, abs=1e-15)
    assert (geo.l1, geo.l2, geo.s1, geo.s2, geo.h, geo.a, geo.modes) == (0.30, 0.30, 0.15, 0.15, 0.12, 0.40, (1, 1, 1))
    cad = InertialParams.from_vector(initial_parameters(cfg.robot))
    assert (cad.m_c, cad.m_l1, cad.m_l2, cad.m_ee) == (780.0, 0.30, 0.354, 0.78)
    # slender rod and disc formulas, computed here independently of the file's numbers
    assert cad.I_l1 == pytest.approx(0.30 * 0.30**2 / 12)
    assert cad.I_l2 == pytest.approx(0.354 * 0.30**2 / 12)
    assert cad.I_ee == pytest.approx(0.78 * 0.12**2 / 2)
    assert cad.f_v == cad.f_c == (0.0,) * 6
    carriage = axis_scaling(cfg.robot.actuators[3])
    assert carriage.kind == "prismatic" and carriage.screw_lead == 0.002
    assert carriage.force_per_amp == pytest.approx(0.0603 * 2 * math.pi / 0.002)
    assert feasibility_limits(cfg.robot).carriage_stroke == 0.10
    # an actuator without its drive (a config of recordings made elsewhere) has no drive settings
    for key in ("node_id", "profile"):
        with pytest.raises(drivers.errors.ConfigError, match=rf"actuator .zeta1.: no {key}: a drive on the bus needs"):
            axis_config(dataclasses.replace(cfg.robot.actuators[3], **{key: None}))


def test_homing_offsets_are_the_home_pose_angles():
    cfg = load_config(CONFIGS / "robot-3prrr.yaml")
    robot = model_of(cfg.robot)
    assert isinstance(robot, ThreePRRR)
    theta, _ = robot.inverse_kinematics([[0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]])
    offsets = [a.homing.offset for a in cfg.robot.actuators[:3]]
    assert offsets == pytest.approx(theta[0], abs=1e-6)


def test_sim_config_extends_robot_and_has_a_campaign():
    cfg = load_config(CONFIGS / "sim-3prrr.yaml")
    assert cfg.simulated
    assert initial_parameters(cfg.robot)[0] == 780.0
    truth = cfg.sim.truth
    assert (truth.m_c, truth.m_l1, truth.m_l2, truth.m_ee) == (603.62, 0.30, 0.5723, 0.2269)
    squares = [t for t in cfg.trajectories if t.kind == "square"]
    assert [round(math.degrees(t.rotation)) for t in squares] == [0, 10, 20, 30, 40]
    assert cfg.identification.validation == ("triangle",)


@pytest.mark.parametrize("key", ["geometry", "cad"])
def test_the_retired_geometry_and_cad_sections_say_what_to_write(tmp_path, key):
    """A config of an earlier version (the 3PRRR's geometry and CAD values in YAML) is refused at
    the key with what replaced it: the description file."""
    path, text = robot_with(tmp_path, "  stroke: 0.10", f"  {key}:\n    l1: 0.30\n  stroke: 0.10")
    expect_error(path, f"robot.{key}", line_of(text, f"  {key}:"), "no longer a key", "description", "3prrr.xml")


def test_a_description_file_that_is_no_3prrr_is_refused_naming_file_and_key(tmp_path):
    """The hand model read off a file it does not describe (the first link 5 cm longer in the file,
    ``elbow1`` placed further) disagrees with the file's own model: refused at load."""
    xml = (CONFIGS / "robots" / "3prrr.xml").read_text()
    bad = xml.replace('<body name="link2_2" pos="0.3 0 0">', '<body name="link2_2" pos="0.35 0 0">')
    assert bad != xml
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "3prrr.xml").write_text(bad)
    path = write(tmp_path, "robot.yaml", SHIPPED_ROBOT_TEXT)
    err = expect_error(path, "robot.description", line_of(SHIPPED_ROBOT_TEXT, DESCRIPTION_LINE), "3prrr.xml")
    assert "3PRRR" in str(err) and "pinocchio" in str(err)


def test_resolved_yaml_is_self_contained_and_equivalent(tmp_path):
    # its description file named where it is (the results folder's copy names its own copy)
    text = resolved_yaml(CONFIGS / "sim-3prrr.yaml", {"robot.description": str(CONFIGS / "robots" / "3prrr.xml")})
    assert "extends" not in yaml.safe_load(text)
    copy = write(tmp_path, "copy.yaml", text)
    assert load_config(copy) == load_config(CONFIGS / "sim-3prrr.yaml")


def test_typo_key_is_named_with_a_suggestion(tmp_path):
    path, text = robot_with(tmp_path, "  stroke: 0.10", "  strok: 0.10")
    expect_error(path, "robot.strok", line_of(text, "strok:"), "unknown key", "'stroke'")


def test_missing_key(tmp_path):
    path, text = robot_with(tmp_path, "      torque_constant: 0.0369   # EC 45 flat class motor\n", "")
    # reported at the mapping that lacks it
    expect_error(path, "robot.actuators[0].torque_constant", line_of(text, "- &revolute"), "missing key", "a number")


def test_negative_length(tmp_path):
    path, text = robot_with(tmp_path, "  stroke: 0.10", "  stroke: -0.10")
    expect_error(path, "robot.stroke", line_of(text, "stroke: -0.10"), "positive", "-0.1")


def test_wrong_type(tmp_path):
    path, text = robot_with(tmp_path, "  stroke: 0.10", "  stroke: far")
    expect_error(path, "robot.stroke", line_of(text, "stroke: far"), "expected a number", "'far'")


def test_wrong_length_of_a_list(tmp_path):
    path, text = robot_with(tmp_path, "modes: [1, 1, 1]", "modes: [1, 1]")
    expect_error(path, "robot.modes", line_of(text, "modes:"), "list of 3")


def test_bad_choice_inside_a_merged_list_item(tmp_path):
    path, text = robot_with(tmp_path, "      profile: epos4\n", "      profile: epos3\n")
    expect_error(path, "robot.actuators[0].profile", line_of(text, "profile: epos3"), "'epos2'", "'epos4'")


def test_cross_field_rule_points_at_the_key(tmp_path):
    path, text = robot_with(tmp_path, "      name: theta2\n      node_id: 2", "      name: theta2\n      node_id: 1")
    expect_error(path, "robot.actuators[1].node_id", line_of(text, "node_id: 1", 2), "already used")


def sim_with(tmp_path: Path, old: str, new: str) -> tuple[Path, str]:
    """sim-3prrr.yaml with ``old`` replaced by ``new``, written to ``tmp_path`` (extending the shipped robot)."""
    text = SIM_TEXT.replace("extends: robot-3prrr.yaml", f"extends: {CONFIGS / 'robot-3prrr.yaml'}")
    assert old in text
    text = text.replace(old, new, 1)
    return write(tmp_path, "sim.yaml", text), text


def test_degrees_and_radians_both_given(tmp_path):
    path, text = sim_with(tmp_path, "rotation_deg: 10,", "rotation_deg: 10, rotation: 0.2,")
    expect_error(path, "trajectories[3].rotation_deg", line_of(text, "rotation: 0.2"), "not both")


def test_radians_accepted_and_exponent_floats(tmp_path):
    path, _ = sim_with(tmp_path, "rotation_deg: 10,", "rotation: 0.17453292519943295,")
    path.write_text(path.read_text().replace("current_noise: 0.002", "current_noise: 2e-3"))
    cfg = load_config(path)
    assert cfg.trajectories[3].rotation == pytest.approx(math.radians(10))
    assert cfg.sim.current_noise == 2e-3


def test_duplicate_key(tmp_path):
    path, text = robot_with(tmp_path, "  stroke: 0.10", "  stroke: 0.10\n  stroke: 0.11")
    expect_error(path, "robot.stroke", line_of(text, "stroke: 0.11"), "duplicate")


def test_yaml_syntax_error(tmp_path):
    path, text = robot_with(tmp_path, "  stroke: 0.10", "  stroke: [0.10")
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert info.value.file == str(path) and "not valid YAML" in str(info.value)
    assert info.value.line is not None


def test_error_in_the_base_file_names_the_base(tmp_path):
    base, text = robot_with(tmp_path, "      name: theta2\n      node_id: 2", "      name: theta2\n      node_id: 1")
    child = write(tmp_path, "child.yaml", "extends: robot.yaml\nrobot:\n  stroke: 0.05\n")
    with pytest.raises(ConfigError) as info:
        load_config(child)
    err = info.value
    assert (err.file, err.key, err.line) == (str(base), "robot.actuators[1].node_id", line_of(text, "node_id: 1", 2))
    assert "already used" in str(err)


def test_extends_overrides_deeply(tmp_path):
    robot_with(tmp_path, "  stroke: 0.10", "  stroke: 0.10")
    child = write(tmp_path, "child.yaml", "extends: robot.yaml\nrobot:\n  safety:\n    max_cond_A: 40.0\n  stroke: 0.05\n")
    cfg = load_config(child)
    assert cfg.robot.safety.max_cond_A == 40.0 and cfg.robot.safety.min_serial_margin == 0.1
    assert cfg.robot.stroke == 0.05 and cfg.robot.modes == (1, 1, 1)


def test_bad_include(tmp_path):
    child = write(tmp_path, "child.yaml", "# comment\nextends: nowhere.yaml\n")
    expect_error(child, "extends", 2, "'nowhere.yaml' not found")


def test_include_cycle(tmp_path):
    write(tmp_path, "a.yaml", "extends: b.yaml\n")
    b = write(tmp_path, "b.yaml", "extends: a.yaml\n")
    with pytest.raises(ConfigError, match="cycle") as info:
        load_config(tmp_path / "a.yaml")
    assert info.value.file == str(b)


def test_missing_file_and_empty_file(tmp_path):
    with pytest.raises(ConfigError, match="file not found"):
        load_config(tmp_path / "absent.yaml")
    with pytest.raises(ConfigError, match="empty"):
        load_config(write(tmp_path, "empty.yaml", "# nothing\n"))


def test_campaign_references_are_checked(tmp_path):
    write(tmp_path, "robot-3prrr.yaml", ROBOT_TEXT)
    text = SIM_TEXT.replace("validation: [triangle]", "validation: [triangel]")
    path = write(tmp_path, "sim.yaml", text)
    expect_error(path, "identification.validation[0]", line_of(text, "validation: [triangel]"), "'triangel'")
    text = SIM_TEXT.replace("parameters: [m_c,", "parameters: [m_carriage,")
    path = write(tmp_path, "sim.yaml", text)
    expect_error(path, "identification.steps[0].parameters[0]", line_of(text, "m_carriage"), "unknown parameter")


def test_out_of_range_value(tmp_path):
    write(tmp_path, "robot-3prrr.yaml", ROBOT_TEXT)
    text = SIM_TEXT.replace("sync_rate: 250.0", "sync_rate: 25000.0")
    path = write(tmp_path, "sim.yaml", text)
    expect_error(path, "bus.sync_rate", line_of(text, "sync_rate: 25000.0"), "[1.0, 2000.0]", "Hz")


def test_fourier_trajectory_defaults_to_the_shipped_excitation(tmp_path):
    from ident_hw.experiment.plan import plan
    write(tmp_path, "robot-3prrr.yaml", ROBOT_TEXT)
    config = load_config(write(tmp_path, "sim.yaml", SIM_TEXT))
    step = next(s for s in config.identification.steps if s.method == "wls")
    assert step.trajectories == ("excitation",) and len(step.parameters) == 19
    (planned,) = plan(config, ["excitation"])
    assert planned.ok and planned.trajectory.metadata["generator"] == "fourier"
    # ten cycles of the shipped 5 s excitation at the 250 Hz SYNC rate (back to back: one 4 ms
    # period between the end of a cycle and the start of the next), starting and ending at rest at home
    assert config.bus.sync_rate == 250.0
    assert planned.trajectory.duration == pytest.approx(10 * 5.004 - 0.004, abs=1e-9)
    assert abs(planned.trajectory.Thetad[[0, -1]]).max() < 1e-12


@pytest.mark.parametrize("old, new, where", [
    ("{name: sweep, kind: carriage_sweep, size: 0.06}",
     "{name: sweep, kind: carriage_sweep, size: 0.06, rotation_deg: 10}", "trajectories[1].rotation"),
    ("{name: square1, kind: square, size: 0.12,", "{name: square1, kind: square, harmonics: 3, size: 0.12,",
     "trajectories[2].harmonics"),
    ("{name: excitation, kind: fourier, cycles: 10}", "{name: excitation, kind: fourier, cycles: 10, speed_scale: 0.5}",
     "trajectories[7].speed_scale"),
    ("{name: triangle, kind: triangle}", "{name: triangle, kind: triangle, seed: 3}", "trajectories[8].seed"),
])
def test_a_key_its_trajectory_kind_does_not_read_is_refused(tmp_path, old, new, where):
    """A key that the trajectory's kind would silently ignore is an error naming file, line and key."""
    write(tmp_path, "robot-3prrr.yaml", ROBOT_TEXT)
    assert old in SIM_TEXT
    text = SIM_TEXT.replace(old, new, 1)
    expect_error(write(tmp_path, "sim.yaml", text), where, line_of(text, new), "does not use", "ignored")


def test_the_trajectory_kinds_are_those_of_keys_of_kind(tmp_path):
    """The kinds are listed once (KEYS_OF_KIND); a kind not there is refused, naming file, line and key."""
    from typing import get_args, get_type_hints

    from ident_hw.config.trajectory import KEYS_OF_KIND, TrajectoryConfig
    assert get_args(get_type_hints(TrajectoryConfig)["kind"]) == tuple(KEYS_OF_KIND)
    write(tmp_path, "robot-3prrr.yaml", ROBOT_TEXT)
    old = "{name: triangle, kind: triangle}"
    text = SIM_TEXT.replace(old, "{name: triangle, kind: triangel}", 1)
    expect_error(write(tmp_path, "sim.yaml", text), "trajectories[8].kind", line_of(text, "triangel"),
                 "'triangel'", "did you mean 'triangle'")


def test_the_seed_streams_keep_their_numbers():
    """A stream's number is part of every simulated result of a seed: the encoder edges draw from
    ``[seed, 2]``, the perturbed truth from ``[seed, 3]``."""
    import numpy as np

    from ident_hw.config.robots import perturbed
    from ident_hw.config.sim import SeedStream
    assert (SeedStream.ENCODER_EDGES, SeedStream.TRUTH_PERTURBATION) == (2, 3)
    z = np.random.default_rng([7, 3]).standard_normal(2)
    assert np.array_equal(perturbed(np.ones(2), ("a", "b"), 0.1, 7), np.exp(0.1 * z))


def test_a_lab_config_extended_onto_a_virtual_bus_keeps_its_bitrate(tmp_path):
    """The documented way to try a lab's config on the simulated rig: extend it with a virtual
    bus. The hardware's bitrate comes along and is accepted (a virtual bus ignores it)."""
    overlay = write(tmp_path, "hil-sim.yaml", f"extends: {CONFIGS / 'hil-3prrr-epos4.yaml'}\n"
                                              "bus: {interface: virtual, channel: test}\n")
    bus = load_config(overlay).bus
    assert (bus.interface, bus.bitrate) == ("virtual", load_config(CONFIGS / "hil-3prrr-epos4.yaml").bus.bitrate)


def test_source_and_base_dir_are_given_by_the_loader_not_the_file(tmp_path):
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    assert config.source == str(CONFIGS / "sim-3prrr.yaml") and config.base_dir == CONFIGS
    path, text = robot_with(tmp_path, "robot:", "base_dir: elsewhere\nrobot:")
    expect_error(path, "base_dir", line_of(text, "base_dir"), "unknown key")


def test_path_only_for_file_and_fourier_trajectories(tmp_path):
    write(tmp_path, "robot-3prrr.yaml", ROBOT_TEXT)
    old = "{name: square1, kind: square, size: 0.12,"
    text = SIM_TEXT.replace(old, "{name: square1, kind: square, path: a.json, size: 0.12,")
    expect_error(write(tmp_path, "sim.yaml", text), "trajectories[2].path", line_of(text, "a.json"),
                 "a 'square' trajectory does not use path", "ignored")
    text = SIM_TEXT.replace("kind: fourier, cycles: 10}", "kind: fourier, path: missing.json}")
    config = load_config(write(tmp_path, "sim.yaml", text))
    from ident_hw.experiment.plan import plan
    (planned,) = plan(config, ["excitation"])
    assert not planned.ok and "missing.json" in planned.describe()


def test_trajectory_files_of_a_config_read_by_a_relative_path(tmp_path, monkeypatch):
    """A ``fourier`` and a ``file`` trajectory's ``path`` is relative to the config that writes it,
    also where the config itself is named relative to the working directory (``ident-hw run
    configs/x.yaml``): the files are found once, not under the config's folder twice."""
    import shutil

    import trajectories
    from ident_hw.experiment.plan import plan

    folder = tmp_path / "configs"
    folder.mkdir()
    write(folder, "robot-3prrr.yaml", ROBOT_TEXT)
    shutil.copy(Path(trajectories.__file__).parent / "data" / "fourier-nominal.json", folder / "excitation.json")
    text = SIM_TEXT.replace("kind: fourier, cycles: 10}", "kind: fourier, path: excitation.json}")
    text = text.replace("{name: triangle, kind: triangle}", "{name: triangle, kind: file, path: square.npz}")
    write(folder, "sim.yaml", text)
    monkeypatch.chdir(tmp_path)
    config = load_config(Path("configs") / "sim.yaml")
    (square,) = plan(config, ["square1"])
    trajectories.save(square.trajectory, folder / "square.npz")
    (fourier, loaded) = plan(config, ["excitation", "triangle"])
    assert fourier.ok and loaded.ok, (fourier.describe(), loaded.describe())
    assert len(loaded.trajectory.t) == len(square.trajectory.t)


def test_one_least_squares_step_only(tmp_path):
    write(tmp_path, "robot-3prrr.yaml", ROBOT_TEXT)
    text = SIM_TEXT.replace("      parameters: [I_ee]\n      method: sqp", "      parameters: [I_ee]\n      method: ols")
    path = write(tmp_path, "sim.yaml", text)
    with pytest.raises(ConfigError, match=r"identification.steps\[3\].method.*only one step"):
        load_config(path)


@pytest.mark.parametrize("identification, key, line, words", [
    ("  steps: []", "identification.steps", 3, ["at least one step"]),
    ("  steps:\n    - {name: base, trajectories: [excitation], parameters: [], method: wls}",
     "identification.steps[0].parameters", 4, ["step 'base' needs at least one parameter"]),
    ("  steps:\n    - {name: base, trajectories: [], parameters: [all], method: wls}",
     "identification.steps[0].trajectories", 4, ["step 'base' needs at least one trajectory"]),
    ("  filter: {cutoff: 125.0}", "identification.filter.cutoff", 3, ["below half the SYNC rate (125 Hz"]),
    ("  bounds: {m_c: [600.0, 600.0]}", "identification.bounds.m_c", 3, ["min < max", "leave it out of the steps"]),
])
def test_what_run_could_not_identify_is_refused_where_it_is_written(tmp_path, identification, key, line, words):
    """Each of these once passed ``check``, and ``run`` failed after recording the whole campaign
    (the main job's SYNC at 250 Hz: a cut-off must lie below 125 Hz)."""
    text = f"extends: {CONFIGS / 'sim-3prrr.yaml'}\nidentification:\n{identification}\n"
    path = write(tmp_path, "bad.yaml", text)
    expect_error(path, key, line, *words)


def test_a_standstill_too_short_for_a_noise_floor_is_refused(tmp_path):
    """Its first 0.5 s are left out of the floor and the filter trims its ends: below 1 s the
    floor was silently missing from the verdict."""
    text = (f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n"
            "trajectories: [{name: still, kind: standstill, duration: 0.9}, {name: s, kind: carriage_sweep, size: 0.03}]\n"
            "identification: {steps: [{name: a, trajectories: [s], parameters: [m_c]}], validation: []}\n")
    expect_error(write(tmp_path, "still.yaml", text), "trajectories[0].duration", 2,
                 "a standstill of 0.9 s gives no noise floor", "at least 1 s")
    load_config(write(tmp_path, "still.yaml", text.replace("duration: 0.9", "duration: 1.0")))


@pytest.mark.parametrize("interface, channel, local", [
    ("virtual", "anything", True),
    ("socketcan", "vcan0", True),
    ("socketcan", "can0", False),
    ("pcan", "PCAN_USBBUS1", False),
    ("udp_multicast", "ff11::4944", True),                  # interface-local (scope 1): loopback only
    ("udp_multicast", "ff01::1", True),
    ("udp_multicast", "ff15:7079:7468:6f6e:6465:6d6f:6d63:6173", False),   # python-can's default, site scope
    ("udp_multicast", "ff02::1", False),                    # link-local: reaches the LAN
    ("udp_multicast", "239.74.163.2", False),               # IPv4 has no interface-local scope
    ("udp_multicast", "not-an-address", False),
])
def test_lockstep_only_on_a_bus_that_cannot_reach_hardware(tmp_path, interface, channel, local):
    path = write(tmp_path, "bus.yaml", f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n"
                                       f"bus: {{interface: {interface}, channel: '{channel}', sync: lockstep}}\n")
    if local:
        config = load_config(path)
        assert config.simulated and config.sync_mode == "lockstep"
    else:
        with pytest.raises(ConfigError) as info:
            load_config(path)
        assert info.value.key == "bus.sync" and "may carry real drives" in str(info.value)
        path.write_text(path.read_text().replace(", sync: lockstep", ""))
        assert load_config(path).sync_mode == "periodic"     # and --arm is what moves it


def test_per_arm_amplitudes_are_for_the_delta_s_paths(tmp_path):
    delta = CONFIGS / "sim-delta.yaml"
    good = write(tmp_path, "good.yaml", f"extends: {delta}\ntrajectories:\n"
                 "  - {name: training, kind: delta_training, duration: 10.0, amplitude: [1.5, 1.0, 0.5]}\n"
                 "identification: {validation: [], online: {in_run: false}}\n")
    assert load_config(good).trajectories[0].amplitude == (1.5, 1.0, 0.5)
    two = write(tmp_path, "two.yaml", f"extends: {delta}\ntrajectories:\n"
                "  - {name: training, kind: delta_training, duration: 10.0, amplitude: [1.5, 1.0]}\n")
    expect_error(two, "trajectories[0].amplitude", 3, "one amplitude per arm", "got 2")
    square = write(tmp_path, "square.yaml", f"extends: {CONFIGS / 'sim-3prrr.yaml'}\ntrajectories:\n"
                   "  - {name: s, kind: square, size: 0.05, amplitude: [1.0, 1.0, 1.0]}\n")
    expect_error(square, "trajectories[0].amplitude", 3, "a 'square' trajectory does not use amplitude")


def test_the_delta_is_read_from_its_description_file():
    """robot-delta.yaml names robots/delta.xml: the hand Delta built from it is the configs' Delta
    (``physical_parameters``, the bodies the file's crosses and yokes lumped in, the platform's
    inertia the file's, which never acts), the rotor inertia the arms' armature."""
    cfg = load_config(CONFIGS / "robot-delta.yaml")
    model = model_of(cfg.robot)
    assert isinstance(model, Delta)
    g = model.geometry
    assert (g.L1, g.L2, g.R, g.r) == (0.309, 0.595, 0.140, 0.035)
    assert g.psi == pytest.approx(DeltaGeometry().psi, rel=1e-15, abs=1e-15)
    np.testing.assert_array_equal(model.g, [0.0, 0.0, -9.81])
    pi = initial_parameters(cfg.robot)
    expected = physical_parameters(DeltaGeometry())
    np.testing.assert_allclose(pi[:64], expected[:64], rtol=0, atol=1e-15)     # arms, rods, platform mass and centre
    np.testing.assert_array_equal(pi[70:], [0.0] * 6 + [0.01] * 3)


def test_the_retired_delta_section_says_what_to_write(tmp_path):
    text = (CONFIGS / "robot-delta.yaml").read_text().replace(
        "  description: robots/delta.xml", "  delta:\n    geometry: {L1: 0.309}")
    path = write(tmp_path, "delta.yaml", text)
    expect_error(path, "robot.delta", line_of(text, "  delta:"), "no longer a key", "description: robots/delta.xml")


def test_a_description_file_that_is_no_delta_is_refused(tmp_path):
    """A platform yoke off its joint's centre is not what the hand Delta lumps: refused at load,
    naming the body and the file."""
    xml = (CONFIGS / "robots" / "delta.xml").read_text()
    bad = xml.replace('<body name="wrist2" pos="-0.595 0 0">\n              <joint name="wrist2_n" type="hinge" axis="0 0 1"/>\n'
                      '              <inertial pos="0 0 0"',
                      '<body name="wrist2" pos="-0.595 0 0">\n              <joint name="wrist2_n" type="hinge" axis="0 0 1"/>\n'
                      '              <inertial pos="0.01 0 0"')
    assert bad != xml
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "delta.xml").write_text(bad)
    text = (CONFIGS / "robot-delta.yaml").read_text()
    path = write(tmp_path, "delta.yaml", text)
    err = expect_error(path, "robot.description", line_of(text, "description: robots/delta.xml"), "delta.xml")
    assert "'wrist2_n'" in str(err) and "cross" in str(err)
