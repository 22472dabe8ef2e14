"""PDO layout of a streaming run and the assembly of one sample per SYNC cycle.

The master maps, per drive (see :func:`pdo_layout`):

* TPDO1, SYNC-triggered: position actual (I32) + current actual (I16 on EPOS2, I32 on EPOS4),
  plus the statusword on EPOS2 (4 + 2 + 2 = 8 bytes);
* TPDO2 on EPOS4 only: statusword, event-driven with an event timer (the I32 + I32 of TPDO1
  leave no room for it);
* TPDO3, SYNC-triggered (optional): velocity actual (I32);
* RPDO1, applied on the next SYNC: cyclic set-point (I32) + controlword (U16).

:class:`CycleAssembler` is a :class:`can.Listener` that cuts the received traffic into SYNC
cycles: the SYNC frame (received back with ``receive_own_messages``, or from the kernel BCM on
SocketCAN) opens a cycle and gives its timestamp; the SYNC-triggered TPDOs received until the
next SYNC fill it; the RPDO echoes seen in a cycle are the set-points the drives take over at
the next SYNC, so they become the ``target`` of the next row. A cycle that misses a frame, or
receives one twice (a late frame of the previous cycle), is flagged invalid for that axis and
its values are left out — never filled from an earlier cycle. A SYNC that repeats the counter of
the open cycle (a lockstep retry, :mod:`drivers.sync`) opens no new cycle; the TPDOs answering it
are the same frames again and are taken as such (a different frame is still a late one). In
lockstep (``period`` given) a row's time is its cycle index times the period: the simulated time. The EPOS4 statusword, which is
event-driven by design, is reported as the last value received.

Decoding uses precompiled :class:`struct.Struct` s; the listener runs in the notifier thread and
never calls SDO: it only sends PDO frames (through ``on_sync``) and hands finished rows to a sink.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Callable, Sequence

import can

from drivers.bus import SYNC_COB_ID
from drivers.profiles import DriveProfile, ObjectRef

#: fields of a sample, in drive units
FIELDS = ("position", "velocity", "current", "statusword", "target")

_STRUCT_CODES = {"INTEGER8": "b", "UNSIGNED8": "B", "INTEGER16": "h", "UNSIGNED16": "H",
                 "INTEGER32": "i", "UNSIGNED32": "I"}

STATUS_FAULT = 0x0008  # statusword bit 3
STATUS_FOLLOWING_ERROR = 0x2000  # statusword bit 13 (homing error in HMM)


@dataclass(frozen=True)
class PdoFrame:
    """One PDO of one drive: which objects it carries and how it is triggered.

    Args:
        direction: ``"tpdo"`` (drive -> master) or ``"rpdo"`` (master -> drive).
        number: PDO number 1..4.
        entries: ``(field, object)`` pairs in mapping order; field is one of :data:`FIELDS`
            or ``"controlword"``.
        trans_type: CiA 301 transmission type (1 = every SYNC, 255 = event-driven).
        event_timer: event timer in ms for event-driven TPDOs (``None`` for none).
    """

    direction: str
    number: int
    entries: tuple[tuple[str, ObjectRef], ...]
    trans_type: int
    event_timer: int | None = None

    def cob_id(self, node_id: int) -> int:
        base = 0x180 if self.direction == "tpdo" else 0x200
        return base + 0x100 * (self.number - 1) + node_id

    @property
    def struct(self) -> struct.Struct:
        return struct.Struct("<" + "".join(_STRUCT_CODES[ref.data_type] for _, ref in self.entries))

    @property
    def size(self) -> int:
        return self.struct.size

    @property
    def per_sync(self) -> bool:
        """Sent once per SYNC cycle (SYNC-triggered TPDO, or an RPDO of the set-point stream)."""
        return self.direction == "rpdo" or 1 <= self.trans_type <= 240


def pdo_layout(profile: DriveProfile, with_velocity: bool = True) -> tuple[PdoFrame, ...]:
    """The PDOs the master configures on a drive of ``profile`` for a streaming run.

    Every TPDO is SYNC-triggered: TPDO1 = position + current (+ statusword where it fits: the
    EPOS2's 16-bit current); else the statusword travels in TPDO2 with the velocity (6 bytes), or
    alone without the velocity. No event timer is used: a real EPOS4 has none on its TPDOs.
    """
    frames = []
    status_in_first = profile.current_actual.bits + profile.position_actual.bits + profile.statusword.bits <= 64
    first = (("position", profile.position_actual), ("current", profile.current_actual))
    if status_in_first:
        first += (("statusword", profile.statusword),)
    frames.append(PdoFrame("tpdo", 1, first, 1))
    second = (("velocity", profile.velocity_actual),) if with_velocity else ()
    if not status_in_first:
        second += (("statusword", profile.statusword),)
    if second:
        frames.append(PdoFrame("tpdo", 2, second, 1))
    frames.append(PdoFrame("rpdo", 1, (("target", profile.cyclic_target),
                                       ("controlword", profile.controlword)), 1))
    return tuple(frames)


@dataclass(frozen=True)
class AxisLayout:
    """The node-ID and PDO layout of one axis, as the assembler needs them."""

    node_id: int
    frames: tuple[PdoFrame, ...]


def cycle_frame_sizes(axes: Sequence[AxisLayout]) -> list[int]:
    """Data lengths of all frames sent once per SYNC cycle, the SYNC (0 bytes) included."""
    return [0] + [f.size for a in axes for f in a.frames if f.per_sync]


def event_bits_per_s(axes: Sequence[AxisLayout]) -> float:
    """Worst-case bits/s of the event-driven TPDOs (sent at least once per event timer)."""
    from drivers.bus import frame_bits
    return sum(frame_bits(f.size) * 1000.0 / f.event_timer
               for a in axes for f in a.frames if not f.per_sync and f.event_timer)


@dataclass
class Row:
    """One SYNC cycle of all axes, in drive units.

    ``position``, ``velocity``, ``current``, ``target``: lists (one value per axis, ``None``
    when not received); ``statusword``: last received per axis; ``valid``: per axis, every
    SYNC-triggered TPDO of the axis was received exactly once in this cycle.
    """

    cycle: int
    timestamp: float
    position: list
    velocity: list
    current: list
    statusword: list
    target: list
    valid: list


class CycleAssembler(can.Listener):
    """Assemble one :class:`Row` per SYNC cycle from the frames of all axes.

    Args:
        axes: the axes in sample order.
        sink: called with every finished :class:`Row` (e.g. a bounded queue's ``put``).
        on_sync: called with the SYNC's index (0, 1, ...: the cycle index) right after a SYNC
            was seen, also after ``max_cycles`` (notifier thread; may send PDO frames, must not
            block or call SDO).
        on_status: called ``(axis_index, statusword)`` the first time an axis reports its fault
            or following-error bit.
        on_bus_error: called with a text on an error frame or a receive error of the bus.
        max_cycles: stop after this many rows (``None``: no limit).
        forward: listeners that receive every message first (e.g. the raw-traffic logger), so
            that the raw log holds exactly the frames this assembler saw.
        period: in lockstep, the SYNC period (s): row ``k`` gets the time ``k * period``
            instead of its SYNC's bus timestamp.
    """

    def __init__(self, axes: Sequence[AxisLayout], sink: Callable[[Row], None],
                 on_sync: Callable[[int], None] | None = None,
                 on_status: Callable[[int, int], None] | None = None,
                 on_bus_error: Callable[[str], None] | None = None,
                 max_cycles: int | None = None, forward: Sequence[can.Listener] = (),
                 period: float | None = None):
        self.n_axes = len(axes)
        self._sink = sink
        self._on_sync = on_sync
        self._on_status = on_status
        self._on_bus_error = on_bus_error
        self.max_cycles = max_cycles
        self._forward = tuple(forward)
        self._period = period
        self._tpdo: dict[int, tuple] = {}
        self._rpdo: dict[int, tuple] = {}
        self._expected = []
        for i, axis in enumerate(axes):
            mask = 0
            for frame in axis.frames:
                fields = tuple(name for name, _ in frame.entries)
                if frame.direction == "tpdo":
                    bit = (1 << frame.number) if frame.per_sync else 0
                    mask |= bit
                    self._tpdo[frame.cob_id(axis.node_id)] = (i, frame.struct.unpack, fields, bit)
                else:
                    self._rpdo[frame.cob_id(axis.node_id)] = (i, frame.struct.unpack, fields)
            self._expected.append(mask)
        self.syncs = 0  # SYNC frames seen
        self.cycles = 0  # rows emitted
        self.invalid_cycles = 0  # rows with at least one invalid axis
        self.late_frames = 0  # TPDOs received twice in one cycle
        self.error_frames = 0
        self.done = False
        self._statusword = [None] * self.n_axes
        self._status_reported = [False] * self.n_axes
        self._pending_target = [None] * self.n_axes
        self._open = None  # the cycle being filled, see _new_cycle
        self._open_counter = None  # SYNC counter of the open cycle (None: SYNC without counter)
        self._frames: dict[int, bytes] = {}  # TPDO data of the open cycle by COB-ID

    def _new_cycle(self, timestamp: float) -> list:
        n = self.n_axes
        if self._period is not None:
            timestamp = self.cycles * self._period
        self._frames = {}
        # [timestamp, position, velocity, current, received-frame bits, duplicate, target]
        return [timestamp, [None] * n, [None] * n, [None] * n, [0] * n, [False] * n,
                list(self._pending_target)]

    def on_message_received(self, msg: can.Message) -> None:
        for listener in self._forward:
            listener.on_message_received(msg)
        if self.done:
            if msg.arbitration_id == SYNC_COB_ID and not (msg.is_remote_frame or msg.is_error_frame):
                self._sync(msg.timestamp, msg.data)    # no more rows, but on_sync still follows the SYNC
            return
        if msg.is_error_frame:
            self.error_frames += 1
            if self._on_bus_error is not None:
                self._on_bus_error(f"error frame received at t={msg.timestamp:.6f} s "
                                   f"(data {bytes(msg.data).hex()})")
            return
        cob_id = msg.arbitration_id
        if cob_id == SYNC_COB_ID and not msg.is_remote_frame:
            self._sync(msg.timestamp, msg.data)
            return
        handler = self._tpdo.get(cob_id)
        if handler is not None:
            self._tpdo_frame(cob_id, handler, msg.data)
            return
        handler = self._rpdo.get(cob_id)
        if handler is not None:
            axis, unpack, fields = handler
            values = unpack(bytes(msg.data))
            self._pending_target[axis] = values[fields.index("target")]

    def _tpdo_frame(self, cob_id: int, handler, data) -> None:
        axis, unpack, fields, bit = handler
        data = bytes(data)
        try:
            values = unpack(data)
        except struct.error:
            return  # wrong length: treated as not received
        cycle = self._open
        if cycle is not None and bit:
            if self._frames.get(cob_id) == data and self._open_counter is not None:
                return  # the same frame again, answering a repeated SYNC (lockstep retry)
            self._frames[cob_id] = data
        for name, value in zip(fields, values):
            if name == "statusword":
                self._statusword[axis] = value
                if value & (STATUS_FAULT | STATUS_FOLLOWING_ERROR) and not self._status_reported[axis]:
                    self._status_reported[axis] = True
                    if self._on_status is not None:
                        self._on_status(axis, value)
            elif cycle is not None and bit:
                cycle[1 + FIELDS.index(name)][axis] = value
        if cycle is not None and bit:
            if cycle[4][axis] & bit:
                cycle[5][axis] = True  # duplicate: late frame of an earlier cycle
                self.late_frames += 1
            cycle[4][axis] |= bit

    def _sync(self, timestamp: float, data=b"") -> None:
        counter = data[0] if len(data) else None
        if counter is not None and counter == self._open_counter:
            return  # a repeated SYNC (lockstep retry): the same cycle, asked again
        self._open_counter = counter
        if self._open is not None:
            self._close()
        if not self.done:
            self._open = self._new_cycle(timestamp)
        if self._on_sync is not None:
            self._on_sync(self.syncs)
        self.syncs += 1

    def _close(self) -> None:
        timestamp, pos, vel, cur, got, dup, target = self._open
        valid = [got[i] == self._expected[i] and not dup[i] for i in range(self.n_axes)]
        if not all(valid):
            self.invalid_cycles += 1
            for i, ok in enumerate(valid):
                if not ok:
                    pos[i] = vel[i] = cur[i] = None
        self._sink(Row(self.cycles, timestamp, pos, vel, cur, list(self._statusword),
                       list(target), valid))
        self.cycles += 1
        self._open = None
        if self.max_cycles is not None and self.cycles >= self.max_cycles:
            self.done = True

    def on_error(self, exc: Exception) -> None:
        for listener in self._forward:
            try:
                listener.on_error(exc)
            except NotImplementedError:
                pass
        if self._on_bus_error is not None:
            self._on_bus_error(f"receiving from the bus failed: {exc!r}")

    def stop(self) -> None:
        """Forwarded listeners are stopped by their owner, not here."""
