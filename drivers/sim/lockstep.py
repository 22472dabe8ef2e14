"""The simulated rig's SYNC source: the master and the rig in lockstep.

A simulated rig has no clock of its own worth keeping: in lockstep the master sends SYNC k+1 as
soon as the rig has answered SYNC k (and the set-points of k+1 are on the bus), and the simulated
time is the SYNC count times the period, for the rig and for the recording. Nothing the host's
scheduling does then reaches a sample: a slow host makes the run slower, never different.

The rig closes its answer to every SYNC with an *answer frame* (:data:`ANSWER_COB_ID`, a COB-ID
no CANopen device uses): the SYNC counter, the number of SYNC-triggered TPDO frames its drives
sent, and whether it held the SYNC back because some set-points of the cycle had not come. The
master's :class:`LockstepSync` then knows at once when a frame was lost on the way (fewer
frames arrived than the rig sent) or a set-point was (the rig held the SYNC): it asks the cycle
again right away, with the caller's set-points and the SYNC with the *same* counter, and the rig
answers a repeated counter with the TPDOs of that cycle without moving. A lost frame costs a
round trip, not a time-out. Only a lost answer frame (a lossy transport such as
``udp_multicast``) is waited for, ``retry_after`` s. A rig that answered twice (a late original,
then the repeat) is waited for through a *barrier* (an SDO round trip through the rig, which
answers frames in the order they came) before the next SYNC, so that no late copy lands in the
next cycle. A cycle still incomplete after ``timeout`` is a fault naming the silent nodes.

Lockstep is for the simulated rig only: real drives move on every SYNC, whatever its counter.
"""

from __future__ import annotations

import functools
import struct
import threading
import time
from typing import Callable, Mapping

import can
import canopen

from drivers.cia import SYNC_COB_ID
from drivers.errors import ConfigError, DriveError
from drivers.sync import SYNC_COUNTER_MAX, TICK, SyncReport, SyncSource

#: COB-ID of the rig's answer frame (outside CiA 301's predefined connection set and LSS)
ANSWER_COB_ID = 0x7F0

#: the answer frame: SYNC counter (U8), SYNC-triggered TPDO frames sent (U16), held (U8: 1 when
#: the rig left the SYNC unanswered for want of set-points)
ANSWER = struct.Struct("<BHB")

#: s between two calls of a step's ``poll`` while it waits
POLL = 0.05

#: s: the least time between two asks of a cycle that the rig's answer called for (a frame the
#: transport holds back would otherwise be asked for again and again until it comes)
REASK_SPACING = 0.005


def answer_frame(counter: int, frames: int, held: bool) -> bytes:
    """The data of the rig's answer to the SYNC with ``counter`` (see :data:`ANSWER`)."""
    return ANSWER.pack(counter, frames, int(held))


class LockstepTimeout(DriveError):
    """A lockstep cycle did not complete: ``missing`` names the nodes whose frames never came."""

    def __init__(self, cycle: int, missing: list[str], waited: float):
        self.cycle, self.missing = cycle, missing
        super().__init__(f"lockstep SYNC cycle {cycle}: no complete answer (TPDOs missing from "
                         f"{', '.join(missing) or 'no node'}) within {waited:.1f} s (is the simulated "
                         f"rig serving this bus, in lockstep?)")


class LockstepSync(SyncSource, can.Listener):
    """One SYNC per step, the next once the rig has answered: the simulated rig's SYNC source.

    Until a drive group attaches it (its drives are up) and after the lockstep broke, the waits
    count in wall-clock time, as they would on a periodic SYNC; in between every wait advances
    the simulated time by whole SYNC cycles. It needs the SYNC echo (``receive_own_messages``),
    which opens the cycle it counts.

    Args:
        period: the simulated time one cycle stands for, s.
        timeout: wall-clock s a cycle may take before it is a :class:`LockstepTimeout`.
        retry_after: wall-clock s after which a cycle whose answer did not come is asked again.
    """

    name = "lockstep"
    free_running = False

    def __init__(self, period: float, timeout: float = 10.0, retry_after: float = 1.0):
        if not period > 0 or not timeout > 0 or not retry_after > 0:
            raise ValueError(f"period, timeout and retry_after must be positive, got {period}, "
                             f"{timeout}, {retry_after}")
        self.period = period
        self.timeout = timeout
        self.retry_after = retry_after
        self.network: canopen.Network | None = None
        self.expected: dict[int, str] = {}
        self.barrier: Callable[[], None] | None = None
        self.cycles = 0        # cycles completed
        self.retries = 0       # cycles asked again
        self.waited_out = 0    # of them, asked again after ``retry_after`` without an answer
        self.broken: LockstepTimeout | None = None   # the timeout that ended the lockstep, if any
        self._counter = 0
        self._open_counter: int | None = None    # counter of the cycle being counted (set by its SYNC echo)
        self._got: set[int] = set()
        self._complete = False
        self._again = False          # the rig's answer calls for asking the cycle again
        self._wake = threading.Event()
        self._heartbeat: CountedHeartbeat | None = None

    # -- SyncSource -----------------------------------------------------------------------------
    def watch_clock(self) -> SimulatedClock:
        """The simulated time of the cycles completed: the master's watch of the drives'
        heartbeats counts SYNC periods, so that a busy host never stops a simulated run (the rig
        sends its heartbeats by SYNC count too, :mod:`drivers.sim.rig`)."""
        return SimulatedClock(self)

    def start_heartbeat(self, network: canopen.Network, cob_id: int, data: bytes, period: float) -> CountedHeartbeat:
        """The master's heartbeat in simulated time: sent before the SYNC of every cycle that
        starts ``period`` s or more of simulated time after the last one (the first one with the
        first SYNC), never by a wall clock."""
        self._heartbeat = CountedHeartbeat(self, can.Message(arbitration_id=cob_id, data=bytes(data),
                                                              is_extended_id=False), period)
        return self._heartbeat

    def attach(self, network: canopen.Network, tpdos: Mapping[int, str],
               barrier: Callable[[], None]) -> None:
        if network.notifier is None:
            raise RuntimeError("lockstep: the network is not connected (no notifier to listen to)")
        self.network, self.expected, self.barrier = network, dict(tpdos), barrier
        network.notifier.add_listener(self)

    def detach(self) -> None:
        if self.network is not None:
            if self.network.notifier is not None:
                self.network.notifier.remove_listener(self)
            self.network = None

    @property
    def stepping(self) -> bool:
        """Attached and not broken: the waits advance the simulated time."""
        return self.network is not None and self.broken is None

    def now(self) -> float:
        """Simulated time of the next SYNC (completed cycles times the period), s."""
        return self.cycles * self.period if self.stepping else time.monotonic()

    def wait(self, seconds: float) -> None:
        if self.stepping:
            self.run(max(1, round(seconds / self.period)))
        else:
            time.sleep(seconds)

    def tick(self) -> None:
        if self.stepping:
            self.run(1)
        else:
            time.sleep(TICK)

    def check_period(self, period: float) -> None:
        if abs(period - self.period) > 1e-12:
            raise ConfigError(f"run_cyclic: period {period} s differs from the lockstep SYNC period "
                              f"{self.period} s")

    @property
    def row_period(self) -> float:
        return self.period

    def stream(self, network, period, cycles, setpoints, poll) -> None:
        """SYNC k goes out once cycle k-1 is answered; one more closes the last row (the drives
        get the last set-points again)."""
        for k in range(cycles + 1):
            self.step(functools.partial(setpoints.send, k), poll=poll)
            poll()

    def report(self) -> SyncReport:
        return SyncReport(lockstep_retries=self.retries, lockstep_waited_out=self.waited_out,
                          timing="lockstep: the SYNC paced by the simulated rig's answers")

    # -- notifier thread ----------------------------------------------------------------------
    def on_message_received(self, msg: can.Message) -> None:
        cob_id = msg.arbitration_id
        if msg.is_remote_frame or msg.is_error_frame:
            return
        if cob_id == SYNC_COB_ID:
            counter = msg.data[0] if msg.dlc else None
            if counter is not None and counter == self._counter and counter != self._open_counter:
                self._open_counter = counter
                self._got = set()
            return
        if self._open_counter != self._counter:
            return
        if cob_id in self.expected:
            self._got.add(cob_id)
            if len(self._got) >= len(self.expected):
                self._complete = True
                self._wake.set()
        elif cob_id == ANSWER_COB_ID and msg.dlc >= ANSWER.size:
            counter, frames, held = ANSWER.unpack(bytes(msg.data[:ANSWER.size]))
            if counter != self._counter:
                return
            if not held and len(self._got) >= frames:
                self._complete = True
            else:
                self._again = True
            self._wake.set()

    # -- calling thread -------------------------------------------------------------------------
    def step(self, before_sync: Callable[[], None] | None = None,
             poll: Callable[[], None] | None = None) -> None:
        """One cycle: ``before_sync()`` (e.g. send the set-points), SYNC, wait for the rig's answer.

        ``poll()`` is called every :data:`POLL` s while waiting (e.g. to raise on a lost
        heartbeat or an EMCY instead of waiting for the timeout).

        Raises:
            LockstepTimeout: the cycle did not complete within ``timeout`` s (then every later
                step raises it at once).
        """
        if self.broken is not None:
            raise self.broken
        network = self.network
        if network is None:
            raise RuntimeError("lockstep: step() before attach()")
        self._counter = self._counter % SYNC_COUNTER_MAX + 1
        self._complete = False
        started = time.monotonic()
        asked = 0
        last_ask = 0.0
        heartbeat = self._heartbeat
        if heartbeat is not None and heartbeat.due(self.cycles * self.period):
            network.send_message(heartbeat.msg.arbitration_id, bytes(heartbeat.msg.data))
        while True:
            self._again = False
            self._wake.clear()
            if before_sync is not None:
                before_sync()
            last_ask = time.monotonic()
            network.send_message(SYNC_COB_ID, bytes([self._counter]))
            retry_at = last_ask + self.retry_after
            while not self._complete and not self._again and time.monotonic() < retry_at:
                self._wake.wait(max(min(POLL, retry_at - time.monotonic()), 0.0))
                self._wake.clear()
                if poll is not None:
                    poll()
            if self._complete:
                break
            waited = time.monotonic() - started
            if waited >= self.timeout:
                missing = sorted({label for cob, label in self.expected.items() if cob not in self._got})
                self.broken = LockstepTimeout(self.cycles, missing, waited)
                raise self.broken
            if not self._again:
                self.waited_out += 1
            time.sleep(max(0.0, last_ask + REASK_SPACING - time.monotonic()))
            self.retries += 1
            asked += 1
        if asked and self.barrier is not None:
            self.barrier()        # the rig's answers to the repeated SYNCs are in before SYNC k+1
        self.cycles += 1

    def run(self, cycles: int) -> None:
        """``cycles`` steps without set-points (homing, profile moves, stopping)."""
        for _ in range(cycles):
            self.step()


class SimulatedClock:
    """The watch clock of a lockstep run: the simulated time of the cycles completed, s (it
    stands still between streams and while the master does anything else)."""

    def __init__(self, sync: LockstepSync):
        self._sync = sync

    def advance(self) -> float:
        return self._sync.cycles * self._sync.period

    peek = advance


class CountedHeartbeat:
    """The master's heartbeat of a lockstep run, due every ``period`` s of simulated time."""

    def __init__(self, sync: LockstepSync, msg: can.Message, period: float):
        self._sync, self.msg, self.period = sync, msg, period
        self._last: float | None = None

    def due(self, now: float) -> bool:
        """Whether the heartbeat goes out with the cycle starting at simulated time ``now``."""
        if self._last is not None and now - self._last < self.period - 1e-9:
            return False
        self._last = now
        return True

    def update(self, data: bytes) -> None:
        self.msg = can.Message(arbitration_id=self.msg.arbitration_id, data=bytes(data), is_extended_id=False)

    def stop(self) -> None:
        if self._sync._heartbeat is self:
            self._sync._heartbeat = None
