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

from canopen.nmt import NMT_STATES

from drivers.emcy import describe
from drivers.errors import BusError, DriveFault, HeartbeatTimeout

logger = logging.getLogger(__name__)

#: s: the most a gap between two heartbeat checks of the controlling thread counts as silence. The
#: wait loops check every few ms to 50 ms; a longer gap means the master's own process did not run
#: (a loaded host, a thread holding the GIL for seconds, as a compilation does), when the drives'
#: heartbeats cannot be received either: that is not a silent node. A node silent while the master
#: runs still times out after its consumer timeout of checked time.
MAX_UNWATCHED = 0.1


class Supervisor:
    """Thread-safe collector of the first fault, and the heartbeat consumer of the master."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._fault: DriveFault | None = None
        self.fault_event = threading.Event()
        self._heartbeats: dict[str, list] = {}  # label -> [timeout s, last reception (watch time) or None]
        self.heartbeat_active = False
        self._watched = 0.0                     # s of watch time: checked time, gaps capped (MAX_UNWATCHED)
        self._last_check = time.monotonic()

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
    def watch_heartbeat(self, label: str, nmt, timeout: float) -> None:
        """Expect a heartbeat of node ``label`` at least every ``timeout`` s once active.

        While :attr:`heartbeat_active` is set, a heartbeat reporting a state other than
        OPERATIONAL is a fault too (the node was reset or stopped).
        """
        if label in self._heartbeats:
            raise ValueError(f"{label}: heartbeat already watched")
        entry = self._heartbeats[label] = [timeout, None]

        def on_heartbeat(state: int) -> None:
            entry[1] = self._watch_time()
            if self.heartbeat_active and state != 5:
                self.report(DriveFault(label, None, "heartbeat reports NMT state "
                                       f"{NMT_STATES.get(state, state)} instead of OPERATIONAL"))
        nmt.add_heartbeat_callback(on_heartbeat)

    def _watch_time(self) -> float:
        """The watch clock now (s): the checked time so far plus the time since the last check,
        capped at :data:`MAX_UNWATCHED` (read from any thread; only a check advances it)."""
        return self._watched + min(time.monotonic() - self._last_check, MAX_UNWATCHED)

    def _advance_watch(self) -> float:
        now = time.monotonic()
        self._watched += min(now - self._last_check, MAX_UNWATCHED)
        self._last_check = now
        return self._watched

    def start_heartbeat_monitoring(self) -> None:
        """Start counting the consumer timeouts from now."""
        now = self._advance_watch()
        for entry in self._heartbeats.values():
            entry[1] = now if entry[1] is None else max(entry[1], now)
        self.heartbeat_active = True

    def stop_heartbeat_monitoring(self) -> None:
        self.heartbeat_active = False

    def check_heartbeats(self) -> None:
        """Report a :class:`HeartbeatTimeout` for the first node whose heartbeat is overdue on the
        watch clock (the time the master was running and checking, :data:`MAX_UNWATCHED`)."""
        if not self.heartbeat_active:
            return
        now = self._advance_watch()
        for label, (timeout, last) in self._heartbeats.items():
            if last is not None and now - last > timeout:
                self.report(HeartbeatTimeout(label, 0x8130, f"no heartbeat for {now - last:.3f} s "
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
