"""drivers.supervision.Supervisor's heartbeat consumer: a node silent while the master runs and
checks times out after its consumer timeout; a gap in the master's own checks (its process did
not run: a loaded host, a thread holding the GIL) counts as silence only up to MAX_UNWATCHED."""

from __future__ import annotations

import time

from drivers.errors import HeartbeatTimeout
from drivers.supervision import MAX_UNWATCHED, Supervisor

TIMEOUT = 0.35   # s, the master's consumer timeout of the shipped configs (3.5 x 0.1 s)


class _Nmt:
    """The part of canopen's NMT a supervisor uses: a heartbeat callback, called here by hand."""

    def __init__(self):
        self.callbacks = []

    def add_heartbeat_callback(self, callback):
        self.callbacks.append(callback)

    def heartbeat(self, state: int = 5):
        for callback in self.callbacks:
            callback(state)


def watched() -> tuple[Supervisor, _Nmt]:
    supervisor, nmt = Supervisor(), _Nmt()
    supervisor.watch_heartbeat("node 1 (theta1)", nmt, TIMEOUT)
    nmt.heartbeat()
    supervisor.start_heartbeat_monitoring()
    return supervisor, nmt


def test_a_node_silent_while_the_master_checks_times_out_after_its_timeout():
    supervisor, _ = watched()
    start = time.monotonic()
    while supervisor.fault is None and time.monotonic() - start < 5 * TIMEOUT:
        supervisor.check_heartbeats()
        time.sleep(0.01)
    elapsed = time.monotonic() - start
    assert isinstance(supervisor.fault, HeartbeatTimeout) and "node 1 (theta1)" in str(supervisor.fault)
    assert TIMEOUT <= elapsed <= 2 * TIMEOUT, elapsed      # its own checks every 10 ms: on time


def test_heartbeats_keep_the_node_alive():
    supervisor, nmt = watched()
    for _ in range(60):                      # 0.6 s, a heartbeat every 0.1 s
        time.sleep(0.01)
        if _ % 10 == 0:
            nmt.heartbeat()
        supervisor.check_heartbeats()
    assert supervisor.fault is None


def test_a_stall_of_the_master_itself_is_not_a_silent_node():
    """The master's thread stops for three consumer timeouts (no check, no heartbeat handled),
    then runs again: the stall counts as MAX_UNWATCHED, the next heartbeat comes in time."""
    supervisor, nmt = watched()
    time.sleep(3 * TIMEOUT)
    supervisor.check_heartbeats()
    assert supervisor.fault is None
    nmt.heartbeat()
    for _ in range(10):
        time.sleep(0.01)
        supervisor.check_heartbeats()
    assert supervisor.fault is None and MAX_UNWATCHED < TIMEOUT
