"""The lab's HIL configs against drives in another process, with the master's process disturbed
(issue 50): the emulated drives served by ``ident-hw sim`` on ``udp_multicast`` with a periodic
SYNC (real time, as on a real bus), the master's SYNC, set-points and heartbeat from its timing
process (``bus.timing: auto``).

* Beside a busy loop on each CPU the test runs on, with the master's whole process held 1 s at a time by a
  GIL-holding call (``held_master.py``): no drive faults, every trajectory streams to its end,
  at most 5 % of the SYNC slots skipped, and the recordings say how long the master was held.
  (One square per config here; the whole campaigns are ``benchmarks/bench_hil_timing.py``.)
* The master's process stopped (SIGSTOP): shorter than ``bus.watchdogs.master_progress``, nothing
  happens; longer, every drive faults within that limit plus its consumer time of the master's
  heartbeat, and the run, continued, stops with the recording kept.
"""

import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
import yaml

from processes import stop_process, wait_for_line
from udp_groups import interface_local_group, loopback_multicast_works

pytest.importorskip("msgpack", reason="python-can's udp_multicast interface needs msgpack (pip install -e '.[test]')")

ROOT = Path(__file__).resolve().parent.parent
HELD_MASTER = Path(__file__).resolve().parent / "held_master.py"
RUN_TIMEOUT = 300.0   # s, bounds a hang
IDENT_HW = [sys.executable, "-m", "ident_hw.cli"]


def hil_on_udp(tmp_path: Path, hil: str, **bus) -> Path:
    """The lab's config ``hil`` with its bus swapped for a fresh interface-local udp_multicast group,
    a periodic SYNC (as on a real bus), the main job's simulated truth served from another process,
    one square of the campaign (a fifth of the links' identification) and no encoder draws."""
    group = interface_local_group()
    if not loopback_multicast_works(group):
        pytest.skip(f"this host does not loop IPv6 multicast back to its own sockets ({group})")
    sim = yaml.safe_load((ROOT / "configs" / "sim-3prrr.yaml").read_text())["sim"]
    sim["in_process"] = False
    path = tmp_path / f"udp-{hil}"
    path.write_text(yaml.safe_dump({
        "extends": str(ROOT / "configs" / hil),
        "bus": {"interface": "udp_multicast", "channel": group, "sync": "periodic", "bring_up_timeout": 30.0, **bus},
        "sim": sim,
        "trajectories": [{"name": "square1", "kind": "square", "size": 0.12, "rotation_deg": 0, "speed_scale": 0.5,
                          "dwell": 0.5}],
        "identification": {"encoder_draws": 0, "validation": [], "steps": [
            {"name": "links", "trajectories": ["square1"],
             "parameters": ["fv_theta1", "fv_theta2", "fv_theta3", "fc_theta1", "fc_theta2", "fc_theta3"]}]},
    }, sort_keys=False))
    return path


@contextmanager
def busy_loops():
    """A busy loop pinned to each CPU this test runs on (under pytest-xdist its worker's one: the
    other worker's tests keep theirs)."""
    procs = [subprocess.Popen([sys.executable, "-c", f"import os\nos.sched_setaffinity(0, {{{cpu}}})\nwhile True: pass"])
             for cpu in sorted(os.sched_getaffinity(0))]
    try:
        yield
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()


@contextmanager
def rig_process(config: Path):
    """``ident-hw sim`` of ``config``, once it serves the bus, its threads on the last CPU this test
    runs on, at real-time priority where this test may give it: real drives answer a SYNC within
    microseconds and take no CPU of the master's PC; an emulation starved by the busy loops would
    send its frames late, one at real-time priority on the master's CPUs could starve the master,
    and neither is what is tested here."""
    proc = subprocess.Popen([*IDENT_HW, "sim", config], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for_line(proc, "simulated rig:", 600.0)
        cpus = sorted(os.sched_getaffinity(0))
        for task in Path(f"/proc/{proc.pid}/task").glob("*"):
            try:
                if len(cpus) > 1:          # a CPU of their own: a real-time rig must not starve the master
                    os.sched_setaffinity(int(task.name), {cpus[-1]})
                os.sched_setscheduler(int(task.name), os.SCHED_FIFO, os.sched_param(10))
            except (OSError, AttributeError):
                break
        yield proc
    finally:
        stop_process(proc)


@pytest.mark.slow
@pytest.mark.parametrize("hil", ["hil-3prrr-epos2.yaml", "hil-3prrr-epos4.yaml"])
def test_a_hil_campaign_streams_to_its_end_beside_busy_loops_with_its_master_held_1_s_at_a_time(tmp_path, hil):
    from drivers.recording import Recording
    config = hil_on_udp(tmp_path, hil)
    with rig_process(config), busy_loops():
        run = subprocess.run([sys.executable, HELD_MASTER, "run", config, "--out", tmp_path / "run", "--no-report"],
                             capture_output=True, text=True, timeout=RUN_TIMEOUT,
                             env=dict(os.environ, HOLD_EVERY="3", HOLD="1"))
    print(run.stdout[-3000:], run.stderr[-3000:])
    holds = [float(line.split()[1]) for line in run.stderr.splitlines() if line.startswith("held ")]
    status = (tmp_path / "run" / "STATUS").read_text()
    assert run.returncode in (0, 6) and not status.startswith("partial"), status     # 6: the quality verdict
    assert len(holds) >= 3 and min(holds) >= 0.99
    rec = Recording.load(tmp_path / "run" / "data" / "square1.npz")
    meta, sync = rec.metadata, rec.metadata.sync_report
    assert meta.status == "complete" and meta.n_cycles == meta.n_targets
    assert "timing process" in sync.timing and sync.timers_stopped_after is None
    assert sync.sync_slots_skipped <= 0.05 * meta.n_cycles
    assert sync.master_longest_stall >= 0.99          # held during the stream, and survived
    assert sync.relay_dropped == 0 and meta.buffer_overflows == 0
    drives = (tmp_path / "run" / "data" / "drives.json").read_text()
    assert "FAULT" not in drives, drives


@pytest.mark.slow
def test_a_master_stopped_longer_than_its_limit_faults_the_drives_within_the_limit_and_their_consumer_time(tmp_path):
    from ident_hw.config import load_config
    from ident_hw.experiment.session import simulated_rig
    limit, consumer = 1.0, 0.35
    path = hil_on_udp(tmp_path, "hil-3prrr-epos4.yaml", watchdogs={"master_progress": limit})
    config = load_config(path)
    rig = simulated_rig(config).start()        # the drives, here: their states are read as they change
    try:
        master = subprocess.Popen([*IDENT_HW, "run", path, "--out", tmp_path / "run", "--no-report", "--quiet"],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + RUN_TIMEOUT
            while not (rig.sync_driven and rig.sync_count > 500):        # 2 s into the square
                assert master.poll() is None and time.monotonic() < deadline, master.communicate()
                time.sleep(0.05)
            os.kill(master.pid, signal.SIGSTOP)        # shorter than the limit: survived
            time.sleep(0.6 * limit)
            os.kill(master.pid, signal.SIGCONT)
            time.sleep(1.0)
            assert rig.faulted() == [] and rig.sync_driven
            os.kill(master.pid, signal.SIGSTOP)        # longer: every drive faults
            stopped = time.monotonic()
            while len(rig.faulted()) < len(rig.drives) and time.monotonic() - stopped < 3 * limit + 2:
                time.sleep(0.01)
            faulted_after = time.monotonic() - stopped
            codes = {d.get(0x603F) for d in rig.drives}
            os.kill(master.pid, signal.SIGCONT)
            out, err = master.communicate(timeout=RUN_TIMEOUT)
        finally:
            if master.poll() is None:
                os.kill(master.pid, signal.SIGCONT)
                master.kill()
                master.communicate()
    finally:
        rig.stop()
    print(f"every drive faulted {faulted_after:.3f} s after the master was stopped\n{err[-2000:]}")
    assert limit < faulted_after <= limit + consumer + 0.25, faulted_after
    assert codes == {0x8130}                           # the heartbeat consumer: the master is lost
    assert master.returncode == 4, err                 # a drive fault
    status = (tmp_path / "run" / "STATUS").read_text()
    assert status.startswith("partial: drive fault") and "timing process had stopped" in status, status
    assert (tmp_path / "run" / "data" / "square1.npz").is_file()
