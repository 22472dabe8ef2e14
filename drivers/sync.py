"""The master's SYNC producer in lockstep with a simulated rig.

Real drives sample, take their set-points and move on the SYNC whenever it comes, so against
them the SYNC is periodic (``network.send_periodic``: the bus's own timer where it has one, else
:class:`drivers.bus.GridPeriodicTask`). A simulated rig has no clock of its own worth keeping: in
``lockstep`` the master sends SYNC k+1 as soon as every SYNC-triggered TPDO of cycle k has
arrived (and the set-points of k+1 are on the bus), and the simulated time is the SYNC count
times the period, for the rig and for the recording. Nothing the host's scheduling does then
reaches a sample: a slow host makes the run slower, never different.

Every SYNC carries the CiA 301 SYNC counter (1..240, object ``0x1019`` on a device). A cycle
whose frames did not all arrive within ``retry_after`` is asked again: the caller's set-points and
the SYNC with the *same* counter are sent again, and the rig answers a repeated counter with the
TPDOs of that cycle without moving (a frame a lossy transport such as ``udp_multicast`` dropped
is sent again). A rig that was only slow then answers that cycle twice; before the next SYNC
the master waits for a *barrier* (an SDO round trip through the rig, which answers frames in the
order they came), so that no late copy lands in the next cycle. A cycle still incomplete after
``timeout`` is a fault naming the silent nodes.

Lockstep is for the simulated rig only: real drives move on every SYNC, whatever its counter.
"""

from __future__ import annotations

import threading
import time
from typing import Callable, Mapping

import can
import canopen

from drivers.cia import SYNC_COB_ID
from drivers.errors import DriveError

#: the SYNC producers a run can use (``bus.sync`` of a config)
SYNC_MODES = ("periodic", "lockstep")

#: the CiA 301 SYNC counter runs 1..SYNC_COUNTER_MAX (``0x1019``, synchronous counter overflow)
SYNC_COUNTER_MAX = 240

#: s between two calls of a step's ``poll`` while it waits
POLL = 0.05


class LockstepTimeout(DriveError):
    """A lockstep cycle did not complete: ``missing`` names the nodes whose frames never came."""

    def __init__(self, cycle: int, missing: list[str], waited: float):
        self.cycle, self.missing = cycle, missing
        super().__init__(f"lockstep SYNC cycle {cycle}: no TPDO from {', '.join(missing)} within "
                         f"{waited:.1f} s (is the simulated rig serving this bus, in lockstep?)")


class LockstepSync(can.Listener):
    """Sends one SYNC per :meth:`step` and returns when every expected TPDO of that cycle arrived.

    Add it to the network's notifier (``network.notifier.add_listener``) before stepping; it
    needs the SYNC echo (``receive_own_messages``), which opens the cycle it counts.

    Args:
        network: the master's network.
        expected: ``{cob_id: node label}`` of every TPDO a drive sends on each SYNC.
        period: the simulated time one cycle stands for, s.
        timeout: wall-clock s a cycle may take before it is a :class:`LockstepTimeout`.
        retry_after: wall-clock s after which an incomplete cycle is asked again.
        barrier: called (from the stepping thread) after a cycle that was asked again completed;
            returns once the rig has handled every frame sent before it (e.g. an SDO read of
            one of its nodes). ``None``: no barrier (a repeated answer may then fall into the
            next cycle, where the acquisition flags it).
    """

    def __init__(self, network: canopen.Network, expected: Mapping[int, str], period: float,
                 timeout: float = 10.0, retry_after: float = 1.0,
                 barrier: Callable[[], None] | None = None):
        if not period > 0 or not timeout > 0 or not retry_after > 0:
            raise ValueError(f"period, timeout and retry_after must be positive, got {period}, "
                             f"{timeout}, {retry_after}")
        self.network = network
        self.expected = dict(expected)
        self.period = period
        self.timeout = timeout
        self.retry_after = retry_after
        self.barrier = barrier
        self.cycles = 0        # cycles completed
        self.retries = 0       # cycles asked again
        self.broken: LockstepTimeout | None = None   # the timeout that ended the lockstep, if any
        self._counter = 0
        self._open_counter = None    # counter of the cycle being counted (set by its SYNC echo)
        self._got: set[int] = set()
        self._complete = threading.Event()

    @property
    def time(self) -> float:
        """Simulated time of the next SYNC, s: completed cycles times the period."""
        return self.cycles * self.period

    # -- notifier thread ----------------------------------------------------------------------
    def on_message_received(self, msg: can.Message) -> None:
        cob_id = msg.arbitration_id
        if cob_id == SYNC_COB_ID and not (msg.is_remote_frame or msg.is_error_frame):
            counter = msg.data[0] if msg.dlc else None
            if counter is not None and counter == self._counter and counter != self._open_counter:
                self._open_counter = counter
                self._got = set()
            return
        if cob_id in self.expected and self._open_counter == self._counter:
            self._got.add(cob_id)
            if len(self._got) >= len(self.expected):
                self._complete.set()

    # -- calling thread -------------------------------------------------------------------------
    def step(self, before_sync: Callable[[], None] | None = None,
             poll: Callable[[], None] | None = None) -> None:
        """One cycle: ``before_sync()`` (e.g. send the set-points), SYNC, wait for its TPDOs.

        ``poll()`` is called every :data:`POLL` s while waiting (e.g. to raise on a lost
        heartbeat or an EMCY instead of waiting for the timeout).

        Raises:
            LockstepTimeout: the cycle did not complete within ``timeout`` s (then every later
                step raises it at once).
        """
        if self.broken is not None:
            raise self.broken
        self._counter = self._counter % SYNC_COUNTER_MAX + 1
        self._complete.clear()
        if not self.expected:      # every node forgotten: nothing to wait for
            self._complete.set()
        started = time.monotonic()
        asked = 0
        while True:
            if before_sync is not None:
                before_sync()
            self.network.send_message(SYNC_COB_ID, bytes([self._counter]))
            retry_at = time.monotonic() + self.retry_after
            while not self._complete.wait(max(min(POLL, retry_at - time.monotonic()), 0.0)):
                if poll is not None:
                    poll()
                if time.monotonic() >= retry_at:
                    break
            if self._complete.is_set():
                break
            waited = time.monotonic() - started
            if waited >= self.timeout:
                missing = sorted({label for cob, label in self.expected.items() if cob not in self._got})
                self.broken = LockstepTimeout(self.cycles, missing, waited)
                raise self.broken
            self.retries += 1
            asked += 1
        if asked and self.barrier is not None:
            self.barrier()        # the rig's answers to the repeated SYNCs are in before SYNC k+1
        self.cycles += 1

    def forget(self, label: str) -> None:
        """Stop waiting for the TPDOs of node ``label`` (a node known to be lost), so that the
        others can still be stepped to a stop."""
        self.expected = {cob: name for cob, name in self.expected.items() if name != label}

    def run(self, cycles: int) -> None:
        """``cycles`` steps without set-points (homing, profile moves, stopping)."""
        for _ in range(cycles):
            self.step()
