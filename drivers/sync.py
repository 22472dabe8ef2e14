"""What paces the drives: the SYNC producer of a run and the time base of the master's waits.

A :class:`drivers.epos.DriveGroup` is given one :class:`SyncSource`. The drives sample, take
their set-points and move on the SYNC whenever it comes; the master's other waits (homing,
profile moves, state transitions) count in the source's time. :class:`PeriodicSync` is the one
for real drives: the SYNC from a timing process beside the master's (:mod:`drivers.timing`), or from the bus's
own timer where the interface has one (the kernel BCM on SocketCAN, an adapter's hardware), else
from a thread on a time grid (:class:`drivers.bus.GridPeriodicTask`); the waits count in the time
the master was running (:class:`drivers.supervision.WatchClock`). Another source (a
simulated rig's, which paces the SYNC by the rig's answers) implements the same interface.

Every SYNC may carry the CiA 301 SYNC counter (1..240, object ``0x1019`` on a device).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Protocol

import canopen

from drivers.cia import SYNC_COB_ID
from drivers.supervision import WatchClock

logger = logging.getLogger(__name__)

#: the CiA 301 SYNC counter runs 1..SYNC_COUNTER_MAX (``0x1019``, synchronous counter overflow)
SYNC_COUNTER_MAX = 240

#: s: a SYNC period below which a thread-timed producer is known to come late. A dress rehearsal
#: at 4 ms on a virtual bus, nothing else running, skipped 2.4 % of the slots (docs/drives.md).
THREAD_LATE_BELOW = 0.010

#: s of wall-clock time :meth:`PeriodicSync.tick` sleeps: the master's shortest poll of a drive
TICK = 0.002


class SyncSource(ABC):
    """The SYNC producer of a drive group and the clock its waits count in.

    Attributes:
        name: what the run's metadata calls it (``sync``).
        free_running: the SYNC keeps coming on its own while the master does other things (a
            timer): the set-points of cycle k+1 then go out when SYNC k is seen, and a stream ends
            when its last cycle has been recorded. ``False``: one SYNC per step of the master.
    """

    name: str = ""
    free_running: bool = True

    def watch_clock(self):
        """The clock the master's watch of the drives' heartbeats counts in
        (:class:`drivers.supervision.Supervisor`): here the time the master was running and
        watching (:class:`~drivers.supervision.WatchClock`)."""
        return WatchClock()

    def start_heartbeat(self, network: canopen.Network, cob_id: int, data: bytes, period: float):
        """Start the master's heartbeat, every ``period`` s; returns what ``stop()`` ends it:
        here ``network.send_periodic`` (a timing process, the bus's timer, or a thread)."""
        return network.send_periodic(cob_id, data, period)

    def answers_on_sync(self, network: canopen.Network) -> bool:
        """Whether the master sends the set-points of cycle k+1 when it sees SYNC k (from its
        notifier thread); ``False`` where the source sends them itself."""
        return self.free_running

    def attach(self, network: canopen.Network, tpdos: Mapping[int, str],
               barrier: Callable[[], None]) -> None:
        """Called once the drives are up: ``tpdos`` maps the COB-ID of every SYNC-triggered TPDO
        to its node's label; ``barrier()`` returns once every frame sent to the drives before it
        was handled (an SDO round trip)."""

    def detach(self) -> None:
        """The drive group closes: forget the network."""

    @abstractmethod
    def now(self) -> float:
        """The time the master's waits count in, s."""

    @abstractmethod
    def wait(self, seconds: float) -> None:
        """Let the drives move for ``seconds`` while the master waits."""

    @abstractmethod
    def tick(self) -> None:
        """The shortest wait between two polls of a drive."""

    def check_period(self, period: float) -> None:
        """Raise :class:`~drivers.errors.ConfigError` when this source cannot stream at ``period`` s."""

    @property
    def row_period(self) -> float | None:
        """The period (s) by which recorded rows are timed (``k * period``), or ``None``: by the
        SYNC frames' bus time stamps."""
        return None

    @abstractmethod
    def stream(self, network: canopen.Network, period: float, cycles: int,
               setpoints: SetpointFrames, poll: Callable[[], None]) -> None:
        """Start (free-running) or run (stepped) the SYNC of a stream of ``cycles`` cycles at
        ``period`` s; ``setpoints.send(k)`` sends the set-points of cycle k (``setpoints.table()``
        all of them as frames), ``poll()`` raises a pending fault. A free-running source sends
        those of cycle 0 and starts its timer; the caller sends the others when it sees each SYNC
        (:meth:`answers_on_sync`), or the source sends them itself. A stepped one returns after
        ``cycles + 1`` SYNCs (the last one closes the last row)."""

    def stop(self) -> None:
        """Stop the SYNC of the stream (a no-op for a stepped source)."""

    def report(self) -> SyncReport:
        """What the last stream's SYNC did, for the recording's metadata."""
        return SyncReport()


@dataclass(frozen=True)
class FrameTable:
    """Every cycle's RPDO frames of a stream, for a SYNC source that sends them itself (a timing
    process, :meth:`drivers.timing.TimedBus.start_stream`).

    Attributes:
        cob_ids: the COB-ID of each RPDO of a cycle, in the order they are sent.
        sizes: the length of each of those frames, bytes.
        data: the frames of all cycles, row k those of cycle k one after the other
            (``len(data) == cycles * sum(sizes)``).
    """

    cob_ids: tuple[int, ...]
    sizes: tuple[int, ...]
    data: bytes


class SetpointFrames(Protocol):
    """The set-points of a stream as RPDO frames (:class:`drivers.stream.TargetStreamer`)."""

    def send(self, k: int) -> None:
        """Send the set-points of cycle k (the last ones past the end)."""

    def table(self) -> FrameTable:
        """Every cycle's RPDO frames: their COB-IDs, their lengths (bytes) and the data of all
        cycles, row k the frames of cycle k one after the other."""


@dataclass(frozen=True)
class SyncReport:
    """What the SYNC of a stream did, for its recording's metadata; each source fills its own
    fields, the others stay ``None``.

    Args:
        sync_slots_skipped: SYNC slots a thread-timed periodic SYNC woke up too late for.
        sync_warning: the warning given before the stream (a thread-timed SYNC too fast).
        lockstep_retries: cycles a lockstep SYNC asked again (answers missing in time).
        lockstep_waited_out: cycles a lockstep SYNC gave up asking again and moved on from.
        timing: where the SYNC came from, in words (a timing process with its pid and
            scheduling, the bus's own timer, a thread of the master's process).
        master_longest_stall: s, the longest the master's own loop made no progress while a
            timing process streamed (what it survived).
        latest_sync: s, the latest a timing process sent a SYNC after its slot.
        latest_heartbeat: s, the latest it sent the master's heartbeat after its slot.
        timers_stopped_after: s the master's loop had made no progress when the timing process
            stopped the SYNC, the set-points and the heartbeat (None: it did not).
        sync_send_failures: SYNC and set-point frames the bus refused to the timing process.
        relay_dropped: frames the timing process could not keep for the master.
    """

    sync_slots_skipped: int | None = None
    sync_warning: str | None = None
    lockstep_retries: int | None = None
    lockstep_waited_out: int | None = None
    timing: str | None = None
    master_longest_stall: float | None = None
    latest_sync: float | None = None
    latest_heartbeat: float | None = None
    timers_stopped_after: float | None = None
    sync_send_failures: int | None = None
    relay_dropped: int | None = None


class PeriodicSync(SyncSource):
    """The SYNC of real drives, free-running on a time grid. On a bus opened through a timing
    process (:class:`drivers.timing.TimedBus`) that process sends the SYNC and every set-point
    from the stream's table, outside the master's process. Else ``network.send_periodic`` (the
    bus's timer, or a :class:`~drivers.bus.GridPeriodicTask` thread that skips the slots it woke
    up too late for) and the master's notifier answers each SYNC with the next set-points; a
    thread-timed SYNC faster than :data:`THREAD_LATE_BELOW` is warned about before the stream
    starts. The waits count in the time the master was running (:meth:`now`)."""

    name = "periodic"
    free_running = True

    def __init__(self) -> None:
        self._clock = WatchClock()
        self._task = None
        self._timed: Any = None              # the TimedBus streaming, if any
        self._report = SyncReport()
        self.warning: str | None = None    # the warning given before the last stream, if any

    def now(self) -> float:
        """The time the master was running (:class:`~drivers.supervision.WatchClock`): a wait's
        deadline (a state change, homing, a move) does not run out during a hold-up of the
        master's own process, when the drive's answers wait for it."""
        return self._clock.advance()

    def wait(self, seconds: float) -> None:
        time.sleep(seconds)

    def tick(self) -> None:
        time.sleep(TICK)

    def answers_on_sync(self, network) -> bool:
        return not _streams_itself(network)

    def stream(self, network, period, cycles, setpoints, poll) -> None:
        self.warning, self._report = None, SyncReport(timing=getattr(network, "timing", None))
        if _streams_itself(network):
            self._timed = network.bus
            frames = setpoints.table()
            self._timed.start_stream(period, SYNC_COB_ID, list(frames.cob_ids), list(frames.sizes), frames.data)
            return
        if period < THREAD_LATE_BELOW and not getattr(network, "timer_periodic", True):
            self.warning = (f"the SYNC at {1 / period:g} Hz is sent by a Python thread (this bus has no "
                            f"timer of its own): a thread is known to come late below "
                            f"{THREAD_LATE_BELOW * 1e3:g} ms; skipped slots are counted, a drive may "
                            f"see a following error. SocketCAN (the kernel's BCM), an adapter with "
                            f"a hardware timer or a timing process (bus.timing: process) sends it on time.")
            logger.warning("%s", self.warning)
        setpoints.send(0)
        self._task = network.send_periodic(SYNC_COB_ID, b"", period)

    def stop(self) -> None:
        if self._timed is not None:
            done = self._timed.stop_stream()
            self._report = dataclasses.replace(
                self._report, sync_slots_skipped=done.slots_skipped, master_longest_stall=done.longest_stall,
                latest_sync=done.latest_sync, latest_heartbeat=done.latest_heartbeat,
                timers_stopped_after=done.stopped_after, sync_send_failures=done.send_failures,
                relay_dropped=done.relay_dropped)
            if done.first_send_error:
                logger.warning("the bus refused %d SYNC or set-point frames to the timing process, the first: %s",
                               done.send_failures, done.first_send_error)
            self._timed = None
        if self._task is not None:
            self._task.stop()
            self._report = dataclasses.replace(self._report, sync_slots_skipped=getattr(self._task, "skipped", None),
                                               sync_warning=self.warning)
            self._task = None

    def report(self) -> SyncReport:
        return self._report


def _streams_itself(network) -> bool:
    """The network's bus streams a SYNC and its set-points itself (a timing process)."""
    return hasattr(getattr(network, "bus", None), "start_stream")
