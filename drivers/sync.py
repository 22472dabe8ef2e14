"""What paces the drives: the SYNC producer of a run and the time base of the master's waits.

A :class:`drivers.epos.DriveGroup` is given one :class:`SyncSource`. The drives sample, take
their set-points and move on the SYNC whenever it comes; the master's other waits (homing,
profile moves, state transitions) count in the source's time. :class:`PeriodicSync` is the one
for real drives: the SYNC from the bus's own timer where the interface has one (the kernel BCM on
SocketCAN, an adapter's hardware), else from a thread on a time grid
(:class:`drivers.bus.GridPeriodicTask`); the waits count in wall-clock time. Another source (a
simulated rig's, which paces the SYNC by the rig's answers) implements the same interface.

Every SYNC may carry the CiA 301 SYNC counter (1..240, object ``0x1019`` on a device).
"""

from __future__ import annotations

import logging
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Callable, Mapping

import canopen

from drivers.cia import SYNC_COB_ID

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
        """Raise :class:`ConfigError` when this source cannot stream at ``period`` s."""

    @property
    def row_period(self) -> float | None:
        """The period (s) by which recorded rows are timed (``k * period``), or ``None``: by the
        SYNC frames' bus time stamps."""
        return None

    @abstractmethod
    def stream(self, network: canopen.Network, period: float, cycles: int,
               send: Callable[[int], None], poll: Callable[[], None]) -> None:
        """Start (free-running) or run (stepped) the SYNC of a stream of ``cycles`` cycles at
        ``period`` s; ``send(k)`` sends the set-points of cycle k, ``poll()`` raises a pending
        fault. A free-running source sends those of cycle 0 and starts its timer; the caller sends
        the others when it sees each SYNC. A stepped one returns after ``cycles + 1`` SYNCs (the
        last one closes the last row)."""

    def stop(self) -> None:
        """Stop the SYNC of the stream (a no-op for a stepped source)."""

    def report(self) -> SyncReport:
        """What the last stream's SYNC did, for the recording's metadata."""
        return SyncReport()


@dataclass(frozen=True)
class SyncReport:
    """What the SYNC of a stream did, for its recording's metadata; each source fills its own
    fields, the others stay ``None``.

    Args:
        sync_slots_skipped: SYNC slots a thread-timed periodic SYNC woke up too late for.
        sync_warning: the warning given before the stream (a thread-timed SYNC too fast).
        lockstep_retries: cycles a lockstep SYNC asked again (answers missing in time).
        lockstep_waited_out: cycles a lockstep SYNC gave up asking again and moved on from.
    """

    sync_slots_skipped: int | None = None
    sync_warning: str | None = None
    lockstep_retries: int | None = None
    lockstep_waited_out: int | None = None


class PeriodicSync(SyncSource):
    """The SYNC of real drives: ``network.send_periodic`` (the bus's timer, else a
    :class:`~drivers.bus.GridPeriodicTask` thread that skips the slots it woke up too late for);
    the waits count in wall-clock time. A thread-timed SYNC faster than
    :data:`THREAD_LATE_BELOW` is warned about before the stream starts."""

    name = "periodic"
    free_running = True

    def __init__(self) -> None:
        self._task = None
        self._skipped: int | None = None   # the slots the last stream's thread-timed SYNC skipped
        self.warning: str | None = None    # the warning given before the last stream, if any

    def now(self) -> float:
        return time.monotonic()

    def wait(self, seconds: float) -> None:
        time.sleep(seconds)

    def tick(self) -> None:
        time.sleep(TICK)

    def stream(self, network, period, cycles, send, poll) -> None:
        self.warning, self._skipped = None, None
        if period < THREAD_LATE_BELOW and not getattr(network, "timer_periodic", True):
            self.warning = (f"the SYNC at {1 / period:g} Hz is sent by a Python thread (this bus has no "
                            f"timer of its own): a thread is known to come late below "
                            f"{THREAD_LATE_BELOW * 1e3:g} ms; skipped slots are counted, a drive may "
                            f"see a following error. SocketCAN (the kernel's BCM) or an adapter with "
                            f"a hardware timer sends it on time.")
            logger.warning("%s", self.warning)
        send(0)
        self._task = network.send_periodic(SYNC_COB_ID, b"", period)

    def stop(self) -> None:
        if self._task is not None:
            self._task.stop()
            self._skipped = getattr(self._task, "skipped", None)
            self._task = None

    def report(self) -> SyncReport:
        return SyncReport(sync_slots_skipped=self._skipped, sync_warning=self.warning)

