"""Where the master's timers run: threads of its own process, the bus's timer, or a timing process
beside it (:mod:`drivers.timing_server`).

A bus without a timer of its own (python-can gives the adapters of most lab PCs, PCAN, Kvaser,
Vector, slcan, only a Python thread, and ``udp_multicast`` too) would have the SYNC, the
set-points and the master's heartbeat sent by threads of the master's process, which a GIL hold,
a garbage collection or a busy core stops together with everything else: the drives then see the
heartbeat pause and fault. Where the kernel sends the SYNC and the heartbeat (SocketCAN's BCM)
the set-points still come from the master's notifier, which answers each SYNC: held up, it
leaves the drives on their last set-point, then sends the ones it owes in a burst, and the
drive's target jumps by the hold-up's share of the trajectory.

:class:`TimedBus` is a bus seen through a timing process that owns it: the master's process sends
and receives as on any python-can bus, the timing process keeps the timers and hands every frame
over, nothing lost while the master is held up. It also watches the master's own loop
(:meth:`TimedBus.alive`) and stops every timer when the loop has made no progress for
``TimingConfig.master_progress`` s. :class:`TimingConfig` says which buses get one
(:meth:`TimingConfig.uses_process`); :func:`drivers.bus.open_network` opens the bus through it.
"""

from __future__ import annotations

import logging
import os
import pickle
import queue
import subprocess
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import can

from drivers.bus import BusConfig, open_bus
from drivers.errors import BusOpenError, ConfigError
from drivers.supervision import MASTER_PROGRESS
from drivers.timing_server import FRAME, FRAMES, RECORD, pack_frame, read_exactly, unpack_frames, write_message

logger = logging.getLogger(__name__)

#: s the master gives the timing process to start and open the bus (a new interpreter, its imports)
START_TIMEOUT = 60.0
#: s the timing process gets to end once asked to, before it is terminated
STOP_TIMEOUT = 5.0
#: real-time priority asked for (``SCHED_FIFO``, 1..99): above every ordinary process, below the
#: kernel's interrupt threads (50)
PRIORITY = 20

#: where the timers of a periodic SYNC run: ``process`` (a timing process that owns the bus),
#: ``thread`` (the bus's own timer where it has one, SocketCAN's BCM, else a thread of the
#: master's process; the set-points from the master's notifier either way), ``auto``
#: (``process`` on every bus another process can open, i.e. anything but python-can's
#: in-process ``virtual``)
TIMINGS = ("auto", "process", "thread")


@dataclass(frozen=True)
class TimingConfig:
    """How the master's timers are kept.

    Args:
        where: one of :data:`TIMINGS`.
        master_progress: s the master's own loop may make no progress before the timing process
            stops the SYNC, the set-points and the heartbeat (so that the drives fault).
        priority: ``SCHED_FIFO`` priority of the timing process (0: none asked for).
    """

    where: Literal["auto", "process", "thread"] = "auto"
    master_progress: float = MASTER_PROGRESS
    priority: int = PRIORITY

    def __post_init__(self) -> None:
        if self.where not in TIMINGS:
            raise ConfigError(f"timing must be one of {TIMINGS}, got {self.where!r}")
        if not self.master_progress > 0:
            raise ConfigError(f"master_progress must be positive, got {self.master_progress!r} s")

    def open(self, config: BusConfig) -> can.BusABC:
        """The bus ``config``, through a timing process where :meth:`uses_process`, else opened
        here (:func:`drivers.bus.open_bus`)."""
        return TimedBus(config, self) if self.uses_process(config) else open_bus(config)

    def uses_process(self, config: BusConfig) -> bool:
        """Whether the bus ``config`` gets a timing process."""
        if config.interface == "virtual":
            if self.where == "process":
                raise ConfigError("a python-can 'virtual' bus only reaches its own process: it cannot "
                                  "have a timing process (timing: thread)")
            return False
        return self.where in ("auto", "process")


@dataclass(frozen=True)
class StreamReport:
    """What the timing process did during a stream.

    Args:
        syncs_sent: SYNC frames sent.
        slots_skipped: grid slots its timer woke up too late for.
        latest_sync: s, the latest a SYNC went out after its slot.
        latest_heartbeat: s, the latest a periodic frame (the master's heartbeat) went out after
            its slot.
        send_failures: frames the bus refused (SYNC or set-points).
        first_send_error: the first of them, in words.
        longest_stall: s, the longest the master's loop made no progress meanwhile.
        stopped_after: s the master had made no progress when the timing process stopped the
            SYNC (None: it did not).
        relay_dropped: frames the master did not take in time (the process's buffer full).
    """

    syncs_sent: int
    slots_skipped: int
    latest_sync: float
    latest_heartbeat: float
    send_failures: int
    first_send_error: str | None
    longest_stall: float
    stopped_after: float | None
    relay_dropped: int


class TimedPeriodic:
    """A frame the timing process sends every ``period`` s: ``stop()``, ``update(data)``."""

    def __init__(self, bus: TimedBus, key: int):
        self._bus, self._key = bus, key

    def update(self, data: bytes) -> None:
        self._bus._command(("periodic_data", self._key, bytes(data)))

    def stop(self) -> None:
        self._bus._command(("periodic_stop", self._key))


class TimedBus(can.BusABC):
    """The bus ``config`` opened by a timing process (``python -m drivers.timing_server``) and
    seen through it: ``send`` and ``recv`` as on the bus itself (the frames the timing
    process sends come back as its own, as with ``receive_own_messages``), :meth:`periodic` and
    :meth:`start_stream` timed there.

    A reader thread takes the timing process's output (frame batches, answers) off the pipe; the
    frames wait in the pipe and in the timing process while the master's process is held up.

    Args:
        config: the bus; the timing process opens it.
        timing: the watch of the master's loop and the process's priority.

    Raises:
        BusOpenError: the timing process could not open the bus, or did not start.
    """

    #: timers outside the master's process (:attr:`drivers.bus.BusNetwork.timer_periodic`)
    own_timer = True
    #: s between two words to the timing process when nothing else is sent (:meth:`alive`)
    ALIVE_SPACING = 0.02

    def __init__(self, config: BusConfig, timing: TimingConfig = TimingConfig()):
        self.timing = timing
        self._lock = threading.Lock()
        self._frames: queue.SimpleQueue = queue.SimpleQueue()     # lists of messages, one per batch
        self._batch: deque[can.Message] = deque()
        self._answers: queue.SimpleQueue = queue.SimpleQueue()
        self._next_key = 0
        self._last_word = 0.0
        self._closed = False
        self.stopped_after: float | None = None    # the timing process stopped its timers (s of silence)
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [_PACKAGE_ROOT, os.environ.get("PYTHONPATH")])))
        self._process = subprocess.Popen([sys.executable, "-m", "drivers.timing_server"], stdin=subprocess.PIPE,
                                         stdout=subprocess.PIPE, env=env)
        self._reader = threading.Thread(target=self._read, name="timing-reader", daemon=True)
        self._reader.start()
        self._command((config, timing.master_progress, timing.priority))
        answer = self._answer(START_TIMEOUT, ("ready", "failed"))
        if answer is None or answer[0] == "failed":
            self._end()
            raise BusOpenError(answer[1] if answer else
                               f"cannot open CAN bus interface={config.interface!r} channel={config.channel!r}: "
                               f"its timing process did not start within {START_TIMEOUT:g} s")
        _, self.pid, self.scheduling = answer
        self.description = f"a timing process of its own (pid {self.pid}, {self.scheduling})"
        if timing.priority > 0 and not self.scheduling.startswith("real-time"):
            logger.warning("the timing process runs at %s: on a busy host its SYNC comes late and slots are "
                           "skipped (about 6 %% beside a busy loop per CPU, benchmarks/README.md). Allow it real-time "
                           "priority: `ulimit -r` %d or more for the user (e.g. a line '<user> - rtprio %d' in "
                           "/etc/security/limits.d/), or run with CAP_SYS_NICE", self.scheduling, timing.priority,
                           timing.priority)
        super().__init__(channel=config.channel)
        self.channel_info = f"{config.interface}:{config.channel} through {self.description}"

    # -- the master's side -------------------------------------------------------------------------
    def alive(self) -> None:
        """The master's loop made progress: a word to the timing process, whose watch then counts
        from now (at most one every :attr:`ALIVE_SPACING` s; every other command counts too)."""
        if time.monotonic() - self._last_word >= self.ALIVE_SPACING:
            self._command(("alive",))

    def _command(self, command: tuple) -> None:
        try:
            with self._lock:
                write_message(self._process.stdin, command)
                self._last_word = time.monotonic()
        except (OSError, ValueError) as exc:
            raise can.CanOperationError(f"the timing process is gone ({exc})") from exc

    def _read(self) -> None:
        """The reader thread: frame batches to :meth:`_recv_internal`, answers to :meth:`_answer`."""
        stream = self._process.stdout
        try:
            while True:
                kind, size = RECORD.unpack(read_exactly(stream, RECORD.size))
                data = read_exactly(stream, size)
                if kind == FRAMES:
                    self._frames.put(unpack_frames(data))
                    continue
                answer = pickle.loads(data)
                if answer[0] == "timers_stopped":
                    self.stopped_after = answer[1]
                    logger.error("the timing process stopped SYNC, set-points and heartbeat: the master's "
                                 "loop made no progress for %.2f s (limit %g s)", answer[1],
                                 self.timing.master_progress)
                self._answers.put(answer)
        except (EOFError, OSError, ValueError, pickle.UnpicklingError):
            self._frames.put(None)      # the end: recv raises unless the bus was closed
            self._answers.put(None)

    def _answer(self, timeout: float, kinds: tuple[str, ...]):
        """The next answer of one of ``kinds`` (others are passed over), or None."""
        deadline = time.monotonic() + timeout
        while (left := deadline - time.monotonic()) > 0:
            try:
                answer = self._answers.get(timeout=left)
            except queue.Empty:
                return None
            if answer is None:
                return None
            if answer[0] in kinds:
                return answer
        return None

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Have the timing process send ``msg`` (in the order of the calls)."""
        self._command(("send", pack_frame(msg)))

    def _recv_internal(self, timeout: float | None):
        if not self._batch:
            try:
                batch = self._frames.get(timeout=timeout)
            except queue.Empty:
                return None, False
            if batch is None:
                self._frames.put(None)
                if self._closed:
                    return None, False
                raise can.CanOperationError("the timing process ended")
            self._batch.extend(batch)
        return self._batch.popleft(), False

    def periodic(self, can_id: int, data: bytes, period: float) -> TimedPeriodic:
        """Have the timing process send a frame every ``period`` s, from now on."""
        if not period > 0:
            raise ValueError(f"period must be positive, got {period!r}")
        self._next_key += 1
        self.stopped_after = None
        self._command(("periodic", self._next_key, can_id, bytes(data), period))
        return TimedPeriodic(self, self._next_key)

    def start_stream(self, period: float, sync_cob_id: int, rpdos: list[int], sizes: list[int], table: bytes) -> None:
        """Start a stream: SYNC every ``period`` s; before SYNC 0 and after SYNC k-1 the RPDO frames
        of row k of ``table`` (``rpdos`` their COB-IDs, ``sizes`` their lengths in bytes, one after
        the other in each row), the last row again after the table's end."""
        self.stopped_after = None
        self._command(("stream", period, sync_cob_id, list(rpdos), list(sizes), bytes(table)))

    def stop_stream(self) -> StreamReport:
        """Stop the stream; what the timing process did meanwhile."""
        self._command(("stream_stop",))
        answer = self._answer(STOP_TIMEOUT, ("stream_stopped",))
        if answer is None:
            return StreamReport(0, 0, 0.0, 0.0, 0, "the timing process did not answer", 0.0, self.stopped_after, 0)
        return StreamReport(**answer[1])

    def shutdown(self) -> None:
        if self._closed:
            return
        try:
            self._command(("close",))
        except can.CanOperationError:
            pass
        self._end()
        super().shutdown()

    def _end(self) -> None:
        self._closed = True
        try:
            if self._process.stdin is not None:
                self._process.stdin.close()
        except OSError:
            pass
        try:
            self._process.wait(STOP_TIMEOUT)
        except subprocess.TimeoutExpired:
            self._process.terminate()
            self._process.wait(STOP_TIMEOUT)
        self._reader.join(STOP_TIMEOUT)
        if self._process.stdout is not None:
            self._process.stdout.close()


#: the folder holding the package :mod:`drivers`, first on the timing process's path (so that it
#: imports this installation's drivers whatever the working directory)
_PACKAGE_ROOT = str(Path(__file__).resolve().parent.parent)


__all__ = ["FRAME", "PRIORITY", "StreamReport", "TIMINGS", "TimedBus", "TimingConfig"]
