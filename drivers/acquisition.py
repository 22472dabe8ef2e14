"""PDO layout of a streaming run and the assembly of one sample per SYNC cycle.

The master maps, per drive (see :func:`pdo_layout`):

* TPDO1, SYNC-triggered: position actual (I32) + current actual (I16 on EPOS2, I32 on EPOS4),
  plus the statusword on EPOS2 (4 + 2 + 2 = 8 bytes);
* TPDO2, SYNC-triggered: velocity actual (I32, optional), plus the statusword on EPOS4 (the
  I32 + I32 of its TPDO1 leave no room for it);
* RPDO1, applied on the next SYNC: cyclic set-point (I32) + controlword (U16).

:class:`CycleAssembler` is a :class:`can.Listener` that cuts the received traffic into SYNC
cycles: the SYNC frame (received back with ``receive_own_messages``, or from the kernel BCM on
SocketCAN) opens a cycle and gives its timestamp; the SYNC-triggered TPDOs received until the
next SYNC fill it; the RPDO echoes seen in a cycle are the set-points the drives take over at
the next SYNC, so they become the ``target`` of the next row (a streaming run records the
set-points it sent instead, :class:`drivers.recording.SampleRecorder`). A frame is placed in its
cycle only where the bus proves it belongs there (one frame per TPDO per SYNC, in order; see the
class): a cycle that misses a frame, or holds one that was late or cannot be placed, is invalid
for that axis, and the values that frame carries are left out, never filled from another cycle;
the values of the axis's other TPDOs of that cycle are kept (validity per TPDO: a lost velocity
frame costs no position or current). A SYNC that repeats
the counter of the open cycle (a lockstep retry, :mod:`drivers.sync`) opens no new cycle; the
TPDOs answering it are the same frames again and are taken as such. In lockstep (``period``
given) a row's time is its cycle index times the period: the simulated time.

Decoding uses precompiled ``struct.Struct`` objects; the listener runs in the notifier thread and
never calls SDO: it only sends PDO frames (through ``on_sync``) and hands finished rows to a sink.
"""

from __future__ import annotations

import struct
import threading
from dataclasses import dataclass
from typing import Callable, Sequence

import can
from canopen.objectdictionary import ODVariable, datatypes

from drivers.cia import SW_BIT13, SW_FAULT, SYNC_COB_ID, pdo_cob_id
from drivers.profiles import CURRENTS, INSTANTANEOUS, DriveProfile, ObjectRef

#: fields of a sample, in drive units
FIELDS = ("position", "velocity", "current", "statusword", "target")


@dataclass(frozen=True)
class PdoFrame:
    """One PDO of one drive: which objects it carries and how it is triggered.

    Args:
        direction: ``"tpdo"`` (drive -> master) or ``"rpdo"`` (master -> drive).
        number: PDO number 1..4.
        entries: ``(field, object)`` pairs in mapping order; field is one of :data:`FIELDS`
            or ``"controlword"``.
        trans_type: CiA 301 transmission type (1 = every SYNC, 255 = event-driven). No event
            timer is mapped: the EPOS2 and EPOS4 have none on their TPDOs.
    """

    direction: str
    number: int
    entries: tuple[tuple[str, ObjectRef], ...]
    trans_type: int

    def cob_id(self, node_id: int) -> int:
        return pdo_cob_id(self.direction, self.number, node_id)

    @property
    def struct(self) -> struct.Struct:
        # canopen's own little-endian formats of the CiA 301 data types
        formats = (ODVariable.STRUCT_TYPES[getattr(datatypes, ref.data_type)].format.lstrip("<")
                   for _, ref in self.entries)
        return struct.Struct("<" + "".join(formats))

    @property
    def size(self) -> int:
        return self.struct.size

    @property
    def per_sync(self) -> bool:
        """Sent once per SYNC cycle (SYNC-triggered TPDO, or an RPDO of the set-point stream)."""
        return self.direction == "rpdo" or 1 <= self.trans_type <= 240


def pdo_layout(profile: DriveProfile, current: str = INSTANTANEOUS) -> tuple[PdoFrame, ...]:
    """The PDOs the master configures on a drive of ``profile`` for a streaming run.

    Every TPDO is SYNC-triggered: TPDO1 = position + current (``current``: the instantaneous or
    the averaged one, :meth:`DriveProfile.streamed_current`) (+ statusword where it fits: the
    EPOS2's 16-bit current); TPDO2 = velocity (+ the statusword where it did not fit in TPDO1:
    6 bytes). No event timer is used: a real EPOS4 has none on its TPDOs.
    """
    frames = []
    streamed = profile.streamed_current(current)
    status_in_first = streamed.bits + profile.position_actual.bits + profile.statusword.bits <= 64
    first: tuple[tuple[str, ObjectRef], ...] = (("position", profile.position_actual), ("current", streamed))
    if status_in_first:
        first += (("statusword", profile.statusword),)
    frames.append(PdoFrame("tpdo", 1, first, 1))
    second: tuple[tuple[str, ObjectRef], ...] = (("velocity", profile.velocity_actual),)
    if not status_in_first:
        second += (("statusword", profile.statusword),)
    frames.append(PdoFrame("tpdo", 2, second, 1))
    frames.append(PdoFrame("rpdo", 1, (("target", profile.cyclic_target),
                                       ("controlword", profile.controlword)), 1))
    return tuple(frames)


@dataclass(frozen=True)
class AxisLayout:
    """The node-ID and PDO layout of one axis, as the assembler needs them."""

    node_id: int
    frames: tuple[PdoFrame, ...]


def current_of(layout: AxisLayout, profile: DriveProfile) -> str:
    """Which motor current an axis's layout streams: :data:`~drivers.profiles.INSTANTANEOUS` or
    :data:`~drivers.profiles.AVERAGED`, by the object its TPDO maps as ``current`` on a drive of
    ``profile``.

    Raises:
        ValueError: no current mapped, or an object that is neither of the profile's currents
            (a layout of another drive generation).
    """
    mapped = [ref for f in layout.frames if f.direction == "tpdo" for name, ref in f.entries if name == "current"]
    if len(mapped) != 1:
        raise ValueError(f"node {layout.node_id}: {len(mapped)} current objects mapped, expected one")
    ref = mapped[0]
    for kind in CURRENTS:
        ours = profile.streamed_current(kind)
        if ref.key == ours.key and ref.data_type == ours.data_type:
            return kind
    raise ValueError(f"node {layout.node_id}: the current mapped is {ref} ({ref.data_type}), neither of an "
                     f"{profile.name}'s currents ({profile.current_actual} instantaneous, {profile.current_averaged} "
                     f"averaged, {profile.current_actual.data_type}): a layout of another drive")


def master_layouts(axes: Sequence) -> list[AxisLayout]:
    """The PDO layout the master maps on each of ``axes`` (:class:`drivers.axis.AxisConfig`:
    node-ID, drive profile, streamed current), in their order: :func:`pdo_layout` of each."""
    return [AxisLayout(a.node_id, pdo_layout(a.drive_profile, a.current)) for a in axes]


#: version of the stored form of a PDO layout (:func:`layout_record`)
LAYOUT_VERSION = 1


def layout_record(axes: Sequence[AxisLayout]) -> dict:
    """The PDO layout of a run's axes as JSON-able data, stored with its recording and beside
    its raw log, so that both decode with the layout they were recorded with, whatever the
    master maps later (:func:`layout_from_record` reads it back).

    ``{"version": 1, "axes": [{"node_id": 1, "frames": [{"direction": "tpdo", "number": 1,
    "cob_id": 385, "trans_type": 1, "entries": [{"field": "position",
    "index": 24676, "subindex": 0, "data_type": "INTEGER32", "unit": "qc"}, ...]}, ...]}, ...]}``:
    per axis in sample order, every PDO with its COB-ID and its mapped objects in mapping order
    (CiA 301 data type names, drive units).
    """
    return {"version": LAYOUT_VERSION, "axes": [
        {"node_id": axis.node_id, "frames": [
            {"direction": f.direction, "number": f.number, "cob_id": f.cob_id(axis.node_id),
             "trans_type": f.trans_type,
             "entries": [{"field": name, "index": ref.index, "subindex": ref.subindex,
                          "data_type": ref.data_type, "unit": ref.unit} for name, ref in f.entries]}
            for f in axis.frames]}
        for axis in axes]}


def layout_from_record(record) -> tuple[AxisLayout, ...]:
    """The axes' layouts stored by :func:`layout_record`.

    Raises:
        ValueError: not such a record, or one the assembler cannot decode with (an unknown
            version, field or data type, a COB-ID other than CiA 301's default for its PDO, a
            frame longer than 8 bytes, an RPDO without the set-point); the message says what.
    """
    if not isinstance(record, dict) or record.get("version") != LAYOUT_VERSION:
        raise ValueError(f"not a PDO layout of version {LAYOUT_VERSION} "
                         f"(version {record.get('version') if isinstance(record, dict) else None!r})")
    axes = []
    try:
        for axis in record["axes"]:
            node_id = int(axis["node_id"])
            frames = []
            for f in axis["frames"]:
                entries = []
                for e in f["entries"]:
                    if e["field"] not in FIELDS + ("controlword",):
                        raise ValueError(f"node {node_id}: unknown field {e['field']!r}")
                    entries.append((e["field"], ObjectRef(int(e["index"]), int(e["subindex"]), e["data_type"],
                                                          e.get("unit", ""))))
                frame = PdoFrame(f["direction"], int(f["number"]), tuple(entries), int(f["trans_type"]))
                where = f"node {node_id} {frame.direction.upper()}{frame.number}"
                if frame.cob_id(node_id) != int(f["cob_id"]):
                    raise ValueError(f"{where}: COB-ID 0x{int(f['cob_id']):03X}, not CiA 301's default "
                                     f"0x{frame.cob_id(node_id):03X} (not supported)")
                if frame.size > 8:
                    raise ValueError(f"{where}: {frame.size} bytes, more than a CAN frame holds")
                if frame.direction == "rpdo" and "target" not in (name for name, _ in entries):
                    raise ValueError(f"{where}: an RPDO without the set-point")
                frames.append(frame)
            axes.append(AxisLayout(node_id, tuple(frames)))
    except (KeyError, TypeError) as exc:
        raise ValueError(f"damaged PDO layout ({type(exc).__name__}: {exc})") from None
    return tuple(axes)


def cycle_frame_sizes(axes: Sequence[AxisLayout]) -> list[int]:
    """Data lengths of all frames sent once per SYNC cycle, the SYNC (0 bytes) included."""
    return [0] + [f.size for a in axes for f in a.frames if f.per_sync]


@dataclass(frozen=True)
class Row:
    """One SYNC cycle of all axes, in drive units.

    ``position``, ``velocity``, ``current``, ``target``: lists (one value per axis, ``None``
    when not received: a measured value is ``None`` exactly when the TPDO carrying it is not
    provably this cycle's, whatever the axis's other TPDOs did); ``statusword``: last received
    per axis; ``valid``: per axis, every SYNC-triggered TPDO of the axis was received exactly
    once in this cycle.
    """

    cycle: int
    timestamp: float
    position: list
    velocity: list
    current: list
    statusword: list
    target: list
    valid: list


class _Stream:
    """One SYNC-triggered TPDO of one node, as the assembler keeps its books.

    ``owed`` holds the cycles whose window closed without this frame, oldest first: each is a
    frame either lost or still on its way. While one is owed, a window holding exactly one frame
    is ``provisional`` (it holds its own frame if the owed one was lost, the previous cycle's
    if that one was late) until an extra frame proves the shift or :data:`LOOKAHEAD` cycles pass
    without one.
    """

    __slots__ = ("cob_id", "axis", "unpack", "size", "fields", "owed", "provisional")

    def __init__(self, cob_id: int, axis: int, layout: struct.Struct, fields: tuple[str, ...]):
        self.cob_id = cob_id
        self.axis = axis
        self.unpack = layout.unpack
        self.size = layout.size
        self.fields = fields
        self.owed: list[int] = []
        self.provisional: list[int] = []


#: cycles an owed frame may still arrive in before it is taken as lost (see :class:`CycleAssembler`)
LOOKAHEAD = 16

_OK, _MISSING, _PROVISIONAL, _WITHDRAWN = range(4)


class CycleAssembler(can.Listener):
    """Assemble one :class:`Row` per SYNC cycle from the frames of all axes.

    A TPDO carries no cycle number, so its cycle is inferred from what the bus guarantees: each
    node sends exactly one frame of each SYNC-triggered TPDO per SYNC, in order, and never
    before that SYNC. Per TPDO of each node the assembler counts the frames between two SYNCs
    (a *window*):

    * one frame, nothing owed: the cycle's own frame; the cell is valid;
    * none: the cell is invalid and the frame is *owed*: lost, or late;
    * two or more: the extra ones pay what is owed (late frames); the last one is the cycle's own
      once nothing is owed any more; every window since the first owed one held the previous
      cycle's frame and is withdrawn (invalid);
    * one frame while a frame is owed: undecided. The row is held back until an extra frame
      proves the shift (withdrawn) or :data:`LOOKAHEAD` cycles pass without one: the owed frame
      is then taken as lost and the window's frame as its own.

    Rows leave in cycle order, each as soon as it is decided; :meth:`flush` (the end of a run)
    withdraws what is still undecided. An extra frame with nothing owed (later than
    ``LOOKAHEAD`` cycles, or sent twice) cannot be placed: it invalidates its window and is
    counted in ``unplaced_frames``, a sign that cells already handed out may hold another
    cycle's data (the quality verdict fails on it).

    Args:
        axes: the axes in sample order.
        sink: called with every finished :class:`Row` (e.g. a bounded queue's ``put``).
        on_sync: called with the SYNC's index (0, 1, ...: the cycle index) right after a SYNC
            was seen, also after ``max_cycles`` (notifier thread; may send PDO frames, must not
            block or call SDO).
        on_status: called ``(axis_index, statusword)`` the first time an axis reports its fault
            or following-error bit.
        on_bus_error: called with a text on an error frame or a receive error of the bus.
        max_cycles: stop after this many cycles (``None``: no limit).
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
        self._lock = threading.RLock()
        self._streams: dict[int, _Stream] = {}     # SYNC-triggered TPDOs by COB-ID
        self._events: dict[int, tuple] = {}        # event-driven TPDOs (statusword only)
        self._rpdo: dict[int, tuple] = {}
        for i, axis in enumerate(axes):
            for frame in axis.frames:
                fields = tuple(name for name, _ in frame.entries)
                cob_id = frame.cob_id(axis.node_id)
                if frame.direction == "rpdo":
                    self._rpdo[cob_id] = (i, frame.struct.unpack, fields.index("target"))
                elif frame.per_sync:
                    self._streams[cob_id] = _Stream(cob_id, i, frame.struct, fields)
                else:
                    self._events[cob_id] = (i, frame.struct.unpack, fields)
        self._status_field = {cob: s.fields.index("statusword") for cob, s in self._streams.items()
                              if "statusword" in s.fields}
        self.syncs = 0  # SYNC frames seen
        self.cycles = 0  # windows closed
        self.emitted = 0  # rows handed to the sink
        self.invalid_cycles = 0  # rows with at least one invalid axis
        self.late_frames = 0  # frames that arrived in a later cycle's window than their own
        self.lost_frames = 0  # owed frames that did not come within LOOKAHEAD cycles
        self.withdrawn_cells = 0  # cells holding one frame that was not provably their own
        self.unplaced_frames = 0  # extra frames with nothing owed
        self.error_frames = 0
        self.wrong_length: dict[int, tuple[int, int]] = {}   # COB-ID -> (frames, their last length)
        self.done = False
        self._statusword: list[int | None] = [None] * self.n_axes
        self._status_reported = [False] * self.n_axes
        self._pending_target: list[int | None] = [None] * self.n_axes
        # (timestamp, target) of the window being filled
        self._open: tuple[float, list[int | None]] | None = None
        self._open_counter = None  # SYNC counter of the open window (None: SYNC without counter)
        self._count: dict[int, int] = {}   # frames per COB-ID in the open window
        self._last: dict[int, bytes] = {}  # last frame per COB-ID in the open window
        self._held: dict[int, list] = {}   # cycle -> [timestamp, target, statusword, {cob: [state, data]}]

    @property
    def progress(self) -> int:
        """Cycles closed, plus one while a SYNC's window is open: grows with every SYNC seen
        (what a stall watchdog watches)."""
        return self.cycles + (self._open is not None)

    def on_message_received(self, msg: can.Message) -> None:
        for listener in self._forward:
            listener.on_message_received(msg)
        with self._lock:
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
            elif cob_id in self._streams:
                self._tpdo_frame(cob_id, bytes(msg.data))
            elif cob_id in self._events:
                axis, unpack, fields = self._events[cob_id]
                try:
                    values = unpack(bytes(msg.data))
                except struct.error:
                    return
                if "statusword" in fields:
                    self._status(axis, values[fields.index("statusword")])
            elif cob_id in self._rpdo:
                axis, unpack, at = self._rpdo[cob_id]
                try:
                    self._pending_target[axis] = unpack(bytes(msg.data))[at]
                except struct.error:
                    pass

    def _status(self, axis: int, value: int) -> None:
        self._statusword[axis] = value
        if value & (SW_FAULT | SW_BIT13) and not self._status_reported[axis]:
            self._status_reported[axis] = True
            if self._on_status is not None:
                self._on_status(axis, value)

    def _tpdo_frame(self, cob_id: int, data: bytes) -> None:
        stream = self._streams[cob_id]
        if len(data) != stream.size:   # another layout's frame: treated as not received, counted
            count, _ = self.wrong_length.get(cob_id, (0, 0))
            self.wrong_length[cob_id] = (count + 1, len(data))
            return
        at = self._status_field.get(cob_id)
        if at is not None:     # the values themselves are decoded once, when the row leaves
            self._status(stream.axis, stream.unpack(data)[at])
        if self._open is None:
            return
        if self._open_counter is not None and self._last.get(cob_id) == data:
            return  # the same frame again, answering a repeated SYNC (lockstep retry)
        self._last[cob_id] = data
        self._count[cob_id] = self._count.get(cob_id, 0) + 1

    def _sync(self, timestamp: float, data=b"") -> None:
        counter = data[0] if len(data) else None
        if counter is not None and counter == self._open_counter:
            return  # a repeated SYNC (lockstep retry): the same cycle, asked again
        self._open_counter = counter
        if self._open is not None:
            self._close()
        if not self.done:
            if self._period is not None:
                timestamp = self.cycles * self._period
            self._open = (timestamp, list(self._pending_target))
            self._count = {}
            self._last = {}
        if self._on_sync is not None:
            self._on_sync(self.syncs)
        self.syncs += 1

    def _close(self) -> None:
        """Book the open window's frames per TPDO (see the class docstring) and emit what is decided."""
        w = self.cycles
        if self._open is None:
            raise RuntimeError("CycleAssembler: no open cycle to close")
        timestamp, target = self._open
        cells = {}
        for cob_id, stream in self._streams.items():
            n = self._count.get(cob_id, 0)
            if n == 0:
                state = _MISSING
                stream.owed.append(w)
            elif n == 1:
                state = _PROVISIONAL if stream.owed else _OK
                if stream.owed:
                    stream.provisional.append(w)
            else:
                repaid = min(n - 1, len(stream.owed))
                if repaid:
                    self.late_frames += repaid
                    del stream.owed[:repaid]
                    self._withdraw(stream, stream.provisional)
                surplus = n - 1 - repaid
                self.unplaced_frames += surplus
                state = _OK if not (stream.owed or surplus) else _WITHDRAWN
                self.withdrawn_cells += state == _WITHDRAWN
            cells[cob_id] = [state, self._last.get(cob_id)]
        self._held[w] = [timestamp, target, list(self._statusword), cells]
        self.cycles += 1
        self._open = None
        for stream in self._streams.values():
            while stream.owed and w - stream.owed[0] >= LOOKAHEAD:
                stream.owed.pop(0)
                self.lost_frames += 1
                until = stream.owed[0] if stream.owed else w + 1
                for p in [p for p in stream.provisional if p < until]:
                    stream.provisional.remove(p)
                    self._held[p][3][stream.cob_id][0] = _OK
        if self.max_cycles is not None and self.cycles >= self.max_cycles:
            self.done = True
            self.flush()
        else:
            self._emit()

    def _withdraw(self, stream: _Stream, windows: list[int]) -> None:
        for p in windows:
            self._held[p][3][stream.cob_id][0] = _WITHDRAWN
            self.withdrawn_cells += 1
        windows.clear()

    def _emit(self) -> None:
        """Hand the decided rows at the front to the sink, in cycle order."""
        while self.emitted in self._held:
            held = self._held[self.emitted]
            if any(state == _PROVISIONAL for state, _ in held[3].values()):
                return
            del self._held[self.emitted]
            timestamp, target, statusword, cells = held
            n = self.n_axes
            values = {"position": [None] * n, "velocity": [None] * n, "current": [None] * n}
            valid = [True] * n
            for cob_id, (state, data) in cells.items():
                stream = self._streams[cob_id]
                if state != _OK:     # this TPDO's values stay None; the axis's others are kept
                    valid[stream.axis] = False
                    continue
                for name, value in zip(stream.fields, stream.unpack(data)):
                    if name in values:
                        values[name][stream.axis] = value
            if not all(valid):
                self.invalid_cycles += 1
            self._sink(Row(self.emitted, timestamp, values["position"], values["velocity"],
                           values["current"], statusword, target, valid))
            self.emitted += 1

    def flush(self) -> None:
        """End of the run: withdraw the cells still undecided and emit every held row."""
        with self._lock:
            for stream in self._streams.values():
                self._withdraw(stream, stream.provisional)
                stream.owed.clear()
            self._emit()

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


@dataclass(frozen=True)
class CycleBooks:
    """The counts of misplaced frames of a :class:`CycleAssembler` (its attributes of the same
    names), for a recording's metadata; ``wrong_length_frames``: frames on a streamed TPDO's
    COB-ID whose length is not the layout's (another layout's frames: not used)."""

    late_frames: int = 0
    lost_frames: int = 0
    withdrawn_cells: int = 0
    unplaced_frames: int = 0
    error_frames: int = 0
    wrong_length_frames: int = 0


def cycle_books(assembler: CycleAssembler) -> CycleBooks:
    """The assembler's counts of misplaced frames, for a recording's metadata."""
    return CycleBooks(assembler.late_frames, assembler.lost_frames, assembler.withdrawn_cells,
                      assembler.unplaced_frames, assembler.error_frames,
                      sum(count for count, _ in assembler.wrong_length.values()))
