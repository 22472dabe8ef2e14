"""Collecting the faults that must stop a run: EMCY, heartbeat, statusword bits, bus errors.

The callbacks of the notifier thread (EMCY, heartbeat, the assembler's statusword check) only
*report* a fault here; the controlling thread polls :meth:`Supervisor.raise_if_fault` in every
wait loop, stops the motion (quick stop, disable — over SDO, outside any callback) and raises.
Only the first fault is kept: later ones are usually consequences of it.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from typing import Callable

import can
from canopen.nmt import NMT_STATES

from drivers.emcy import describe
from drivers.errors import BusError, ConfigError, DriveFault, HeartbeatTimeout

logger = logging.getLogger(__name__)

#: s: the most a gap between two heartbeat checks of the controlling thread counts as silence. The
#: wait loops check every few ms to 50 ms; a longer gap means the master's own process did not run
#: (a loaded host, a thread holding the GIL for seconds, as a compilation does), when the drives'
#: heartbeats cannot be received either: that is not a silent node. A node silent while the master
#: runs still times out after its consumer timeout of checked time.
MAX_UNWATCHED = 0.1


#: heartbeat periods: the default of both heartbeat timeouts (:class:`Watchdogs`)
HEARTBEAT_PERIODS = 3.5
#: s without a new SYNC cycle of the master's watched time before it stops a stream (default)
SYNC_PROGRESS = 1.0
#: s without progress of the master's own loop before a timing process stops the SYNC, the
#: set-points and the heartbeat (default): twice the longest hold-ups seen on loaded lab PCs (the
#: issue-50 rehearsal froze a master 2.18 s at load 9; a 1 s GIL hold at load 8 once became
#: 3 s without a word, benchmarks/README.md), so that a loaded host does not stop a run, while a
#: hung master's drives still fault within seconds
MASTER_PROGRESS = 5.0


@dataclass(frozen=True)
class Watchdogs:
    """Every time limit that stops a run when one side goes silent, in s (``None``: the default
    given with each).

    Args:
        heartbeat_period: the drives' producer heartbeat time (``0x1017``) and the master's.
        drive_heartbeat: the master stops the run when a drive's heartbeat is this late on the
            time it was running and watching (:class:`WatchClock`; in lockstep the simulated
            time). Default :data:`HEARTBEAT_PERIODS` periods: three heartbeats lost in a row (a
            drive's heartbeat comes from its firmware, on time).
        master_heartbeat: every drive's consumer time of the master's heartbeat (``0x1016:01``):
            a drive faults (EMCY 0x8130) when the master's heartbeat is this late. Default
            :data:`HEARTBEAT_PERIODS` periods likewise: the master's heartbeat comes from a timer
            outside its process where the bus allows (a timing process, the kernel's BCM).
        sync_progress: the master stops a stream when no new SYNC cycle came for this long of the
            time it was running and watching (a hold-up of its own process does not count).
        master_progress: a timing process stops the SYNC, the set-points and the master's
            heartbeat when the master's own loop made no progress for this long
            (:class:`drivers.timing.TimingConfig`), so that the drives see a hung master.
    """

    heartbeat_period: float = 0.1
    drive_heartbeat: float | None = None
    master_heartbeat: float | None = None
    sync_progress: float = SYNC_PROGRESS
    master_progress: float = MASTER_PROGRESS

    def __post_init__(self) -> None:
        for name in ("drive_heartbeat", "master_heartbeat"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, HEARTBEAT_PERIODS * self.heartbeat_period)
        period = self.heartbeat_period
        if not (period > 0 and round(period * 1e3) >= 1):
            raise ConfigError(f"heartbeat period: at least 1 ms, got {period!r} s")
        for name in ("drive_heartbeat", "master_heartbeat"):
            value = getattr(self, name)
            if not (value > period and 1 <= round(value * 1e3) <= 0xFFFF):
                raise ConfigError(f"{name} timeout: need heartbeat period < timeout <= 65.535 s, got {value!r} s "
                                  f"(period {period!r} s)")
        for name in ("sync_progress", "master_progress"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"{name}: a positive time in s, got {getattr(self, name)!r}")

    @property
    def drive_timeout(self) -> float:
        """``drive_heartbeat`` in s, its default filled in (never None once built)."""
        return _filled(self.drive_heartbeat)

    @property
    def master_timeout(self) -> float:
        """``master_heartbeat`` in s, its default filled in (never None once built)."""
        return _filled(self.master_heartbeat)


def _filled(value: float | None) -> float:
    """A heartbeat timeout :class:`Watchdogs` filled in on construction."""
    if value is None:
        raise ConfigError("heartbeat timeout not filled in (Watchdogs.__post_init__ fills both)")
    return value


class WatchClock:
    """The time the master was running and watching, s: wall-clock time of which a gap between
    two :meth:`advance` calls counts at most ``cap`` s (:data:`MAX_UNWATCHED`), so that a
    hold-up of the master's own process is not taken for a silence of what it watches."""

    #: a wall clock: the heartbeat watch also asks the bus's time (:meth:`Supervisor.check_heartbeats`)
    wall_clock = True

    def __init__(self, cap: float = MAX_UNWATCHED) -> None:
        self.cap = cap
        self._watched = 0.0
        self._last = time.monotonic()

    def advance(self) -> float:
        """The watch time now, advanced (the controlling thread's checks)."""
        now = time.monotonic()
        self._watched += min(now - self._last, self.cap)
        self._last = now
        return self._watched

    def peek(self) -> float:
        """The watch time now, without advancing it (any thread): the time since the last
        :meth:`advance`, capped, added."""
        return self._watched + min(time.monotonic() - self._last, self.cap)


class BusTime(can.Listener):
    """The bus time stamp (s) of the latest frame the master's notifier has handled: the bus's own
    clock as far as the master has read it. A hold-up of the master's process stops it too, and
    it catches up with the backlog, so that a gap in it is a gap on the bus, not in the master."""

    def __init__(self) -> None:
        self.latest: float | None = None

    def on_message_received(self, msg: can.Message) -> None:
        if self.latest is None or msg.timestamp > self.latest:
            self.latest = msg.timestamp


class Supervisor:
    """Thread-safe collector of the first fault, and the heartbeat consumer of the master.

    Args:
        clock: the clock the drives' heartbeat timeouts count in (``advance()`` at a check,
            ``peek()`` when a heartbeat comes): a :class:`WatchClock` (the default), or a
            simulated rig's SYNC time (:meth:`drivers.sync.SyncSource.watch_clock`).
        alive: called at every check of the controlling thread: the master's own loop made
            progress (a timing process watches it, :meth:`drivers.bus.BusNetwork.alive`).
    """

    def __init__(self, clock=None, alive: Callable[[], None] | None = None) -> None:
        self._lock = threading.Lock()
        self._fault: DriveFault | None = None
        self.fault_event = threading.Event()
        self._heartbeats: dict[str, list] = {}  # label -> [timeout s, last reception: watch time, bus time]
        self.heartbeat_active = False
        self.clock = clock if clock is not None else WatchClock()
        self._alive = alive or (lambda: None)
        #: the bus's time as the master read it (a listener of its notifier, :class:`BusTime`)
        self.bus_time = BusTime()

    # -- reporting (any thread) ---------------------------------------------------------------
    def report(self, fault: DriveFault) -> None:
        """Record ``fault`` unless an earlier one is already pending."""
        with self._lock:
            if self._fault is None:
                self._fault = fault
                self.fault_event.set()
                logger.error("fault: %s", fault)
            else:
                logger.warning("further fault (ignored, first one pending): %s", fault)

    def emcy_callback(self, label: str, profile: str):
        """A callback for :meth:`canopen.emcy.EmcyConsumer.add_callback` of node ``label``."""
        def on_emcy(entry) -> None:
            if entry.code & 0xFF00 == 0:  # error reset / no error
                return
            self.report(DriveFault(label, entry.code, f"EMCY: {describe(entry.code, profile)} "
                                   f"(error register 0x{entry.register:02X})"))
        return on_emcy

    def bus_error(self, text: str) -> None:
        self.report(BusError(text))

    # -- heartbeat consumer --------------------------------------------------------------------
    def watch_heartbeat(self, label: str, network, node_id: int, timeout: float) -> None:
        """Expect a heartbeat of node ``label`` (``node_id`` on ``network``) at least every
        ``timeout`` s once active.

        While ``heartbeat_active`` is set, a heartbeat reporting a state other than
        OPERATIONAL is a fault too (the node was reset or stopped).
        """
        if label in self._heartbeats:
            raise ValueError(f"{label}: heartbeat already watched")
        entry = self._heartbeats[label] = [timeout, None, None]

        def on_heartbeat(can_id: int, data: bytes, timestamp: float) -> None:
            entry[1], entry[2] = self.clock.peek(), timestamp
            state = data[0] & 0x7F if data else None
            if self.heartbeat_active and state != 5:
                named = None if state is None else NMT_STATES.get(state, state)
                self.report(DriveFault(label, None, f"heartbeat reports NMT state {named} instead of OPERATIONAL"))
        network.subscribe(0x700 + node_id, on_heartbeat)

    def start_heartbeat_monitoring(self) -> None:
        """Start counting the consumer timeouts from now."""
        now = self.clock.advance()
        for entry in self._heartbeats.values():
            entry[1] = now if entry[1] is None else max(entry[1], now)
            entry[2] = self.bus_time.latest
        self.heartbeat_active = True

    def stop_heartbeat_monitoring(self) -> None:
        self.heartbeat_active = False

    def check_heartbeats(self) -> None:
        """Report a :class:`HeartbeatTimeout` for the first node whose heartbeat is overdue on the
        watch clock (the time the master was running and checking, :data:`MAX_UNWATCHED`; in
        lockstep the simulated time) and, on a wall-clock watch, on the bus's own time as far as
        the master has read it (:class:`BusTime`): after a hold-up of the master's process its
        notifier works through the frames that waited, and a heartbeat it reaches late was not
        late on the bus. Every call is a sign of the master's progress (``alive``)."""
        self._alive()
        if not self.heartbeat_active:
            return
        now = self.clock.advance()
        bus_now = self.bus_time.latest if getattr(self.clock, "wall_clock", False) else None
        for label, (timeout, last, last_on_bus) in self._heartbeats.items():
            if last is None or now - last <= timeout:
                continue
            if bus_now is not None and last_on_bus is not None and bus_now - last_on_bus <= timeout:
                continue            # the master is behind the bus, not the node
            on_bus = "" if bus_now is None or last_on_bus is None else f", {bus_now - last_on_bus:.3f} s on the bus"
            self.report(HeartbeatTimeout(label, 0x8130, f"no heartbeat for {now - last:.3f} s{on_bus} "
                                         f"(consumer timeout {timeout:.3f} s)"))
            return

    # -- controlling thread -----------------------------------------------------------------------
    @property
    def fault(self) -> DriveFault | None:
        return self._fault

    def raise_if_fault(self) -> None:
        """Check heartbeats, then raise the pending fault, if any."""
        self.check_heartbeats()
        if self._fault is not None:
            raise self._fault

    def clear(self) -> DriveFault | None:
        """Forget the pending fault (after the drives were reset); return it."""
        with self._lock:
            fault, self._fault = self._fault, None
            self.fault_event.clear()
        return fault
