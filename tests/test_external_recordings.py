"""Recordings the tool did not make (issue 46): CSV files read by a config's ``recordings``
section into the tool's own recordings, on the planar 2R arm's description file.

The files are written here from known motions (a sum of sines, its rates by hand), with the
time stamps, units, header and bad rows a lab's files have; what the reader gives back is held to
those motions, computed independently of it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from drivers.errors import RecordingError
from ident_hw.config import ConfigError, load_config
from ident_hw.experiment.external import read_external
from ident_hw.experiment.recordings import gather_recordings
from ident_hw.segments import slot_indices

ROBOTS = Path(__file__).resolve().parent.parent / "configs" / "robots"
#: N m / A of the two actuators (torque_constant x gear_ratio below)
PER_AMP = (1.2, 0.6)


def config_text(recordings: str, trajectory: str = "{name: run, kind: recorded, path: run.csv}") -> str:
    """A config of the 2R arm that only identifies recordings made elsewhere (no bus)."""
    return f"""
robot:
  kind: described
  description: {ROBOTS / '2r.urdf'}
  described: {{home: {{joint1: 0.0, joint2: 1.2}}, end_effector: tool}}
  actuators:
    - {{name: shoulder, joint: joint1, kind: revolute, torque_constant: 1.2, counts_per_turn: 1048576,
       limits: {{position: [-2.0, 2.0], velocity: 3.0, acceleration: 20.0, current: 15.0, following_error: 0.05}}}}
    - {{name: elbow, joint: joint2, kind: revolute, torque_constant: 0.6, counts_per_turn: 1048576,
       limits: {{position: [-0.8, 3.0], velocity: 4.0, acceleration: 30.0, current: 10.0, following_error: 0.05}}}}
recordings:
{recordings}
trajectories:
  - {trajectory}
identification:
  steps: [{{name: base, trajectories: [run], parameters: [all], method: wls}}]
"""


PLAIN = """  columns: {time: 1, position: [2, 3], velocity: [4, 5], current: [6, 7]}"""


def motion(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 2) rad and rates (N, 2) rad/s of a smooth motion, by hand."""
    q = np.column_stack([0.5 * np.sin(1.3 * t), 1.2 + 0.4 * np.sin(2.1 * t + 0.3)])
    qd = np.column_stack([0.65 * np.cos(1.3 * t), 0.84 * np.cos(2.1 * t + 0.3)])
    return q, qd


def currents(t: np.ndarray) -> np.ndarray:
    return np.column_stack([0.8 * np.cos(0.9 * t), -0.3 + 0.2 * np.sin(1.7 * t)])


def uneven_times(n: int, seed: int = 0) -> np.ndarray:
    """A controller's stamps: 10 ms steps, a third of them 12 ms, from 1017.78 s."""
    steps = np.where(np.random.default_rng(seed).random(n - 1) < 1 / 3, 0.012, 0.010)
    return 1017.78 + np.concatenate([[0.0], np.cumsum(steps)])


def rows_of(t: np.ndarray) -> list[str]:
    q, qd = motion(t - t[0])
    i = currents(t - t[0])
    return [",".join(f"{v:.6f}" for v in (tk, *qk, *qdk, *ik)) for tk, qk, qdk, ik in zip(t, q, qd, i)]


def write(tmp_path: Path, data: list[str], recordings: str = PLAIN, header: list[str] = (), **trajectory) -> Path:
    (tmp_path / "run.csv").write_text("\n".join([*header, *data]) + "\n")
    spec = "{name: run, kind: recorded, path: run.csv" + "".join(f", {k}: {v}" for k, v in trajectory.items()) + "}"
    path = tmp_path / "config.yaml"
    path.write_text(config_text(recordings, spec))
    return path


def read(path: Path):
    config = load_config(path)
    return read_external(config, config.trajectory("run"))


def test_a_recorded_path_is_relative_to_its_config_named_by_a_relative_path(tmp_path, monkeypatch):
    folder = tmp_path / "lab"
    folder.mkdir()
    config = write(folder, rows_of(uneven_times(300)))
    monkeypatch.chdir(tmp_path)
    relative = load_config(Path("lab") / config.name)          # the config named from its parent folder
    external = read_external(relative, relative.trajectory("run"))
    assert external.summary.data_rows == 300
    assert Path(relative.trajectory("run").path) == Path("lab") / "run.csv"


def test_uneven_stamps_are_resampled_onto_an_even_step_with_the_motion_kept(tmp_path):
    t = uneven_times(1500)
    external = read(write(tmp_path, rows_of(t)))
    rec, summary = external.recording, external.summary
    steps = np.diff(t)
    assert summary.period_s == pytest.approx(np.mean(steps), rel=1e-9)
    assert summary.step_min_s == pytest.approx(0.010) and summary.step_max_s == pytest.approx(0.012)
    assert np.allclose(np.diff(rec.t), summary.period_s, rtol=0, atol=1e-9)     # even rows, nothing else
    # the rows hold the motion at their own times (the file's rows are rounded to 1e-6)
    q, qd = motion(rec.t)
    assert np.max(np.abs(rec.position - q)) < 5e-6
    assert np.max(np.abs(rec.velocity - qd)) < 5e-4         # linear between 10 ms samples
    assert np.max(np.abs(rec.current - currents(rec.t))) < 5e-4
    assert summary.velocity == "recorded" and summary.force == "current" and summary.cut == ()


def test_units_scales_header_names_and_torque_columns(tmp_path):
    """A file in ms, degrees and N m, columns named by its header, the elbow's sign reversed."""
    t = 0.01 * np.arange(800)
    q, qd = motion(t)
    torque = currents(t) * PER_AMP
    rows = [f"{1e3 * tk:.3f};{math.degrees(a):.6f};{-math.degrees(b):.6f};{ta:.6f};{tb:.6f}"
            for tk, (a, b), (ta, tb) in zip(t, q, torque)]
    spec = """  delimiter: ";"
  header: 2
  columns: {time: stamp, position: [q1, q2], torque: [tau1, tau2]}
  units: {time: ms, position: deg, torque: N m}
  scale: {position: [1.0, -1.0]}"""
    external = read(write(tmp_path, rows, spec, header=["# logged by a lab's own controller", "stamp;q1;q2;tau1;tau2"]))
    rec = external.recording
    assert np.allclose(rec.position, motion(rec.t)[0], atol=1e-7)
    assert np.allclose(rec.current, currents(rec.t), atol=1e-5)        # torque back to amperes
    assert external.summary.velocity == "differentiated" and np.isnan(rec.velocity).all()
    assert external.summary.force == "torque"


def test_a_column_the_header_does_not_name_is_an_error_naming_the_file(tmp_path):
    spec = """  header: 1
  columns: {time: t, position: [q1, q9], current: [i1, i2]}"""
    path = write(tmp_path, rows_of(uneven_times(100)), spec, header=["t,q1,q2,qd1,qd2,i1,i2"])
    with pytest.raises(RecordingError, match=r"run\.csv.*position\[1\].*no column named 'q9'"):
        read(path)


# ----------------------------------------------------------------------------- rows that are not data
def corrupted(tmp_path: Path, line: int, text: str, bad_rows: str = "cut"):
    rows = rows_of(uneven_times(600))
    rows[line - 1] = text
    return write(tmp_path, rows, PLAIN + f"\n  bad_rows: {bad_rows}")


def cut_of(external, reason: str):
    found = [c for c in external.summary.cut if c.reason == reason]
    assert len(found) == 1, external.summary.cut
    return found[0]


def test_a_row_with_the_wrong_number_of_fields_is_cut_naming_its_line(tmp_path):
    external = read(corrupted(tmp_path, 300, "1020.7,0.1,0.2"))
    cut = cut_of(external, "fields")
    assert (cut.count, cut.lines) == (1, (300,))
    assert external.summary.rows_used == 599
    assert "line 300" in " ".join(external.summary.describe())


def test_a_field_that_is_no_number_is_cut_naming_its_line(tmp_path):
    rows = rows_of(uneven_times(600))
    rows[99] = rows[99].replace(rows[99].split(",")[2], "abc", 1)
    rows[199] = rows[199].replace(rows[199].split(",")[6], "nan", 1)
    external = read(write(tmp_path, rows))
    assert cut_of(external, "number").lines == (100, 200)


def test_a_value_beyond_reach_is_cut_naming_its_line(tmp_path):
    rows = rows_of(uneven_times(600))
    fields = rows[49].split(",")
    fields[1] = "253.0"                          # rad: beyond the shoulder's [-2, 2] by far more than its range
    rows[49] = ",".join(fields)
    fields = rows[59].split(",")
    fields[6] = "71.0"                           # A: the elbow's limit is 10 A
    rows[59] = ",".join(fields)
    external = read(write(tmp_path, rows))
    assert cut_of(external, "absurd").lines == (50, 60)


def test_time_going_back_is_cut_and_a_lone_stamp_ahead_is_the_one_out_of_order(tmp_path):
    t = uneven_times(600)
    rows = rows_of(t)
    back, ahead = rows[250].split(","), rows[400].split(",")
    back[0] = f"{t[100]:.6f}"                    # a stamp from the past
    ahead[0] = f"{t[400] + 50.0:.6f}"            # a stamp far ahead, its successors in order
    rows[250], rows[400] = ",".join(back), ",".join(ahead)
    external = read(write(tmp_path, rows))
    assert cut_of(external, "time_back").lines == (251, 401)
    # each leaves one step of two: bridged, below recordings.gap (2.5 median steps)
    assert external.summary.gaps == 0 and external.summary.step_max_s == pytest.approx(0.022, abs=0.0021)
    assert external.summary.rows_used == 598


def test_with_bad_rows_error_the_first_row_that_is_not_data_stops_the_reading(tmp_path):
    with pytest.raises(RecordingError, match=r"run\.csv, line 300: not data: 3 fields"):
        read(corrupted(tmp_path, 300, "1020.7,0.1,0.2", bad_rows="error"))


# ----------------------------------------------------------------------------- windows, idle ends, gaps
def test_a_window_of_rows_or_of_time_picks_that_part(tmp_path):
    t = uneven_times(1000)
    rows = rows_of(t)
    by_rows = read(write(tmp_path, rows, rows="[201, 700]"))
    assert by_rows.summary.window == "rows 201..700" and by_rows.summary.rows_used == 500
    assert by_rows.recording.metadata.t0 == pytest.approx(t[200])
    by_time = read(write(tmp_path, rows, window=f"[{t[300]:.6f}, {t[600]:.6f}]"))
    assert by_time.summary.rows_used == 301 and by_time.recording.metadata.t0 == pytest.approx(t[300])


def test_an_idle_head_and_tail_are_found_and_left_out(tmp_path):
    """3 s at rest, 8 s of motion, 2 s at rest: the rows kept start and end half a second into the rest."""
    t = 0.01 * np.arange(1300)
    active = np.clip(t - 3.0, 0.0, 8.0)
    q = np.column_stack([0.3 * (1 - np.cos(2 * np.pi * active / 8.0)), 1.2 + 0.2 * np.sin(np.pi * active / 8.0) ** 2])
    rows = [",".join(f"{v:.6f}" for v in (tk, *qk, 0.0, 0.0, 0.1, 0.1)) for tk, qk in zip(t, q)]
    summary = read(write(tmp_path, rows)).summary
    tolerance = 1e-3 * np.array([4.0, 3.8])      # of the position ranges
    moved = np.flatnonzero((np.abs(q - q[0]) > tolerance).any(axis=1))
    assert summary.idle_head_s == pytest.approx(t[moved[0]] - 0.5, abs=0.011)
    settled = np.flatnonzero((np.abs(q - q[-1]) > tolerance).any(axis=1))
    assert summary.idle_tail_s == pytest.approx(t[-1] - t[settled[-1]] - 0.5, abs=0.011)
    assert "idle head" in " ".join(summary.describe())


def test_a_gap_cuts_the_recording_and_nothing_is_interpolated_across_it(tmp_path):
    t = uneven_times(900)
    rows = rows_of(t)
    del rows[400:410]                            # 10 rows lost: about 0.1 s
    external = read(write(tmp_path, rows))
    rec = external.recording
    assert external.summary.gaps == 1
    slots = slot_indices(rec.t, external.summary.period_s)
    assert int(np.sum(np.diff(slots) > 1)) == 1
    before, after = t[399] - t[0], t[410] - t[0]
    assert not np.any((rec.t > before + 1e-9) & (rec.t < after - 1e-9))   # no row inside the gap


# ----------------------------------------------------------------------------- on the command line
def test_name_equals_path_takes_the_place_of_the_configs_trajectory(tmp_path):
    config_path = write(tmp_path, rows_of(uneven_times(500)), rows="[1, 100]")
    other = tmp_path / "other.csv"
    other.write_text("\n".join(rows_of(uneven_times(700, seed=3))) + "\n")
    config = load_config(config_path)
    gathered = gather_recordings(config, [f"run={other}"])
    recordings, imported = gathered.recordings, gathered.imported
    assert imported["run"].window is None                    # taken whole: the window is the config file's
    assert imported["run"].rows_used == 700 and recordings["run"].metadata.file == str(other)
    gathered = gather_recordings(config, [])
    recordings, imported = gathered.recordings, gathered.imported
    assert imported["run"].window == "rows 1..100"
    with pytest.raises(RecordingError, match="no trajectory 'walk'"):
        gather_recordings(config, [f"walk={other}"])
    with pytest.raises(RecordingError, match="give it as NAME="):
        gather_recordings(config, [str(other)])


def test_an_unset_dataset_variable_is_a_config_error_naming_key_and_variable(tmp_path, monkeypatch):
    monkeypatch.delenv("IDENT_HW_LAB_DATA", raising=False)
    path = write(tmp_path, rows_of(uneven_times(100)))
    path.write_text(path.read_text().replace("path: run.csv", "path: \"${IDENT_HW_LAB_DATA}/run.csv\""))
    with pytest.raises(ConfigError, match=r"trajectories\[0\]\.path.*IDENT_HW_LAB_DATA is not set"):
        load_config(path)
    monkeypatch.setenv("IDENT_HW_LAB_DATA", str(tmp_path))
    config = load_config(path)
    assert Path(config.trajectory("run").path) == tmp_path / "run.csv"


def test_a_config_of_recordings_made_elsewhere_does_not_run(tmp_path):
    from ident_hw.experiment.plan import check_campaign
    problems = check_campaign(load_config(write(tmp_path, rows_of(uneven_times(100)))))
    assert any("recordings made elsewhere" in p and "ident-hw identify" in p for p in problems)
