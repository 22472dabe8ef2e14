"""drivers.affinity.one_cpu: the calling thread and the threads it starts run on one CPU, the
CPU set comes back after; the command line's host settings use it for the in-process lockstep
rig only."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import pytest

from cpus import ALL_CPUS, all_cpus
from drivers.affinity import _current_cpu, one_cpu
from ident_hw.config import load_config
from ident_hw.experiment.session import HostSettings, open_session

SIM = Path(__file__).resolve().parents[1] / "configs" / "sim-3prrr.yaml"

needs_two_cpus = pytest.mark.skipif(len(ALL_CPUS) < 2, reason="needs Linux and at least two CPUs this process may use")


@pytest.fixture(autouse=True)
def every_cpu():
    """A pytest-xdist worker is pinned to one CPU (tests/conftest.py): these tests run on all."""
    if len(ALL_CPUS) < 2:
        yield
        return
    with all_cpus():
        yield


def cpus_of(thread: threading.Thread) -> set[int]:
    """The CPU set the kernel holds for a running thread (by its native thread ID)."""
    return os.sched_getaffinity(thread.native_id)


@needs_two_cpus
def test_threads_started_inside_run_on_the_one_cpu_and_the_set_comes_back():
    before = os.sched_getaffinity(0)
    seen = {}
    with one_cpu() as cpu:
        assert cpu in before
        worker = threading.Thread(target=lambda: seen.setdefault("cpus", os.sched_getaffinity(0)))
        worker.start()
        worker.join()
        assert os.sched_getaffinity(0) == {cpu}
    assert seen["cpus"] == {cpu}
    assert os.sched_getaffinity(0) == before


@needs_two_cpus
def test_the_one_cpu_is_the_one_the_thread_runs_on():
    """Moved onto each allowed CPU in turn (the kernel migrates the calling thread before
    ``sched_setaffinity`` returns), the thread reads that CPU back; ``one_cpu`` pins to a CPU the
    thread may use and runs on."""
    before = os.sched_getaffinity(0)
    try:
        for cpu in sorted(before):
            os.sched_setaffinity(0, {cpu})
            assert _current_cpu() == cpu
            os.sched_setaffinity(0, before)
            with one_cpu() as chosen:     # the thread may have moved meanwhile: where it is now
                assert os.sched_getaffinity(0) == {chosen} and _current_cpu() == chosen
    finally:
        os.sched_setaffinity(0, before)


@needs_two_cpus
def test_the_set_comes_back_when_the_section_raises():
    before = os.sched_getaffinity(0)
    with pytest.raises(RuntimeError), one_cpu():
        raise RuntimeError("stop")
    assert os.sched_getaffinity(0) == before


def session_config(folder: Path, sync: str):
    path = folder / f"{sync}.yaml"
    path.write_text(f"extends: {SIM}\n"
                    f"bus: {{interface: virtual, channel: affinity-{os.getpid()}-{time.monotonic_ns()}, "
                    f"sync_rate: 100.0, sync: {sync}}}\n")
    return load_config(path)


@needs_two_cpus
@pytest.mark.parametrize("sync, pinned", [("lockstep", True), ("periodic", False)])
def test_the_command_runs_the_in_process_lockstep_rig_and_master_on_one_cpu(tmp_path, sync, pinned):
    """Under the command line's host settings every thread the session starts (the rig's notifier
    and clock, the master's notifier) is on one CPU with the lockstep rig in the process; with a
    periodic SYNC (real time) nothing is."""
    before = os.sched_getaffinity(0)
    existing = set(threading.enumerate())
    config = session_config(tmp_path, sync)
    host = HostSettings.for_command(config)
    assert host.one_cpu is pinned and host.freeze_gc
    with host.pinned(), open_session(config) as session:
        started = [t for t in threading.enumerate() if t not in existing and t.is_alive()]
        assert session.rig is not None and len(started) >= 3
        sets = {frozenset(cpus_of(t)) for t in started} | {frozenset(os.sched_getaffinity(0))}
        if pinned:
            assert len(sets) == 1 and len(next(iter(sets))) == 1
        else:
            assert sets == {frozenset(before)}
    assert os.sched_getaffinity(0) == before
