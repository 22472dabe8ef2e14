"""Trajectory files of any robot (issue 49): their columns are the robot's actuators, so a Delta's
or a described robot's trajectory is saved, read back exactly and streamed as a ``file``
trajectory; a file of another robot's columns is refused naming the file and both column sets.
Files of the first version (the 3PRRR's named columns) are still read (tests/test_traj.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ident_hw.config import load_config
from ident_hw.experiment.plan import PlanInputs, plan
from trajectories import TrajectoryFileError, load, read, save
from trajectories.files import MAGIC_V2

CONFIGS = Path(__file__).resolve().parent.parent / "configs"
KEYS = ("t", "X", "Xd", "Xdd", "Theta", "Thetad", "Thetadd")


def generated(config_name: str, trajectory: str):
    """A config's inputs and its trajectory ``trajectory`` as ``ident-hw run`` plans it."""
    config = load_config(CONFIGS / config_name)
    (planned,) = [p for p in plan(config, names=[trajectory]) if p.config.name == trajectory]
    assert planned.ok, planned.describe()
    return PlanInputs.of(config), planned.trajectory


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_a_delta_trajectory_is_saved_with_its_actuators_and_read_back_exactly(tmp_path, suffix):
    inputs, traj = generated("sim-delta.yaml", "verification")
    columns = inputs.columns
    assert [u for _, u in columns] == ["rad"] * 3
    path = save(traj, tmp_path / f"delta{suffix}", columns)
    found = read(path)
    assert found.actuators == columns and found.actuator_names == tuple(a.name for a in inputs.robot.actuators)
    back = found.trajectory
    assert back.name == traj.name and back.metadata == traj.metadata
    for key in KEYS:
        assert np.array_equal(getattr(back, key), getattr(traj, key)), key
    if suffix == ".csv":
        lines = path.read_text().splitlines()
        assert lines[0] == MAGIC_V2
        names = [n for n, _ in columns]
        header = lines[5].split(",")
        # t, the pose's coordinates and their rates, then each actuator with its unit and rates'
        pose = traj.X.shape[1]
        assert header[0] == "t[s]" and len(header) == 1 + 3 * pose + 9
        assert header[1 + 3 * pose:] == ([f"{n}[rad]" for n in names] + [f"{n}d[rad/s]" for n in names]
                                         + [f"{n}dd[rad/s^2]" for n in names])


def test_a_described_robot_streams_a_file_of_its_own_columns_as_it_streams_the_generated_one(tmp_path):
    """The 2R's validation excitation saved, then named as a ``file`` trajectory of a config
    extending the 2R's: planned at the SYNC rate and checked, it is the generated one."""
    inputs, traj = generated("sim-2r.yaml", "validation")
    save(traj, tmp_path / "validation.csv", inputs.columns)
    config = tmp_path / "file-2r.yaml"
    config.write_text(f"extends: {CONFIGS / 'sim-2r.yaml'}\n"
                      "trajectories:\n"
                      "  - {name: excitation, kind: joint_excitation, duration: 60.0, bandwidth: 1.5, seed: 1}\n"
                      "  - {name: validation, kind: file, path: validation.csv, cycles: 1}\n")
    (planned,) = [p for p in plan(load_config(config), names=["validation"])]
    assert planned.ok, planned.describe()
    # the planner resamples a file at the SYNC rate (the quintic Hermite through its samples): on
    # the file's own grid it gives the samples back, but for the rounding of the grid's times and
    # of the polynomial's evaluation (a few 1e-10 rad/s^2 on accelerations of order 1)
    assert len(planned.trajectory.t) == len(traj.t)
    for key in ("t", "Theta", "Thetad", "Thetadd"):
        np.testing.assert_allclose(getattr(planned.trajectory, key), getattr(traj, key), rtol=1e-8, atol=1e-9,
                                   err_msg=key)


def test_a_file_of_another_robot_s_columns_is_refused_naming_the_file_and_both_sets(tmp_path):
    _, delta_traj = generated("sim-delta.yaml", "verification")
    delta_file = save(delta_traj, tmp_path / "delta.csv", (("a1", "rad"), ("a2", "rad"), ("a3", "rad")))
    config = tmp_path / "file-2r.yaml"
    config.write_text(f"extends: {CONFIGS / 'sim-2r.yaml'}\n"
                      "trajectories:\n"
                      "  - {name: excitation, kind: joint_excitation, duration: 60.0, bandwidth: 1.5, seed: 1}\n"
                      "  - {name: validation, kind: file, path: delta.csv}\n")
    (planned,) = plan(load_config(config), names=["validation"])
    assert not planned.ok
    assert str(delta_file) in planned.error
    assert "a1[rad], a2[rad], a3[rad]" in planned.error and "shoulder[rad], elbow[rad]" in planned.error


def test_saving_refuses_columns_that_are_not_the_trajectory_s_actuators(tmp_path):
    _, traj = generated("sim-2r.yaml", "validation")
    with pytest.raises(ValueError, match=r"moves 2 actuators, the file's columns name 3 \(a, b, c\)"):
        save(traj, tmp_path / "x.csv", (("a", "rad"), ("b", "rad"), ("c", "m")))


def test_a_second_version_header_that_is_wrong_is_named_with_its_line(tmp_path):
    inputs, traj = generated("sim-2r.yaml", "validation")
    good = save(traj, tmp_path / "good.csv", inputs.columns).read_text().splitlines()
    cases = {
        "actuators": (good[:3] + ["# actuators: shoulder,elbow[rad]"] + good[4:], r"actuators: expected name\[unit\]"),
        "pose": (good[:4] + ["# pose: two"] + good[5:], r"pose: expected the number of pose coordinates"),
        "column": (good[:5] + [good[5].replace("elbowd[rad/s]", "elbowd[deg/s]")] + good[6:],
                   r"line 6: bad column header \(missing \['elbowd\[rad/s\]'\]"),
    }
    for name, (lines, message) in cases.items():
        path = tmp_path / f"{name}.csv"
        path.write_text("\n".join(lines) + "\n")
        with pytest.raises(TrajectoryFileError, match=message) as info:
            load(path)
        assert str(path) in str(info.value), name
