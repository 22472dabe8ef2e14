"""The timing process (drivers.timing, drivers.timing_server) on python-can's udp_multicast bus: it
owns the bus, relays every frame both ways, sends the SYNC, a stream's set-points and the
master's heartbeat on time while the master's process is held (a GIL-holding call), stops them
when the master's loop makes no progress for longer than the limit, and ends with the master.

What the bus carries is heard by a listener in a process of its own (``bus_listener.py``), whose
kernel time stamps hold however the test process is held up."""

import ctypes
import json
import os
import signal
import struct
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import can
import numpy as np
import pytest

from drivers.bus import BusConfig, open_bus, open_network
from drivers.cia import SYNC_COB_ID
from drivers.timing import TimedBus, TimingConfig
from udp_groups import interface_local_group, loopback_multicast_works

pytest.importorskip("msgpack", reason="python-can's udp_multicast interface needs msgpack (pip install -e '.[test]')")

LISTENER = Path(__file__).resolve().parent / "bus_listener.py"
HEARTBEAT = 0x77F


@pytest.fixture
def group():
    group = interface_local_group()
    if not loopback_multicast_works(group):
        pytest.skip(f"this host does not loop IPv6 multicast back to its own sockets ({group})")
    return group


@pytest.fixture
def listen():
    """``listen(group, seconds)`` starts a listener process; ``.heard()`` its JSON once it ended."""
    procs = []

    class Listening:
        def __init__(self, group, seconds):
            self.proc = subprocess.Popen([sys.executable, str(LISTENER), group, str(seconds)],
                                         stdout=subprocess.PIPE, text=True)
            procs.append(self.proc)
            assert self.proc.stdout.readline().strip() == "ready"

        def heard(self) -> dict:
            out, _ = self.proc.communicate(timeout=60)
            return json.loads(out.strip().splitlines()[-1])

    yield Listening
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def _hold_the_gil(seconds: float) -> None:
    """A C call that keeps the GIL (ctypes.PyDLL): no thread of this process runs meanwhile."""
    ctypes.PyDLL(None).usleep(int(seconds * 1e6))


def _rows(n: int) -> bytes:
    """Set-points k = 0..n-1 of one RPDO (I32 target, U16 controlword)."""
    return b"".join(struct.pack("<iH", k, 0x0F) for k in range(n))


def test_frames_go_both_ways_and_a_stream_sends_row_k_plus_1_after_sync_k(group, listen):
    bus = TimedBus(BusConfig("udp_multicast", group), TimingConfig(master_progress=2.0))
    peer = open_bus(BusConfig("udp_multicast", group))
    try:
        assert bus.pid != os.getpid() and "timing process" in bus.channel_info
        bus.send(can.Message(arbitration_id=0x601, data=b"\x40\x00\x10\x00", is_extended_id=False))
        got = peer.recv(2.0)
        assert got.arbitration_id == 0x601 and bytes(got.data) == b"\x40\x00\x10\x00"
        own = bus.recv(2.0)                         # the timing process's frames come back as own ones
        assert own.arbitration_id == 0x601
        peer.send(can.Message(arbitration_id=0x581, data=b"\x43\x00\x10\x00\x92\x01\x02\x00", is_extended_id=False))
        answer = bus.recv(2.0)
        assert answer.arbitration_id == 0x581 and bytes(answer.data) == b"\x43\x00\x10\x00\x92\x01\x02\x00"

        listening = listen(group, 1.0)
        period, rows = 0.005, 100
        bus.start_stream(period, SYNC_COB_ID, [0x201], [6], _rows(rows))
        end = time.monotonic() + 0.8
        while time.monotonic() < end:
            bus.alive()
            time.sleep(0.02)
        report = bus.stop_stream()
        heard = listening.heard()
    finally:
        peer.shutdown()
        bus.shutdown()
    syncs, setpoints = heard[f"{SYNC_COB_ID:#05x}"], heard["0x201"]
    values = [struct.unpack("<iH", bytes.fromhex(d))[0] for d in heard["data 0x201"]]
    # row 0 before the first SYNC, row k+1 right after SYNC k, the last row again past the table's end
    assert values[:rows] == list(range(rows)) and set(values[rows:]) == {rows - 1}
    first = setpoints[0]
    order = sorted([(t, "s") for t in syncs] + [(t, "r") for t in setpoints if t > first])
    assert "".join(kind for _, kind in order).startswith("sr" * 50)
    assert report.syncs_sent == len(syncs) and report.slots_skipped <= 2 and report.send_failures == 0
    assert abs(np.median(np.diff(syncs)) - period) < 0.2 * period


def test_a_held_master_process_keeps_sync_and_heartbeat_on_time_and_loses_no_frame(group, listen):
    """1 s of a GIL-holding call in the master's process: the listener hears the SYNC every period and
    the heartbeat every 0.1 s throughout; afterwards the master receives every SYNC the timing
    process sent, and the stream's report says how long the master was held."""
    network = open_network(BusConfig("udp_multicast", group), TimingConfig(master_progress=3.0))
    try:
        listening = listen(group, 3.0)
        heartbeat = network.send_periodic(HEARTBEAT, b"\x05", 0.1)
        syncs_seen = []
        network.notifier.add_listener(_Collect(syncs_seen, SYNC_COB_ID))
        network.bus.start_stream(0.004, SYNC_COB_ID, [0x201], [6], _rows(200))
        for _ in range(25):
            network.alive()
            time.sleep(0.02)
        _hold_the_gil(1.0)
        for _ in range(40):
            network.alive()
            time.sleep(0.02)
        report = network.bus.stop_stream()
        heartbeat.stop()
        time.sleep(0.3)                             # the notifier catches up with what waited
        heard = listening.heard()
    finally:
        network.disconnect()
    syncs = np.array(heard[f"{SYNC_COB_ID:#05x}"])
    beats = np.array(heard[f"{HEARTBEAT:#05x}"])
    assert len(syncs) > 500 and np.diff(syncs).max() < 3 * 0.004, np.diff(syncs).max()
    assert np.diff(beats).max() < 0.15, np.diff(beats).max()
    assert len(syncs_seen) == report.syncs_sent == len(syncs)
    assert 1.0 <= report.longest_stall < 2.0 and report.stopped_after is None and report.relay_dropped == 0


class _Collect(can.Listener):
    def __init__(self, into: list, cob_id: int):
        self.into, self.cob_id = into, cob_id

    def on_message_received(self, msg):
        if msg.arbitration_id == self.cob_id:
            self.into.append(msg.timestamp)


def test_other_timing_processes_starting_and_ending_on_its_cpu_do_not_hold_a_stream_up(group, listen):
    """Timing processes of other masters start and end on the CPU of one that streams SYNC every
    4 ms (this test's CPU: a pinned worker's processes inherit it): the stream skips no more slots
    than a quiet one (at most 2, no interval of 3 periods). A timing process is real-time only
    while it serves; its start-up and ending at SCHED_FIFO held the streaming one, of the same
    priority, ~30 ms each time (68 slots skipped here)."""
    bus = TimedBus(BusConfig("udp_multicast", group), TimingConfig(master_progress=3.0))
    try:
        listening = listen(group, 3.0)
        period = 0.004
        bus.start_stream(period, SYNC_COB_ID, [0x201], [6], _rows(500))
        others, end = 0, time.monotonic() + 2.0
        while time.monotonic() < end:
            bus.alive()
            TimedBus(BusConfig("udp_multicast", interface_local_group()), TimingConfig(master_progress=3.0)).shutdown()
            others += 1
        bus.alive()
        report = bus.stop_stream()
        heard = listening.heard()
    finally:
        bus.shutdown()
    syncs = np.array(heard[f"{SYNC_COB_ID:#05x}"])
    assert others >= 5 and len(syncs) > 400, (others, len(syncs))
    assert report.slots_skipped <= 2 and np.diff(syncs).max() < 3 * period, (report.slots_skipped, np.diff(syncs).max())


def test_the_timers_stop_when_the_master_makes_no_progress_and_start_again_with_it(group, listen):
    limit = 0.5
    bus = TimedBus(BusConfig("udp_multicast", group), TimingConfig(master_progress=limit))
    try:
        listening = listen(group, 2.5)
        task = bus.periodic(HEARTBEAT, b"\x05", 0.05)
        bus.start_stream(0.01, SYNC_COB_ID, [0x201], [6], _rows(1000))
        for _ in range(20):
            bus.alive()
            time.sleep(0.02)
        last_word = time.time()
        time.sleep(1.0)                             # the master's loop: no progress (its threads run)
        assert bus.stopped_after == pytest.approx(limit, abs=0.05)
        report = bus.stop_stream()
        task = bus.periodic(HEARTBEAT, b"\x05", 0.05)   # started again: the watch starts afresh
        for _ in range(20):
            bus.alive()
            time.sleep(0.02)
        task.stop()
        heard = listening.heard()
    finally:
        bus.shutdown()
    assert report.stopped_after == pytest.approx(limit, abs=0.05)
    syncs = np.array(heard[f"{SYNC_COB_ID:#05x}"])
    beats = np.array(heard[f"{HEARTBEAT:#05x}"])
    assert syncs.max() - last_word == pytest.approx(limit, abs=0.05)      # the last SYNC: at the limit
    gap = int(np.argmax(np.diff(beats)))
    assert limit - 0.05 - 0.02 < beats[gap] - last_word < limit + 0.03    # the last heartbeat: one period before the limit
    assert beats[gap + 1] - beats[gap] > 0.4                              # silent until the master started it again
    assert np.diff(beats[gap + 1:]).max() < 0.08                          # and on its period again after that


def test_the_timing_process_ends_when_the_master_process_dies(group, listen, tmp_path):
    """A master killed (SIGKILL: no clean-up at all) leaves no SYNC or heartbeat behind: its timing
    process sees the pipe close and ends."""
    script = tmp_path / "master.py"
    script.write_text(textwrap.dedent(f"""
        import sys, time
        from drivers.bus import BusConfig
        from drivers.timing import TimedBus, TimingConfig
        bus = TimedBus(BusConfig("udp_multicast", {group!r}), TimingConfig(master_progress=60.0))
        bus.periodic({HEARTBEAT}, b"\\x05", 0.05)
        bus.start_stream(0.01, 0x80, [0x201], [6], b"\\x00" * 60)
        print(bus.pid, flush=True)
        while True:
            bus.alive()
            time.sleep(0.02)
        """))
    master = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        timing_pid = int(master.stdout.readline())
        listening = listen(group, 1.5)
        time.sleep(0.5)
        os.kill(master.pid, signal.SIGKILL)
        killed = time.time()
        master.wait(10)
        heard = listening.heard()
        deadline = time.monotonic() + 10
        while _alive(timing_pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(timing_pid)
    finally:
        if master.poll() is None:
            master.kill()
    assert max(heard[f"{HEARTBEAT:#05x}"]) < killed + 0.1
    assert max(heard[f"{SYNC_COB_ID:#05x}"]) < killed + 0.1


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:                       # a zombie (not yet reaped by its new parent) is ended too
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except OSError:
        return False


def test_a_bus_that_the_timing_process_cannot_open_is_a_bus_open_error():
    from drivers.errors import BusOpenError
    with pytest.raises(BusOpenError, match="interface='nosuchinterface'"):
        TimedBus(BusConfig("nosuchinterface", "x"))
