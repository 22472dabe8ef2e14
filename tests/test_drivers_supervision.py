"""drivers.supervision.Supervisor's heartbeat consumer: a node silent while the master runs and
checks times out after its consumer timeout; a gap in the master's own checks (its process did
not run: a loaded host, a thread holding the GIL) counts as silence only up to MAX_UNWATCHED, and
a master behind the bus (working through frames that waited) measures silence on the bus's own
time stamps too."""

from __future__ import annotations

import time

import can

from drivers.errors import HeartbeatTimeout
from drivers.supervision import MAX_UNWATCHED, Supervisor

TIMEOUT = 0.35   # s, the master's consumer timeout of the shipped configs (3.5 x 0.1 s)


class _Network:
    """The part of a canopen network a supervisor uses: a subscription to the node's heartbeat
    COB-ID, called here by hand with the frame's bus time stamp (which the supervisor's bus
    clock, a listener of the notifier, sees too)."""

    def __init__(self, supervisor: Supervisor):
        self.supervisor = supervisor
        self.callbacks = []

    def subscribe(self, can_id, callback):
        assert can_id == 0x701
        self.callbacks.append(callback)

    def frame(self, stamp: float, can_id: int = 0x080) -> None:
        """Another frame handled by the notifier (a SYNC), stamped ``stamp`` on the bus."""
        self.supervisor.bus_time.on_message_received(can.Message(arbitration_id=can_id, timestamp=stamp))

    def heartbeat(self, state: int = 5, stamp: float | None = None):
        stamp = time.time() if stamp is None else stamp
        self.frame(stamp, 0x701)
        for callback in self.callbacks:
            callback(0x701, bytes([state]), stamp)


def watched() -> tuple[Supervisor, _Network]:
    supervisor = Supervisor()
    network = _Network(supervisor)
    supervisor.watch_heartbeat("node 1 (theta1)", network, 1, TIMEOUT)
    network.heartbeat()
    supervisor.start_heartbeat_monitoring()
    return supervisor, network


def test_a_node_silent_while_the_master_checks_times_out_after_its_timeout():
    supervisor, network = watched()
    start = time.monotonic()
    while supervisor.fault is None and time.monotonic() - start < 5 * TIMEOUT:
        network.frame(time.time())              # the bus goes on: the node alone is silent
        supervisor.check_heartbeats()
        time.sleep(0.01)
    elapsed = time.monotonic() - start
    assert isinstance(supervisor.fault, HeartbeatTimeout) and "node 1 (theta1)" in str(supervisor.fault)
    assert TIMEOUT <= elapsed <= 2 * TIMEOUT, elapsed      # its own checks every 10 ms: on time


def test_heartbeats_keep_the_node_alive():
    supervisor, network = watched()
    for _ in range(60):                      # 0.6 s, a heartbeat every 0.1 s
        time.sleep(0.01)
        if _ % 10 == 0:
            network.heartbeat()
        supervisor.check_heartbeats()
    assert supervisor.fault is None


def test_a_stall_of_the_master_itself_is_not_a_silent_node():
    """The master's thread stops for three consumer timeouts (no check, no heartbeat handled),
    then runs again: the stall counts as MAX_UNWATCHED, the next heartbeat comes in time."""
    supervisor, network = watched()
    time.sleep(3 * TIMEOUT)
    supervisor.check_heartbeats()
    assert supervisor.fault is None
    network.heartbeat()
    for _ in range(10):
        time.sleep(0.01)
        supervisor.check_heartbeats()
    assert supervisor.fault is None and MAX_UNWATCHED < TIMEOUT


def test_a_master_working_through_a_backlog_is_behind_the_bus_not_facing_a_silent_node():
    """After a hold-up the notifier reaches the frames that waited more slowly than the master's own
    checks go on (a loaded host): 10 ms of checks per 2.5 ms of the bus read, the node's heartbeats
    every 0.1 s on the bus, so 0.4 s of checks apart, more than its timeout. Each came in time on
    the bus: no fault. A node silent on the bus for longer than its timeout is one."""
    supervisor, network = watched()
    bus = time.time()
    for k in range(1, 161):
        time.sleep(0.01)
        network.frame(bus + 0.0025 * k)
        if k % 40 == 0:
            network.heartbeat(stamp=bus + 0.0025 * k)
        supervisor.check_heartbeats()
    assert supervisor.fault is None
    for k in range(161, 400):                # the node falls silent on the bus itself
        time.sleep(0.004)
        network.frame(bus + 0.0025 * k)
        supervisor.check_heartbeats()
        if supervisor.fault is not None:
            break
    assert isinstance(supervisor.fault, HeartbeatTimeout) and "on the bus" in str(supervisor.fault)
    assert TIMEOUT < 0.0025 * (k - 160) <= TIMEOUT + 0.005      # timed out on the bus's time
