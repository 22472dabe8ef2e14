"""Faults, signals and bad input, tried as a user would (``ident-hw`` in a subprocess, the
in-process simulated rig with a short config): no traceback, no wrong answer, nothing lost.

Exit codes (README, "Exit codes"), written out by hand here: 2 config, 3 bus, 4 drive fault,
5 data, 6 degraded (quality verdict failed), 130 interrupted.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import yaml

from drivers.recording import Recording, sidecar_path
from ident_hw.config import load_config
from cli_runs import ident_hw

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"
SIM = CONFIGS / "sim-3prrr.yaml"
CYCLE = 266   # samples of one cycle of the short config's square (6 cm, speed_scale 0.6, 100 Hz)
LONG = 120    # cycles of the runs interrupted by a signal: 320 s of simulated time, 20 s of wall time in
              # lockstep, killed once a checkpoint exists (~1.5 s in). With 30 cycles (~5 s) the run
              # sometimes wrote no checkpoint before it ended (its first recording 'complete', all its
              # rows: the recorder thread, which checkpoints every 1 s, did not run meanwhile), and
              # start_run took the final recording for a checkpoint

CONFIG_ERROR, BUS_ERROR, DRIVE_FAULT, DATA_ERROR, DEGRADED, INTERRUPTED = 2, 3, 4, 5, 6, 130


def short_config(folder: Path, cycles: int = 1, extra: str = "", name: str = "short.yaml",
                 sync: str = "lockstep") -> Path:
    """One 6 cm square (2.6 s, 266 samples per cycle) at 100 Hz SYNC on the in-process rig
    (``sync``: ``periodic`` runs it in real time, as real drives)."""
    path = folder / name
    path.write_text(
        f"extends: {SIM}\n"
        f"bus: {{interface: virtual, channel: faults-{os.getpid()}-{time.monotonic_ns()}, sync_rate: 100.0, "
        f"sync: {sync}}}\n"
        f"trajectories:\n  - {{name: square, kind: square, size: 0.06, cycles: {cycles}, speed_scale: 0.6}}\n"
        "identification:\n"
        "  steps: [{name: links, trajectories: [square], parameters: [m_l2, m_ee, I_l1]}]\n"
        "  validation: []\n" + extra)
    return path


def hardware_config(folder: Path, identification: bool = True) -> Path:
    """A rig behind SocketCAN channel ``nosuchcan9`` (not a simulated bus: motion needs --arm)."""
    path = folder / "hw.yaml"
    text = (f"extends: {CONFIGS / 'robot-3prrr.yaml'}\n"
            "bus: {interface: socketcan, channel: nosuchcan9, sync_rate: 100.0}\n"
            "trajectories:\n  - {name: square, kind: square, size: 0.06, speed_scale: 0.6}\n")
    if identification:
        text += "identification:\n  steps: [{name: links, trajectories: [square], parameters: [m_l2]}]\n"
    path.write_text(text)
    return path


def no_traceback(out) -> None:
    assert "Traceback" not in out.stderr + out.stdout, out.stderr


def edited_config(run_folder: Path, target: Path, edit) -> Path:
    """The run's own config (``config.yaml`` of its results folder) with ``edit(doc)`` applied,
    written to ``target`` (naming the folder's copy of the description file where it is)."""
    doc = yaml.safe_load((run_folder / "config.yaml").read_text())
    doc["robot"]["description"] = str(run_folder / doc["robot"]["description"])
    edit(doc)
    target.write_text(yaml.safe_dump(doc, sort_keys=False))
    return target


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> Path:
    """The results folder of one complete short run on the simulated rig."""
    folder = tmp_path_factory.mktemp("recorded")
    out = ident_hw("run", short_config(folder), "--out", folder / "run", "--no-report", "--quiet", cwd=folder)
    assert out.returncode in (0, DEGRADED), out.stderr
    return folder / "run"


def start_run(config: Path, res: Path, trajectory: str = "square") -> subprocess.Popen:
    """``ident-hw run`` in a subprocess, returned once it has streamed ``trajectory`` for ~1.5 s."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "ident_hw.cli", "run", str(config), "--out", str(res), "--quiet"],
                            cwd=config.parent, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    path = res / "data" / f"{trajectory}.npz"
    while not path.exists():   # first checkpoint: streaming for ~1 s
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise AssertionError(proc.communicate())
        time.sleep(0.05)
    time.sleep(0.5)
    first = Recording.load(path)
    if first.metadata.status != "running (checkpoint)":     # the test's premise, not what it checks
        proc.kill()
        raise AssertionError(f"the run's first recording is {first.metadata.status!r} with {len(first.t)} rows: "
                             "no checkpoint came before it (a faster host, or the recorder thread not scheduled)")
    return proc


def rig_states(folder: Path) -> list[str]:
    return list(json.loads((folder / "data" / "drives.json").read_text())["rig"].values())


# ----------------------------------------------------------------------------- identify: recordings vs config
@pytest.mark.parametrize("key, factor", [("torque_constant", 1.5), ("screw_lead", 0.8)])
def test_identify_refuses_a_recording_made_with_another_drive_scaling(recorded, tmp_path, key, factor):
    def edit(doc):
        doc["robot"]["actuators"][3][key] *= factor
    config = edited_config(recorded, tmp_path / "other-scaling.yaml", edit)
    out = ident_hw("identify", config, recorded / "data" / "square.npz", "--out", tmp_path / "res", "--no-report",
                   cwd=tmp_path)
    no_traceback(out)
    assert out.returncode == DATA_ERROR, out.stderr
    assert "square.npz" in out.stderr and "other-scaling.yaml" in out.stderr
    assert key in out.stderr and "zeta1" in out.stderr
    assert not (tmp_path / "res").exists()


def test_identify_on_a_truncated_raw_log_says_how_much_was_used(recorded, tmp_path):
    text = (recorded / "data" / "square.log").read_bytes()
    cut = text[: int(0.4 * len(text))]          # 40 % of the bytes: ends inside a line
    (tmp_path / "square.log").write_bytes(cut)
    sidecar_path(tmp_path / "square.log").write_bytes(sidecar_path(recorded / "data" / "square.log").read_bytes())
    syncs = sum(1 for line in cut.decode().splitlines() if re.search(r"\s080#([0-9A-F]{2})?(\s+[RT])?\s*$", line))
    out = ident_hw("identify", recorded / "config.yaml", tmp_path / "square.log", "--out", tmp_path / "res",
                   "--no-report", cwd=tmp_path)
    no_traceback(out)
    used = re.search(r"square: (\d+) of (\d+) cycles", out.stdout + out.stderr)
    assert used, out.stdout + out.stderr
    assert int(used.group(2)) == CYCLE and abs(int(used.group(1)) - syncs) <= 1 and syncs < 0.6 * CYCLE
    assert out.returncode == DEGRADED
    status = (tmp_path / "res" / "STATUS").read_text()
    assert status.startswith("degraded") and "square" in status
    doc = json.loads((tmp_path / "res" / "parameters.json").read_text())
    assert doc["trajectories"]["square"]["cycles"] == int(used.group(1))
    assert doc["trajectories"]["square"]["cycles_planned"] == CYCLE
    assert doc["quality"]["passed"] is False


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04 truncated", "head"], ids=["empty", "zip-header", "first-3000-bytes"])
def test_identify_on_an_empty_or_truncated_npz_names_the_file(recorded, tmp_path, content):
    if content == "head":
        content = (recorded / "data" / "square.npz").read_bytes()[:3000]
    (tmp_path / "square.npz").write_bytes(content)
    out = ident_hw("identify", recorded / "config.yaml", tmp_path / "square.npz", "--out", tmp_path / "res",
                   "--no-report", cwd=tmp_path)
    no_traceback(out)
    assert out.returncode == DATA_ERROR
    assert "square.npz" in out.stderr
    assert not (tmp_path / "res").exists()


@pytest.mark.parametrize("file", ["square.npz", "square.log"])
def test_identify_with_other_node_ids_names_file_and_node(recorded, tmp_path, file):
    def edit(doc):
        for act in doc["robot"]["actuators"]:
            act["node_id"] += 10
    config = edited_config(recorded, tmp_path / "other-nodes.yaml", edit)
    out = ident_hw("identify", config, recorded / "data" / file, "--out", tmp_path / "res", "--no-report",
                   cwd=tmp_path)
    no_traceback(out)
    assert out.returncode == DATA_ERROR, out.stderr
    assert file in out.stderr and "node 11" in out.stderr and "theta1" in out.stderr
    assert not (tmp_path / "res").exists() or (tmp_path / "res" / "STATUS").read_text().strip() != "running"


# ----------------------------------------------------------------------------- signals during run
@pytest.fixture(scope="module")
def terminated(tmp_path_factory) -> tuple[Path, subprocess.CompletedProcess]:
    """A long run stopped by SIGTERM in the middle of its trajectory."""
    folder = tmp_path_factory.mktemp("terminated")
    res = folder / "run"
    proc = start_run(short_config(folder, cycles=LONG), res)
    try:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    return res, subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def check_interrupted_folder(res: Path, out, signame: str) -> Recording:
    """What a signal during ``run`` must leave: exit 130, motion stopped, drives disabled, the
    recording so far, STATUS partial with the reason."""
    no_traceback(out)
    assert out.returncode == INTERRUPTED, out.stderr
    assert f"interrupted ({signame})" in out.stderr
    status = (res / "STATUS").read_text()
    assert status.startswith(f"partial: interrupted ({signame})"), status
    assert set(rig_states(res)) == {"SWITCH ON DISABLED"}
    master = json.loads((res / "data" / "drives.json").read_text())["master"]
    assert set(master.values()) == {"SWITCH ON DISABLED"}
    rec = Recording.load(res / "data" / "square.npz")
    assert rec.metadata.status.startswith("stopped")
    assert 100 < len(rec.t) < LONG * CYCLE and np.isfinite(rec.position[rec.valid]).all()
    return rec


def test_sigterm_during_run_is_handled_like_ctrl_c(terminated):
    res, out = terminated
    check_interrupted_folder(res, out, "SIGTERM")


def test_sighup_during_run_is_handled_like_ctrl_c(tmp_path):
    res = tmp_path / "run"
    proc = start_run(short_config(tmp_path, cycles=LONG), res)
    try:
        proc.send_signal(signal.SIGHUP)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    check_interrupted_folder(res, subprocess.CompletedProcess(proc.args, proc.returncode, out, err), "SIGHUP")


def test_a_second_signal_during_shutdown_still_leaves_a_consistent_folder(tmp_path):
    res = tmp_path / "run"
    proc = start_run(short_config(tmp_path, cycles=LONG), res)
    try:
        proc.send_signal(signal.SIGTERM)
        for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGINT):
            time.sleep(0.1)
            if proc.poll() is None:
                proc.send_signal(sig)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    check_interrupted_folder(res, subprocess.CompletedProcess(proc.args, proc.returncode, out, err), "SIGTERM")


def test_identify_after_an_interrupted_run_reports_the_partial_recording(terminated, tmp_path):
    res, _ = terminated
    rec = Recording.load(res / "data" / "square.npz")
    out = ident_hw("identify", res / "config.yaml", res / "data" / "square.npz", "--out", tmp_path / "res",
                   "--no-report", cwd=tmp_path)
    no_traceback(out)
    text = out.stdout + out.stderr
    assert "partial" in text and "interrupted (SIGTERM)" in text
    assert f"square: {len(rec.t)} of {LONG * CYCLE} cycles" in text
    assert out.returncode == DEGRADED
    status = (tmp_path / "res" / "STATUS").read_text()
    assert status.startswith("degraded") and "square" in status
    doc = json.loads((tmp_path / "res" / "parameters.json").read_text())
    assert doc["trajectories"]["square"]["recording_status"].startswith("stopped")
    # --no-report: the results without plots or report.html (`ident-hw report` builds them later)
    assert not (tmp_path / "res" / "report.html").exists() and "report:" not in out.stdout


def test_identify_recognises_the_checkpoint_of_a_killed_run(tmp_path):
    res = tmp_path / "run"
    proc = start_run(short_config(tmp_path, cycles=LONG), res)
    proc.kill()                     # SIGKILL: nothing can be done; the checkpoint is what is left
    proc.communicate(timeout=60)
    rec = Recording.load(res / "data" / "square.npz")
    assert rec.metadata.status == "running (checkpoint)"
    out = ident_hw("identify", res / "config.yaml", res / "data" / "square.npz", "--out", tmp_path / "res",
                   "--no-report", cwd=tmp_path)
    no_traceback(out)
    assert "checkpoint" in out.stdout + out.stderr
    assert f"square: {len(rec.t)} of {LONG * CYCLE} cycles" in out.stdout + out.stderr
    assert out.returncode == DEGRADED


# ----------------------------------------------------------------------------- configs and buses
def test_a_config_without_identification_is_refused_by_check_and_by_run(tmp_path):
    config = short_config(tmp_path)
    base = tmp_path / "no-ident.yaml"
    base.write_text(f"extends: {CONFIGS / 'robot-3prrr.yaml'}\n"
                    + "\n".join(line for line in config.read_text().splitlines()[1:]
                                if not line.startswith(("identification", "  steps", "  validation")))
                    + "\nsim:\n  truth: {m_c: 600, m_l1: 0.3, I_l1: 0.002, m_l2: 0.5, I_l2: 0.004, m_ee: 0.2, "
                      "I_ee: 0.002}\n")
    assert load_config(base).identification is None and load_config(base).simulated
    check = ident_hw("check", base, cwd=tmp_path)
    no_traceback(check)
    assert check.returncode == CONFIG_ERROR and "identification" in check.stdout + check.stderr
    assert "everything would run" not in check.stdout
    started = time.monotonic()
    run = ident_hw("run", base, "--out", tmp_path / "res", "--no-report", cwd=tmp_path)
    no_traceback(run)
    assert run.returncode == CONFIG_ERROR and "identification" in run.stderr and "nothing moved" in run.stderr
    assert time.monotonic() - started < 20 and not (tmp_path / "res").exists()


@pytest.mark.parametrize("content", [b"robot:\n  geometry: \x00\n", bytes(range(256)) * 8], ids=["nul", "binary"])
def test_a_yaml_file_with_nul_bytes_or_binary_content_is_a_config_error(tmp_path, content):
    (tmp_path / "bad.yaml").write_bytes(content)
    for command in ("check", "run"):
        out = ident_hw(command, tmp_path / "bad.yaml", cwd=tmp_path)
        no_traceback(out)
        assert out.returncode == CONFIG_ERROR and "bad.yaml" in out.stderr, out.stderr


def test_check_refuses_an_interface_python_can_does_not_have(tmp_path):
    config = short_config(tmp_path)
    config.write_text(config.read_text().replace("interface: virtual", "interface: virtul"))
    out = ident_hw("check", config, cwd=tmp_path)
    no_traceback(out)
    assert out.returncode == CONFIG_ERROR
    assert "bus.interface" in out.stderr and "'virtul'" in out.stderr and "did you mean 'virtual'" in out.stderr


def test_a_bus_that_cannot_open_is_named_and_leaves_no_results_folder(tmp_path):
    config = hardware_config(tmp_path)
    out = ident_hw("run", config, "--arm", "--out", tmp_path / "res", "--no-report", cwd=tmp_path)
    no_traceback(out)
    assert out.returncode == BUS_ERROR, out.stderr
    assert "socketcan" in out.stderr and "nosuchcan9" in out.stderr
    # what the kernel's error number means, in words: no SocketCAN at all (this host), or no such interface
    assert ("this kernel has no SocketCAN" in out.stderr or "no network interface 'nosuchcan9'" in out.stderr), out.stderr
    assert not (tmp_path / "res").exists()


def test_the_simulated_rig_on_a_missing_vcan_names_the_bus(tmp_path):
    config = short_config(tmp_path)
    config.write_text(re.sub(r"bus: \{interface: virtual, channel: [^,]+,", "bus: {interface: socketcan, channel: vcan9,",
                             config.read_text()))
    if Path("/sys/class/net/vcan9").exists():
        pytest.skip("this host has a vcan9")
    out = ident_hw("run", config, "--out", tmp_path / "res", "--no-report", cwd=tmp_path)
    no_traceback(out)
    assert out.returncode == BUS_ERROR, out.stderr
    assert "socketcan" in out.stderr and "vcan9" in out.stderr
    assert not (tmp_path / "res").exists()


# ----------------------------------------------------------------------------- what is claimed after a stop
def test_a_silent_node_is_reported_as_state_unknown_not_as_disabled(tmp_path, monkeypatch):
    """Node 5 falls silent in the middle of the stream (the rig's own fault injection, reached
    through the session the runner opens): the run stops on its heartbeat, and neither STATUS,
    drives.json nor the stop message claim it was disabled."""
    from ident_hw.experiment import runner
    from ident_hw.experiment.session import HostSettings
    from ident_hw.experiment.folders import new_results_folder
    config = load_config(short_config(tmp_path, cycles=3))
    folder = new_results_folder(config, tmp_path / "res", "run")
    real = runner.open_session

    @contextmanager
    def silencing(cfg):
        with real(cfg) as session:
            def silence_when_streaming():
                rig = session.rig
                while not all(d.streaming for d in rig.drives):
                    time.sleep(0.002)
                start = rig.sync_count
                while rig.sync_count < start + 100:      # 1 s into the square
                    time.sleep(0.002)
                rig.silence(5)
            threading.Thread(target=silence_when_streaming, daemon=True).start()
            yield session
    monkeypatch.setattr(runner, "open_session", silencing)
    with pytest.raises(runner.CampaignStopped) as stopped:
        runner.run_campaign(config, folder,
                                host=HostSettings.for_command(config))
    message = stopped.value.stop_message()
    assert "node 5 (zeta2)" in message and "state unknown" in message
    disabled = re.search(r"disabled: ([^;]*)", message)
    assert disabled and "node 5" not in disabled.group(1) and "node 4 (zeta1)" in disabled.group(1)
    status = (folder / "STATUS").read_text()
    assert status.startswith("partial: drive fault: node 5 (zeta2)") and "state unknown: node 5 (zeta2)" in status
    master = json.loads((folder / "data" / "drives.json").read_text())["master"]
    assert master["node 5 (zeta2)"].startswith("unknown")
    assert master["node 4 (zeta1)"] == "SWITCH ON DISABLED"


def test_dropped_pdo_frames_end_the_run_degraded_not_complete(tmp_path, monkeypatch):
    """5 % of the drives' PDO frames lost (the rig's own fault injection, reached through the
    session the runner opens) with a periodic SYNC, as on a real bus (lockstep would ask the
    cycle again): about half the cycles come incomplete; the run ends ``degraded`` with that
    reason, never ``complete``."""
    from ident_hw.experiment import runner
    from ident_hw.experiment.session import HostSettings
    from ident_hw.experiment.folders import new_results_folder
    config = load_config(short_config(tmp_path, sync="periodic"))
    folder = new_results_folder(config, tmp_path / "res", "run")
    real = runner.open_session

    @contextmanager
    def lossy(cfg):
        with real(cfg) as session:
            session.rig.frame_faults(drop_probability=0.05)
            yield session
    monkeypatch.setattr(runner, "open_session", lossy)
    results = runner.run_campaign(config, folder,
                                host=HostSettings.for_command(config))
    rec = Recording.load(folder / "data" / "square.npz")
    # complete cycles over the SYNC slots: a slot the SYNC thread skipped (counted by the
    # producer) counts as an incomplete cycle
    slots = len(rec.t) + (rec.metadata.sync_report.sync_slots_skipped or 0)
    complete = float(rec.valid.all(axis=1).sum()) / slots
    assert complete < 0.9          # 1 - 0.95^(6 drives x 2-3 PDOs) of the cycles lose a frame
    status = (folder / "STATUS").read_text()
    assert results.quality.passed is False
    doc = json.loads((folder / "parameters.json").read_text())
    reported = doc["quality"]["trajectories"]["square"]["valid_fraction"]
    assert status.startswith("degraded") and f"square: {100 * reported:.1f} % of the cycles complete" in status
    # the verdict places each row in its SYNC slot by its time stamp; on a loaded host a late SYNC
    # can count as a skipped slot there and not in the producer's count: the two agree within 1 %
    assert reported == pytest.approx(complete, abs=0.01)
    assert "Quality verdict: DEGRADED" in (folder / "report.html").read_text()
