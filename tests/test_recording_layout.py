"""A recording carries what decoding needs (issue 50): a raw CAN log is decoded with the PDO layout
stored beside it, or one given on the command line, never with one assumed; which current it holds
(instantaneous or averaged) and the running average behind it are the recording's own, and a config
that says otherwise is an error.

One short campaign streams the drives' averaged currents (the carriage sweep at 100 Hz, lockstep):
its decoded recording, its raw log and the log's sidecar are what the tests read."""

import dataclasses
import os
import shutil
import time
from pathlib import Path

import pytest

from cli_runs import ident_hw
from drivers.acquisition import master_layouts
from drivers.errors import RecordingError
from drivers.profiles import EPOS4, AveragingFilter
from drivers.recording import Recording, decode_log, sidecar_path
from ident_hw.config import load_config
from ident_hw.config.to_drivers import axis_config
from ident_hw.experiment.inputs import Axes
from ident_hw.experiment.preparation import current_averaging
from ident_hw.experiment.recordings import RecordingChecks, load_recording

CONFIGS = Path(__file__).resolve().parent.parent / "configs"


def _sweep(folder: Path, current: str) -> Path:
    path = folder / f"sweep-{current}.yaml"
    path.write_text(
        f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n"
        f"bus: {{channel: layout-{os.getpid()}-{time.monotonic_ns()}, sync_rate: 100.0, current: {current}}}\n"
        "trajectories: [{name: sweep, kind: carriage_sweep, size: 0.03}]\n"
        "identification:\n"
        "  steps: [{name: carriages, trajectories: [sweep], parameters: [m_c, fv_zeta1, fv_zeta2, fv_zeta3,\n"
        "                                                                 fc_zeta1, fc_zeta2, fc_zeta3]}]\n"
        "  validation: []\n"
        "  encoder_draws: 0\n")
    return path


@pytest.fixture(scope="module")
def averaged_run(tmp_path_factory):
    """A run streaming the averaged current: its folder and the configs saying each current."""
    folder = tmp_path_factory.mktemp("layout")
    configs = {current: _sweep(folder, current) for current in ("instantaneous", "averaged")}
    out = ident_hw("run", configs["averaged"], "--out", folder / "run", "--quiet", "--no-report", cwd=folder)
    assert out.returncode in (0, 6), out.stderr
    return folder / "run", configs


def test_a_raw_log_without_its_layout_is_refused_with_how_to_give_it(averaged_run, tmp_path):
    run, configs = averaged_run
    log = tmp_path / "sweep.log"
    shutil.copy(run / "data" / "sweep.log", log)           # copied without its sidecar
    out = ident_hw("identify", configs["averaged"], log, "--out", tmp_path / "res", "--quiet", "--no-report")
    assert out.returncode == 5, out.stderr                  # a data error; nothing made
    assert "no sweep.log.json beside it with the PDO layout it was recorded with" in out.stderr
    assert "--pdo-layout config" in out.stderr and "--pdo-layout <run>.log.json" in out.stderr
    assert not (tmp_path / "res").exists()
    for source in (sidecar_path(run / "data" / "sweep.log"), run / "data" / "sweep.npz", "config"):
        out = ident_hw("identify", configs["averaged"], log, "--pdo-layout", source, "--out", tmp_path / f"res-{id(source)}",
                       "--quiet", "--no-report")
        assert out.returncode in (0, 6), out.stderr
    config = load_config(configs["averaged"])
    _, rec = load_recording(log, RecordingChecks.of(config), layout=sidecar_path(run / "data" / "sweep.log"))
    assert rec.metadata.pdo_layout_source == f"given: that of {sidecar_path(run / 'data' / 'sweep.log')}"
    assert rec.metadata.current == "averaged" and {a.current for a in rec.metadata.axes} == {"averaged"}
    recorded = Recording.load(run / "data" / "sweep.npz")
    assert (rec.current[rec.current_valid] == recorded.current[recorded.current_valid]).all()


def test_a_log_of_another_drive_generation_is_refused_whatever_layout_is_given(averaged_run, tmp_path):
    """The run's EPOS4 log, without its sidecar, read as one of EPOS2 drives (the layout given by
    the caller): its TPDO2 frames have another length than an EPOS2's, so it is refused instead of
    decoding to currents of kiloamperes marked valid."""
    run, configs = averaged_run
    config = load_config(configs["averaged"])
    epos2 = [dataclasses.replace(axis_config(a, current="averaged"), profile="epos2") for a in config.robot.actuators]
    log = tmp_path / "sweep.log"
    shutil.copy(run / "data" / "sweep.log", log)
    with pytest.raises(RecordingError, match=r"recorded with another PDO layout than its decoding's \(given: EPOS2\): "
                                             r"node 1's TPDO2 \(COB-ID 0x281\): \d+ frames of 6 bytes, the layout says 4"):
        decode_log(log, epos2, layouts=master_layouts(epos2), layout_source="EPOS2", max_cycles=100)


def test_the_current_and_its_filter_come_from_the_recording_and_a_config_that_disagrees_is_an_error(averaged_run):
    run, configs = averaged_run
    instantaneous = load_config(configs["instantaneous"])
    for data in (run / "data" / "sweep.npz", run / "data" / "sweep.log"):
        with pytest.raises(RecordingError, match=rf"{data.name} holds the averaged current of theta1 \(node 1\), .*"
                                                 r"says bus.current: instantaneous"):
            load_recording(data, RecordingChecks.of(instantaneous))
    averaged = load_config(configs["averaged"])
    _, rec = load_recording(run / "data" / "sweep.npz", RecordingChecks.of(averaged))
    assert [a.current_filter for a in rec.metadata.axes] == [EPOS4.current_averaging] * 6
    assert current_averaging(Axes.of(averaged.robot.actuators), rec) == (EPOS4.current_averaging,) * 6
    # a drive whose average is another filter: the identification takes the recording's
    other = AveragingFilter(40.0, 20_000.0)
    rec = dataclasses.replace(rec, metadata=dataclasses.replace(
        rec.metadata, axes=tuple(dataclasses.replace(a, current_filter=other) for a in rec.metadata.axes)))
    assert current_averaging(Axes.of(averaged.robot.actuators), rec) == (other,) * 6
    _, decoded = load_recording(run / "data" / "sweep.log", RecordingChecks.of(averaged))
    assert [a.current_filter for a in decoded.metadata.axes] == [EPOS4.current_averaging] * 6   # from the sidecar
