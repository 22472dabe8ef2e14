"""The timing process: where SYNC, a stream's set-points and the master's heartbeat are sent from
on a bus without a timer of its own (PCAN, Kvaser, Vector, slcan adapters, ``udp_multicast``),
in a small process of its own that no GIL hold, garbage collection or busy core of the master's
process can stop.

It owns the bus. It opens it, receives every frame and hands them to the master in batches
(while the master's process is held up they wait here, nothing is lost: its decoder catches up
afterwards), sends the frames the master asks it to (SDO, NMT), and runs the timers: periodic
frames (the master's heartbeat) and a stream, SYNC on the time grid ``start + k * period`` with
the set-points of cycle k+1 right after SYNC k, taken from the table the master gave it when the
stream started. A slot the timer wakes up too late for is skipped and counted (the grid of
:class:`drivers.bus.GridPeriodicTask`); after the table's last row the last set-points are sent
again until the master stops the stream.

The watch of the master: the master's own loop says it made progress (``alive``, sent at every
check of its supervision, :meth:`drivers.timing.TimedBus.alive`; every other command counts
too). While a timer runs, no word from the master for longer than the limit
(``master_progress``) stops every timer at once: no SYNC, no set-point, no heartbeat, so that
the drives' heartbeat consumer faults them (EMCY 0x8130) as it does when the master is gone. A
hold-up shorter than the limit is survived; a hang longer than it stops the drives within the
limit plus their consumer time. The timers stay stopped until the master starts one again.

Real-time priority (``SCHED_FIFO``) where the operating system grants it, while it serves (its
start-up and its ending run at normal priority); what it got is in the ``ready`` answer and so
in every recording's metadata.

The protocol (``python -m drivers.timing_server``, started by :class:`drivers.timing.TimedBus`):
on stdin the master's messages, each a 4-byte length and a pickled tuple, the first one the set-up
``(BusConfig, master_progress, priority)``; on stdout records of a kind byte and a 4-byte
length: ``FRAMES`` (a batch of :data:`FRAME` records) or ``ANSWER`` (a pickled tuple).
The process ends when the master closes the bus or its end of the pipe closes (its process
died).
"""

from __future__ import annotations

import math
import os
import pickle
import struct
import sys
import threading
import time

import can

from drivers.bus import open_bus

#: one frame handed to the master: bus time stamp (s), arbitration ID, flags (``EXTENDED``
#: ...), DLC, 8 data bytes
FRAME = struct.Struct("<dIBB8s")
EXTENDED, REMOTE, ERROR, RX = 1, 2, 4, 8
#: a record on stdout: its kind, the length of what follows
RECORD = struct.Struct("<BI")
FRAMES, ANSWER = 1, 2
#: a message on stdin: the length of the pickled tuple that follows
LENGTH = struct.Struct("<I")

#: s around the stream's next slot in which the receiving thread leaves the GIL to the timer (at
#: most a quarter of the period): a receiving thread that holds the GIL when the timer wakes, or
#: is preempted holding it on a busy host, made a normal-priority timing process skip 11 % of its
#: slots beside a busy loop per CPU; with the guard 0.2-0.5 %
GUARD = 0.001

#: s the timer sleeps at most: how often it looks at the master's last word while nothing is due
WATCH_STEP = 0.01

#: frames kept for the master at most while it does not read (44 MB, about 7 min of a 250 Hz
#: stream of six drives; a master silent for longer than its limit has stopped the stream long
#: before); more are dropped and counted
MAX_PENDING = 2_000_000


def pack_frame(msg: can.Message) -> bytes:
    """``msg`` as one :data:`FRAME` record."""
    flags = (EXTENDED * msg.is_extended_id | REMOTE * msg.is_remote_frame | ERROR * msg.is_error_frame
             | RX * msg.is_rx)
    return FRAME.pack(msg.timestamp, msg.arbitration_id, flags, msg.dlc, bytes(msg.data))


def unpack_frames(blob: bytes) -> list[can.Message]:
    """The messages of a batch of :data:`FRAME` records."""
    return [can.Message(timestamp=stamp, arbitration_id=cob_id, is_extended_id=bool(flags & EXTENDED),
                        is_remote_frame=bool(flags & REMOTE), is_error_frame=bool(flags & ERROR),
                        is_rx=bool(flags & RX), dlc=dlc, data=data[:dlc])
            for stamp, cob_id, flags, dlc, data in FRAME.iter_unpack(blob)]


def write_message(stream, message: tuple) -> None:
    """One message on the master's side of the pipe (:data:`LENGTH` and a pickle)."""
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(LENGTH.pack(len(data)) + data)
    stream.flush()


def read_exactly(stream, size: int) -> bytes:
    """``size`` bytes of ``stream``; EOFError when it ends before."""
    data = bytearray()
    while len(data) < size:
        chunk = stream.read(size - len(data))
        if not chunk:
            raise EOFError("the pipe closed")
        data += chunk
    return bytes(data)


def read_message(stream) -> tuple:
    """One message written by :func:`write_message`."""
    (size,) = LENGTH.unpack(read_exactly(stream, LENGTH.size))
    return pickle.loads(read_exactly(stream, size))


class _Periodic:
    """A frame sent every ``period`` s (the master's heartbeat)."""

    __slots__ = ("msg", "period", "due")

    def __init__(self, msg: can.Message, period: float, due: float):
        self.msg, self.period, self.due = msg, period, due


class _Stream:
    """SYNC every ``period`` s, the set-points of the next cycle after each: row k of ``table``
    (``len(cob_ids)`` RPDO frames of ``sizes`` bytes, one after the other) goes out after SYNC
    k-1 (row 0 before the first SYNC); after the last row, the last one again."""

    def __init__(self, period: float, sync_cob_id: int, cob_ids, sizes, table: bytes, start: float):
        self.period = period
        self.sync = can.Message(arbitration_id=sync_cob_id, data=b"", is_extended_id=False)
        self.cob_ids, self.sizes = list(cob_ids), list(sizes)
        self.row = sum(self.sizes)
        self.rows = len(table) // self.row if self.row else 0
        self.table = table
        self.sent = 0
        self.skipped = 0
        self.latest = 0.0          # s, the latest a SYNC went out after its slot
        self.due = start

    def setpoints(self, k: int) -> list[can.Message]:
        if not self.rows:
            return []
        start = min(k, self.rows - 1) * self.row
        frames = []
        for cob_id, size in zip(self.cob_ids, self.sizes):
            frames.append(can.Message(arbitration_id=cob_id, data=self.table[start:start + size], is_extended_id=False))
            start += size
        return frames


class _Server:
    """The threads of the timing process around one open bus (see the module docstring)."""

    def __init__(self, bus: can.BusABC, out, limit: float):
        self.bus = bus
        self.out = out
        self.limit = limit
        self.out_lock = threading.Lock()
        self.send_lock = threading.Lock()
        self.timer_lock = threading.Lock()
        self.wake = threading.Event()
        self.stopping = threading.Event()
        self.periodic: dict[int, _Periodic] = {}
        self.stream: _Stream | None = None
        self.last_word = time.monotonic()    # when the master last said anything
        self.longest_stall = 0.0             # s, the longest silence of the master while a timer ran
        self.latest_periodic = 0.0           # s, the latest a periodic frame went out after its slot
        self.stopped_after: float | None = None
        self.send_failures = 0
        self.first_send_error: str | None = None
        self.relay_dropped = 0
        self.next_slot = math.inf              # when the stream's next SYNC is due (monotonic s)
        self.slot_sent = threading.Event()     # set once it went out
        self.guard = GUARD                     # s around it that the receiving thread keeps out of
        self._pending = bytearray()
        self._pending_lock = threading.Lock()
        self._pending_ready = threading.Event()
        self._threads = [threading.Thread(target=self._receive, name="timing-receive", daemon=True),
                         threading.Thread(target=self._forward, name="timing-forward", daemon=True),
                         threading.Thread(target=self._time, name="timing-timer", daemon=True)]

    def start(self) -> None:
        for thread in self._threads:
            thread.start()

    def stop(self) -> None:
        self.stopping.set()
        self.wake.set()
        self._pending_ready.set()
        for thread in self._threads:
            thread.join(2.0)

    def answer(self, message: tuple) -> None:
        """An :data:`ANSWER` record to the master."""
        data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
        self._write(ANSWER, data)

    def _write(self, kind: int, data: bytes) -> None:
        with self.out_lock:
            self.out.write(RECORD.pack(kind, len(data)))
            self.out.write(data)
            self.out.flush()

    def send(self, msg: can.Message) -> bool:
        """Send ``msg``; a refusal of the bus is counted (the first one kept in words)."""
        try:
            with self.send_lock:
                self.bus.send(msg)
            return True
        except (can.CanError, OSError) as exc:
            self.send_failures += 1
            if self.first_send_error is None:
                self.first_send_error = f"0x{msg.arbitration_id:03X}: {exc}"
            return False

    # -- commands (the process's main thread) ------------------------------------------------------
    def handle(self, command: tuple) -> None:
        """Act on one message of the master (each one is a word from it: see the watch)."""
        self.last_word = time.monotonic()
        kind = command[0]
        if kind == "send":
            for msg in unpack_frames(command[1]):
                self.send(msg)
        elif kind == "periodic":
            _, key, cob_id, data, period = command
            msg = can.Message(arbitration_id=cob_id, data=bytes(data), is_extended_id=cob_id > 0x7FF)
            with self.timer_lock:
                self.stopped_after = None
                self.periodic[key] = _Periodic(msg, period, time.monotonic())
        elif kind == "periodic_data":
            _, key, data = command
            with self.timer_lock:
                task = self.periodic.get(key)
                if task is not None:
                    task.msg = can.Message(arbitration_id=task.msg.arbitration_id, data=bytes(data),
                                           is_extended_id=task.msg.is_extended_id)
        elif kind == "periodic_stop":
            with self.timer_lock:
                self.periodic.pop(command[1], None)
        elif kind == "stream":
            _, period, sync_cob_id, cob_ids, sizes, table = command
            with self.timer_lock:
                self.stopped_after = None
                self.longest_stall = self.latest_periodic = 0.0
                self.send_failures, self.first_send_error = 0, None
                stream = _Stream(period, sync_cob_id, cob_ids, sizes, table, time.monotonic())
                for msg in stream.setpoints(0):
                    self.send(msg)
                self.stream = stream
                self.guard = min(GUARD, 0.25 * period)
                self.next_slot = stream.due
        elif kind == "stream_stop":
            with self.timer_lock:
                stopped, self.stream = self.stream, None
                self.next_slot = math.inf
            self.answer(("stream_stopped", {
                "syncs_sent": stopped.sent if stopped else 0, "slots_skipped": stopped.skipped if stopped else 0,
                "latest_sync": stopped.latest if stopped else 0.0, "latest_heartbeat": self.latest_periodic,
                "send_failures": self.send_failures, "first_send_error": self.first_send_error,
                "longest_stall": self.longest_stall, "stopped_after": self.stopped_after,
                "relay_dropped": self.relay_dropped}))
        self.wake.set()

    # -- the timer --------------------------------------------------------------------------------
    def _time(self) -> None:
        while not self.stopping.is_set():
            with self.timer_lock:
                wait = WATCH_STEP
                if self.periodic or self.stream is not None:
                    silent = time.monotonic() - self.last_word
                    self.longest_stall = max(self.longest_stall, silent)
                    if silent > self.limit and self.stopped_after is None:
                        self._stop_timers(silent)
                if self.stream is not None:
                    wait = min(wait, self._stream_slot(self.stream))
                for task in self.periodic.values():
                    wait = min(wait, self._periodic_slot(task))
            if wait > 0:
                self.wake.wait(wait)
                self.wake.clear()

    def _stop_timers(self, silent: float) -> None:
        """The master made no progress for longer than the limit: every timer stops."""
        self.periodic.clear()
        if self.stream is not None:
            self.stream.due = math.inf      # kept for its counts until the master stops it
        self.stopped_after = silent
        self.next_slot = math.inf
        self.answer(("timers_stopped", silent))

    def _stream_slot(self, stream: _Stream) -> float:
        """SYNC and the next set-points if their slot has come; the s until the next slot."""
        now = time.monotonic()
        if now < stream.due:
            return stream.due - now
        stream.latest = max(stream.latest, now - stream.due)
        self.send(stream.sync)
        stream.sent += 1
        for msg in stream.setpoints(stream.sent):
            self.send(msg)
        stream.due, missed = _next_slot(stream.due, stream.period)
        stream.skipped += missed
        self.next_slot = stream.due
        self.slot_sent.set()
        return max(stream.due - time.monotonic(), 0.0)

    def _periodic_slot(self, task: _Periodic) -> float:
        now = time.monotonic()
        if now < task.due:
            return task.due - now
        self.latest_periodic = max(self.latest_periodic, now - task.due)
        self.send(task.msg)
        task.due, _ = _next_slot(task.due, task.period)
        return max(task.due - time.monotonic(), 0.0)

    # -- receiving and handing over ---------------------------------------------------------------
    def _receive(self) -> None:
        while not self.stopping.is_set():
            guard = self.guard
            lead = self.next_slot - time.monotonic()
            if -guard < lead < guard:       # the timer's slot is near: leave it the GIL
                self.slot_sent.wait(2 * guard)
                self.slot_sent.clear()
                continue
            try:
                msg = self.bus.recv(min(0.05, max(lead - guard, 0.0002)))
            except (can.CanError, OSError, ValueError):
                if self.stopping.is_set():
                    return
                time.sleep(0.05)
                continue
            if msg is None:
                continue
            record = pack_frame(msg)
            with self._pending_lock:
                if len(self._pending) < MAX_PENDING * FRAME.size:
                    self._pending += record
                else:
                    self.relay_dropped += 1
            self._pending_ready.set()

    def _forward(self) -> None:
        while not self.stopping.is_set():
            self._pending_ready.wait(0.1)
            self._pending_ready.clear()
            with self._pending_lock:
                blob, self._pending = self._pending, bytearray()
            if not blob:
                continue
            try:
                self._write(FRAMES, bytes(blob))   # blocks while the master does not read: frames wait here
            except (OSError, ValueError):
                self.stopping.set()                # the master is gone
                self.wake.set()
                return


def _next_slot(due: float, period: float) -> tuple[float, int]:
    """The slot after ``due`` on the grid of ``period``, skipping those the timer is already too
    late for (less than half a period ahead); returns it and how many were skipped."""
    due += period
    earliest = time.monotonic() + 0.5 * period
    if due >= earliest:
        return due, 0
    missed = math.ceil((earliest - due) / period)
    return due + missed * period, missed


def raise_priority(priority: int) -> str:
    """Ask for real-time scheduling (``SCHED_FIFO`` at ``priority``) for this process's threads
    (those started after it inherit it); say what it got."""
    if priority <= 0:
        return "normal priority (real-time not asked for)"
    if not hasattr(os, "sched_setscheduler"):
        return "normal priority (this operating system offers no SCHED_FIFO)"
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, ValueError) as exc:
        return f"normal priority (SCHED_FIFO {priority} refused: {getattr(exc, 'strerror', None) or exc})"
    return f"real-time, SCHED_FIFO {priority}"


def drop_priority() -> None:
    """Back to normal scheduling (``SCHED_OTHER``) for the calling thread, where it had more."""
    if hasattr(os, "sched_setscheduler"):
        try:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        except (OSError, ValueError):
            pass


def serve(commands, out) -> None:
    """The timing process: the set-up from ``commands`` (binary stdin), open the bus, answer
    ``("ready", pid, scheduling)`` (or ``("failed", why)``) on ``out`` (binary stdout), then act
    on the master's messages until it closes the bus or is gone."""
    config, limit, priority = read_message(commands)
    try:
        bus = open_bus(config)
    except Exception as exc:   # noqa: BLE001 - whatever opening the adapter raises goes to the master
        data = pickle.dumps(("failed", str(exc)))
        out.write(RECORD.pack(ANSWER, len(data)) + data)
        out.flush()
        return
    # real-time only while it serves: its start-up (opening the bus imports its interface) and its
    # ending are CPU-bound work that, at SCHED_FIFO, held the CPU from any other real-time process
    # of its priority on it, e.g. another master's timing process in the middle of its stream,
    # which then skipped its SYNC slots (~30 ms each time; tests/test_timing_process.py)
    scheduling = raise_priority(priority)
    server = _Server(bus, out, limit)
    server.start()
    server.answer(("ready", os.getpid(), scheduling))
    try:
        while not server.stopping.is_set():
            try:
                command = read_message(commands)
            except (EOFError, OSError, pickle.UnpicklingError):
                break                       # the master's process is gone
            if command[0] == "close":
                break
            server.handle(command)
    finally:
        drop_priority()            # the ending (threads joined, the interpreter torn down) as any process's
        server.stop()
        bus.shutdown()


def main() -> None:
    """``python -m drivers.timing_server``: the protocol on stdin and stdout; anything else this
    process prints (a library's warning) goes to stderr, not into the protocol."""
    out = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    serve(sys.stdin.buffer, out)


if __name__ == "__main__":
    main()
