"""The PDO engine of an emulated drive: TPDOs packed from their mapping ``0x1A0x`` (sent on SYNC
for transmission types 1..240, on their event timer and on a change of a mapped object for
254/255), RPDOs decoded per ``0x160x`` and written into the drive (applied on the next SYNC for
types 0..240, at once for 254/255), the RPDO deadline monitoring of CiA 301, and the checks of a
PDO mapping written over SDO. PDOs run only in OPERATIONAL (the drive tells)."""

from __future__ import annotations

import logging
import math
import struct
from dataclasses import dataclass
from typing import Callable

import canopen
from canopen.sdo import SdoAbortedError

from drivers.cia import RPDO_COMM, RPDO_MAP, TPDO_COMM, TPDO_MAP
from drivers.profiles import DriveProfile, find_variable

from .objects import ObjectStore

logger = logging.getLogger(__name__)

EMCY_PDO_LENGTH, EMCY_RPDO_TIMEOUT = 0x8210, 0x8250
ABORT_NOT_MAPPABLE, ABORT_PDO_LENGTH = 0x06040041, 0x06040042
#: the communication and mapping parameters of all PDOs
PDO_PARAMETERS = range(RPDO_COMM, TPDO_MAP + 0x200)


@dataclass
class Pdo:
    cob_id: int
    trans_type: int
    inhibit: float            # s
    event_timer: float        # s (TPDO: transmission period; RPDO: deadline, CiA 301)
    layout: struct.Struct
    entries: list             # [(index, subindex)] in frame order
    last_sent: float = -math.inf
    last_received: float | None = None   # RPDO: time its last value took effect (None: not watched yet)


class PdoEngine:
    """The PDOs of one drive.

    Args:
        node_id, profile, store, network: the drive's.
        clock: ``clock() -> float`` s, the rig's clock.
        lock: the rig's lock, held by the RPDO handler (a notifier thread).
        write: ``write(index, subindex, value)``, the drive's own write (checks, actions).
        emcy: ``emcy(code, fault)``, the drive's error signalling.
        operational: ``operational() -> bool``, NMT OPERATIONAL and not silenced.
    """

    def __init__(self, node_id: int, profile: DriveProfile, store: ObjectStore, network: canopen.Network,
                 clock: Callable[[], float], lock, write, emcy, operational: Callable[[], bool]):
        self.id, self.profile, self.store, self.network = node_id, profile, store, network
        self._clock, self._lock, self._write, self._emcy, self._nmt_operational = clock, lock, write, emcy, operational
        self.tpdos: list[Pdo] = []
        self.rpdos: dict[int, Pdo] = {}
        self._subscribed: list[int] = []
        self.pending: dict[int, bytes] = {}
        self.sync_frames: list[tuple[int, bytes]] = []   # the TPDOs of the last SYNC
        self.dirty = True

    def reset(self) -> None:
        """After a reset of the application: nothing pending, the layouts rebuilt from the dictionary."""
        self.pending = {}
        self.sync_frames = []
        self.rpdos = {}
        self.dirty = True

    # -- layouts --------------------------------------------------------------------------------
    def check_write(self, index: int, subindex: int, value) -> None:
        """A PDO parameter written: a mapping longer than 64 bits or an object that cannot be
        mapped is refused (SDO abort); the layouts are rebuilt before the next PDO."""
        od, get = self.store.dictionary, self.store.get
        if RPDO_MAP <= index < TPDO_COMM or TPDO_MAP <= index < TPDO_MAP + 0x200:
            receive = index < TPDO_COMM
            if subindex == 0:
                bits = sum(get(index, s) & 0xFF for s in range(1, value + 1))
                if bits > 64:
                    raise SdoAbortedError(ABORT_PDO_LENGTH)
            elif value:
                var = find_variable(od, value >> 16, (value >> 8) & 0xFF)
                if (var is None or not var.pdo_mappable or len(var) != value & 0xFF
                        or not (var.writable if receive else var.readable)):
                    raise SdoAbortedError(ABORT_NOT_MAPPABLE)
        self.dirty = True

    def _layout(self, mapping_index: int):
        od, get = self.store.dictionary, self.store.get
        entries, fmt = [], "<"
        for sub in range(1, get(mapping_index, 0) + 1):
            value = get(mapping_index, sub)
            var = find_variable(od, value >> 16, (value >> 8) & 0xFF)
            if var is None or var.data_type is None:    # mapped objects are checked when written
                raise ValueError(f"PDO mapping 0x{mapping_index:04X} sub {sub} names 0x{value >> 16:04X} sub "
                                 f"{(value >> 8) & 0xFF}, which the object dictionary does not define with a type")
            entries.append((var.index, var.subindex))
            fmt += var.STRUCT_TYPES[var.data_type].format.lstrip("<")
        return struct.Struct(fmt), entries

    def _build(self) -> None:
        get, optional = self.store.get, self.store.optional
        self.tpdos, rpdos = [], {}
        for n in range(self.profile.tpdo_count):
            cob = get(TPDO_COMM + n, 1)
            if not cob >> 31 and get(TPDO_MAP + n, 0):
                layout, entries = self._layout(TPDO_MAP + n)
                self.tpdos.append(Pdo(cob & 0x7FF, get(TPDO_COMM + n, 2), get(TPDO_COMM + n, 3) * 1e-4,
                                      optional(TPDO_COMM + n, 5) * 1e-3, layout, entries))
        for n in range(self.profile.rpdo_count):
            cob = get(RPDO_COMM + n, 1)
            if not cob >> 31 and get(RPDO_MAP + n, 0):
                layout, entries = self._layout(RPDO_MAP + n)
                rpdos[cob & 0x7FF] = Pdo(cob & 0x7FF, get(RPDO_COMM + n, 2), 0.0,
                                         optional(RPDO_COMM + n, 5) * 1e-3, layout, entries)
        for cob in self._subscribed:
            self.network.unsubscribe(cob, self._on_rpdo)
        self.rpdos = rpdos
        self._subscribed = list(rpdos)
        for cob in rpdos:
            self.network.subscribe(cob, self._on_rpdo)
        self.dirty = False

    def operational(self) -> bool:
        """PDOs may run (the layouts rebuilt first if a parameter changed)."""
        if self.dirty:
            self._build()
        return self._nmt_operational()

    # -- TPDOs ----------------------------------------------------------------------------------
    def _send(self, pdo: Pdo, now: float) -> bytes:
        values = self.store.values
        try:                      # the mapped objects' values (a streaming drive's live ones)
            data = pdo.layout.pack(*[values[key] for key in pdo.entries])
        except KeyError:          # one not written yet: its default
            get = self.store.get
            data = pdo.layout.pack(*[get(i, s) for i, s in pdo.entries])
        pdo.last_sent = now
        self.network.send_message(pdo.cob_id, data)
        return data

    def send_sync_tpdos(self, sync_count: int) -> None:
        """Send the SYNC-triggered TPDOs due at SYNC number ``sync_count`` (1, 2, ...)."""
        self.sync_frames = []
        if not self.operational():
            return
        now = None
        for pdo in self.tpdos:
            if pdo.trans_type <= 240 and sync_count % max(pdo.trans_type, 1) == 0:
                now = now or self._clock()
                self.sync_frames.append((pdo.cob_id, self._send(pdo, now)))

    def resend_sync_tpdos(self) -> None:
        """Send the frames of the last :meth:`send_sync_tpdos` again, unchanged (a repeated SYNC)."""
        if not self.operational():
            self.sync_frames = []       # nothing sent: the rig's answer counts no frame
        for cob_id, data in self.sync_frames:
            self.network.send_message(cob_id, data)

    def send_event_tpdos(self, now: float, changed=None) -> None:
        """Send the event-driven TPDOs whose event timer ran out, or that map ``changed`` (index, sub)."""
        if not self.operational():
            return
        for pdo in self.tpdos:
            if pdo.trans_type < 254 or now - pdo.last_sent < pdo.inhibit:
                continue
            if (changed in pdo.entries) or (pdo.event_timer and now - pdo.last_sent >= pdo.event_timer):
                self._send(pdo, now)

    # -- RPDOs ----------------------------------------------------------------------------------
    def awaits_setpoint(self) -> bool:
        """Streaming with a synchronous RPDO mapped, and no set-point received since the last SYNC."""
        return (self.operational() and not self.pending
                and any(pdo.trans_type <= 240 for pdo in self.rpdos.values()))

    def _on_rpdo(self, can_id, data, timestamp) -> None:
        with self._lock:
            if not self.operational() or can_id not in self.rpdos:
                return
            pdo = self.rpdos[can_id]
            if len(data) < pdo.layout.size:
                self._emcy(EMCY_PDO_LENGTH, fault=False)
                return
            if pdo.trans_type <= 240:
                self.pending[can_id] = bytes(data)
            else:
                self._apply(pdo, data)

    def _apply(self, pdo: Pdo, data) -> None:
        # the mapped values, decoded by the mapping's own struct, are written as an SDO download
        # would write them (without its encoding to bytes and back: the hot path at 1 kHz)
        pdo.last_received = self._clock()
        for (index, sub), value in zip(pdo.entries, pdo.layout.unpack_from(data)):
            try:
                self._write(index, sub, value)
            except SdoAbortedError as exc:
                logger.warning("node %d: RPDO 0x%03X value for 0x%04X:%02X refused (%s)",
                               self.id, pdo.cob_id, index, sub, exc)

    def apply_pending(self) -> None:
        """Apply the synchronous RPDOs received since the last SYNC."""
        pending, self.pending = self.pending, {}
        for cob, data in pending.items():
            if cob in self.rpdos:
                self._apply(self.rpdos[cob], data)

    def forget_received(self) -> None:
        """The RPDO watch starts again with the next value received (on entering OPERATION ENABLED)."""
        for pdo in self.rpdos.values():
            pdo.last_received = None

    def check_timeout(self, now: float) -> bool:
        """True (once per loss) when an RPDO with a deadline ``0x140x:05`` (ms, 0 = off) missed it.

        A synchronous RPDO's value takes effect at a SYNC, so the deadline counts from the last
        SYNC that applied one: missing SYNC frames and missing set-points both count. As CiA 301
        says, the watch starts with the first value received (and again after each timeout).
        """
        for pdo in self.rpdos.values():
            if pdo.event_timer and pdo.last_received is not None and now - pdo.last_received > pdo.event_timer:
                logger.warning("node %d: no set-point (RPDO 0x%03X) for %.3f s in the cyclic mode",
                               self.id, pdo.cob_id, now - pdo.last_received)
                pdo.last_received = None
                return True
        return False
