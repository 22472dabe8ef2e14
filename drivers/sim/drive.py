"""One emulated EPOS2/EPOS4 drive: a ``canopen.LocalNode`` plus what it lacks.

``LocalNode`` answers SDO from its object dictionary and keeps an NMT state. This module adds:
TPDOs packed from the mapping in ``0x1A0x`` (sent on SYNC for transmission types 1..240, on
their event timer and on a statusword change for 254/255), RPDOs decoded per ``0x160x`` and
written into the dictionary (applied on the next SYNC for types 0..240, at once for 254/255),
PDOs only in OPERATIONAL, boot-up and NMT reset, EMCY with ``0x1001``/``0x1003``, the CiA 402
power state machine (with the fault reaction: a quick-stop ramp, then FAULT with the power off),
the heartbeat consumer ``0x1016:01`` (EMCY ``0x8130`` and a fault when the producer it watches
falls silent), the RPDO deadline monitoring of CiA 301 (see :meth:`EmulatedDrive.check_rpdo_timeout`)
and the modes the master uses: homing (HMM), profile position (PPM) and
cyclic position (EPOS4 CSP mode 8 on ``0x607A``; EPOS2 position mode -1 on ``0x2062``).

Cyclic set-points are interpolated as a real drive does (its loops run much faster than SYNC):
the demand is the uniform cubic B-spline whose control points are the received targets. Over the
period after SYNC k it is the segment of the last four, ``q_k-3 .. q_k``; at SYNC k it stands at
``(q_k-3 + 4 q_k-2 + q_k-1) / 6`` with velocity ``(q_k-1 - q_k-3) / 2T`` and acceleration
``(q_k-3 - 2 q_k-2 + q_k-1) / T^2``, all three continuous across SYNC (C2). So the demand runs
2 periods behind the targets and smooths them: for a motion of constant acceleration ``a`` it is
the motion itself, 2 periods late, plus a constant offset ``a T^2 / 6``; a target step becomes an
S-curve over 4 periods. Continuous acceleration matters: a C1 demand (e.g. the cubic Hermite
segment through the last targets' midpoint, 1.5 periods of delay) has an acceleration step at
every SYNC, hence a force ripple at the SYNC rate that the current sampled at each SYNC catches
at the same phase, aliased into the identification data (link viscous friction +25..+33 %,
``tests/test_sim_links.py``). When streaming starts the spline's earlier control points are the
held demand, so it leaves the standstill with no jump of position, velocity or acceleration.

Positions here are drive units (counts); the rig converts to and from the SI plant. Every
handler runs under the rig's lock, called from the network's notifier thread (SDO, RPDO, NMT,
SYNC) or the rig's clock thread (event timers, heartbeat and RPDO watches). Times come from the
rig's clock (:attr:`drivers.sim.rig.SimulatedRig.time`), which stands still while the rig's
own thread cannot run: a stall of the host process is not a timeout of the drives.
"""

from __future__ import annotations

import logging
import math
import struct
from dataclasses import dataclass

import canopen
from canopen.sdo import SdoAbortedError

from drivers.cia import (CW_FAULT_RESET, CW_HALT, CW_NEW_SETPOINT, CW_RELATIVE, MODE_HMM, MODE_PPM,
                         NMT_ENTER_PRE_OPERATIONAL, NMT_OPERATIONAL, NMT_STOPPED, SW_BIT12, SW_HOMED, SW_REMOTE,
                         SW_TARGET_REACHED, SW_VOLTAGE_ENABLED, state_bits)
from drivers.profiles import get_profile, make_object_dictionary
from drivers.units import AxisScaling

logger = logging.getLogger(__name__)

# CiA 402 state names (canopen's; their statusword bits: drivers.cia.state_bits)
NOT_READY, DISABLED, READY, SWITCHED_ON, ENABLED, QUICK_STOP, FAULT_REACTION, FAULT = (
    "NOT READY TO SWITCH ON", "SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON",
    "OPERATION ENABLED", "QUICK STOP ACTIVE", "FAULT REACTION ACTIVE", "FAULT")
HOME_HERE = (35, 37)  # homing methods "actual position" (CiA 402 35, maxon 37)
HOMING_TRAVEL_TURNS = 0.5  # motor turns of the emulated search move of the other methods

EMCY_FOLLOWING_ERROR, EMCY_OVERCURRENT, EMCY_PDO_LENGTH, EMCY_HEARTBEAT = 0x8611, 0x2310, 0x8210, 0x8130
EMCY_RPDO_TIMEOUT = 0x8250
ABORT_VALUE_RANGE, ABORT_NOT_MAPPABLE, ABORT_PDO_LENGTH = 0x06090030, 0x06040041, 0x06040042

_PDO_PARAMS = range(0x1400, 0x1C00)


def error_register(code: int) -> int:
    """CiA 301 error register (0x1001) bits for an EMCY error code (bit 0 = generic, always)."""
    bits = 0x01
    bits |= {0x2: 0x02, 0x3: 0x04, 0x4: 0x08}.get(code >> 12, 0)
    if code & 0xFF00 == 0x8100:
        bits |= 0x10
    elif code >> 12 == 0x8:
        bits |= 0x20
    return bits


@dataclass
class _Pdo:
    cob_id: int
    trans_type: int
    inhibit: float            # s
    event_timer: float        # s (TPDO: transmission period; RPDO: deadline, CiA 301)
    layout: struct.Struct
    entries: list             # [(index, subindex)] in frame order
    last_sent: float = -math.inf
    last_received: float | None = None   # RPDO: time its last value took effect (None: not watched yet)


class EmulatedDrive:
    """One emulated drive on a ``canopen.Network`` (the rig owns the network and the plant).

    Args:
        node_id: CANopen node-ID.
        profile_name: ``"epos2"`` or ``"epos4"``.
        scaling: the axis' :class:`AxisScaling` (counts per motor turn for the rpm limits).
        network: the rig's network (the node is added to it).
        lock: the rig's lock, held by every handler.
        clock: ``clock() -> float`` seconds (monotonic; the rig's clock), for event timers, inhibit
            times and the heartbeat and RPDO watches.
    """

    def __init__(self, node_id: int, profile_name: str, scaling: AxisScaling, network: canopen.Network,
                 lock, clock):
        self.profile = get_profile(profile_name)
        self.scaling = scaling
        self.node = canopen.LocalNode(node_id, make_object_dictionary(profile_name, node_id))
        self.id = node_id
        self._lock = lock
        self._clock = clock
        network.add_node(self.node)
        self.network = network
        # gate SDO and NMT through this class (silence, STOPPED, injected aborts, resets)
        network.unsubscribe(self.node.sdo.rx_cobid, self.node.sdo.on_request)
        network.unsubscribe(0, self.node.nmt.on_command)
        network.subscribe(self.node.sdo.rx_cobid, self._on_sdo_request)
        network.subscribe(0, self._on_nmt_command)
        self.node.add_read_callback(self._on_read)
        self.node.add_write_callback(self._on_write)
        self.silent = False
        self.sdo_aborts: dict[tuple[int, int], int] = {}
        self._rpdo_subscribed: list[int] = []
        self._reset_application()

    # -- object values -------------------------------------------------------------------------
    def _reset_application(self) -> None:
        self.node.data_store.clear()
        self.values: dict[tuple[int, int], object] = {}
        self.state = DISABLED
        self._cw = 0
        self._mode_bits = 0           # statusword bits 10, 12, 13, 15 of the mode logic
        # offset, counts: plant counts - reported counts (set by the rig at power-up); a reset
        # re-zeroes the incremental encoder where the axis stands, as at power-up
        if getattr(self, "offset", None) is not None:
            self.offset += self.actual
        else:
            self.offset = None
        self.actual = 0               # reported position, counts
        self.demand = 0.0             # position demand at the period start, counts
        self.demand_velocity = 0.0    # counts/s
        self._demand_curve = (0.0, 0.0)   # coefficients of t^2, t^3 of the demand in the period
        self._last_cyclic = None      # the three last cyclic targets (q_k-1, q_k-2, q_k-3), counts
        self._profile = None          # [target counts, velocity counts/s] of a PPM/homing move
        self._homing_phase = None
        self._homing_start = 0.0
        self._next_demand = None
        self._homed = False
        self._pending_rpdo: dict[int, bytes] = {}
        self._sync_frames: list[tuple[int, bytes]] = []   # the TPDOs of the last SYNC
        self.rpdos: dict[int, _Pdo] = {}
        self._quick_stop_since = None
        self._pdos_dirty = True
        self._watch_producer(0)
        self._set(self.profile.statusword, self._statusword())

    def optional(self, index: int, subindex: int = 0, default=0):
        """Value of an object this drive may lack (PDO sub-index 5 and 0x1006 exist on an EPOS2,
        not on an EPOS4): ``default`` where its dictionary has no such object."""
        if self.node.object_dictionary.get_variable(index, subindex) is None:
            return default
        return self.get(index, subindex)

    def get(self, index: int, subindex: int = 0):
        """Current value of an object (written value, live value or default)."""
        try:
            return self.values[(index, subindex)]
        except KeyError:
            value = self.node.object_dictionary.get_variable(index, subindex).default
            self.values[(index, subindex)] = value
            return value

    def _set(self, ref, value) -> None:
        self.values[(ref.index, ref.subindex)] = value

    def _on_read(self, index, subindex, od):
        return self.values.get((index, subindex))

    def _on_write(self, index, subindex, od, data):
        self._write(index, subindex, od.decode_raw(data))

    def _write(self, index: int, subindex: int, value) -> None:
        """An object written (SDO or RPDO): check it, store it, act on it (may raise an SDO abort)."""
        prof = self.profile
        if index in _PDO_PARAMS:
            self._check_pdo_write(index, subindex, value)
            self._pdos_dirty = True
        elif index == 0x1014:
            self._check_emcy_cob_id(value)
        elif index == 0x1016:
            self._watch_producer(value)
        elif index == 0x1003:
            if value != 0:
                raise SdoAbortedError(ABORT_VALUE_RANGE)
            for sub in range(1, 9):
                self.values[(0x1003, sub)] = 0
        elif index == prof.modes_of_operation.index:
            if value not in prof.supported_modes:
                raise SdoAbortedError(ABORT_VALUE_RANGE)
            self._set(prof.modes_display, value)
            self._profile = self._homing_phase = None
            self._mode_bits = 0
        self.values[(index, subindex)] = value
        if index == prof.controlword.index:
            self._on_controlword(value)

    def _check_emcy_cob_id(self, value: int) -> None:
        """CiA 301 (object 0x1014): bit 31 set = no EMCY; bit 29 (29-bit frame) is refused; the
        CAN-ID may only change while bit 31 is set (old or new value) - SDO abort 0x06090030."""
        old = self.get(0x1014)
        if value & (1 << 29) or (value & 0x7FF != old & 0x7FF and not (value | old) & (1 << 31)):
            raise SdoAbortedError(ABORT_VALUE_RANGE)
        self.node.emcy.cob_id = value & 0x7FF

    @property
    def emcy_enabled(self) -> bool:
        """False when the master invalidated the EMCY COB-ID (0x1014 bit 31)."""
        return not self.get(0x1014) >> 31 and not self.silent

    # -- heartbeat consumer ----------------------------------------------------------------------
    def _watch_producer(self, value: int) -> None:
        """Consumer heartbeat time ``0x1016:01`` = producer node-ID << 16 | time in ms (0 = off).

        As CiA 301 says, the watch starts with the first heartbeat received from the producer."""
        if getattr(self, "_consumer_cob", None) is not None:
            self.network.unsubscribe(self._consumer_cob, self._on_consumed_heartbeat)
        producer, ms = (value >> 16) & 0x7F, value & 0xFFFF
        self._consumer_cob = 0x700 + producer if producer and ms else None
        self._consumer_timeout = ms * 1e-3
        self._consumer_last = None
        if self._consumer_cob is not None:
            self.network.subscribe(self._consumer_cob, self._on_consumed_heartbeat)

    def _on_consumed_heartbeat(self, can_id, data, timestamp) -> None:
        with self._lock:
            self._consumer_last = self._clock()

    def check_heartbeat(self, now: float) -> None:
        """Heartbeat error (EMCY 0x8130, fault reaction) when the watched producer is overdue."""
        last = self._consumer_last
        if last is not None and now - last > self._consumer_timeout and not self.silent:
            self._consumer_last = None      # one error per loss; the watch restarts with the next heartbeat
            logger.warning("node %d: heartbeat of node %d lost for %.3f s", self.id, self._consumer_cob - 0x700,
                           now - last)
            self.emcy(EMCY_HEARTBEAT)

    def _check_pdo_write(self, index, subindex, value) -> None:
        od = self.node.object_dictionary
        if 0x1600 <= index < 0x1800 or 0x1A00 <= index < 0x1C00:
            receive = index < 0x1800
            if subindex == 0:
                bits = sum(self.get(index, s) & 0xFF for s in range(1, value + 1))
                if bits > 64:
                    raise SdoAbortedError(ABORT_PDO_LENGTH)
            elif value:
                var = od.get_variable(value >> 16, (value >> 8) & 0xFF)
                if (var is None or not var.pdo_mappable or len(var) != value & 0xFF
                        or not (var.writable if receive else var.readable)):
                    raise SdoAbortedError(ABORT_NOT_MAPPABLE)

    # -- PDO layouts -----------------------------------------------------------------------------
    def _layout(self, mapping_index: int):
        od = self.node.object_dictionary
        entries, fmt = [], "<"
        for sub in range(1, self.get(mapping_index, 0) + 1):
            value = self.get(mapping_index, sub)
            var = od.get_variable(value >> 16, (value >> 8) & 0xFF)
            entries.append((var.index, var.subindex))
            fmt += var.STRUCT_TYPES[var.data_type].format.lstrip("<")
        return struct.Struct(fmt), entries

    def _build_pdos(self) -> None:
        self.tpdos, rpdos = [], {}
        for n in range(self.profile.tpdo_count):
            cob = self.get(0x1800 + n, 1)
            if not cob >> 31 and self.get(0x1A00 + n, 0):
                layout, entries = self._layout(0x1A00 + n)
                self.tpdos.append(_Pdo(cob & 0x7FF, self.get(0x1800 + n, 2), self.get(0x1800 + n, 3) * 1e-4,
                                       self.optional(0x1800 + n, 5) * 1e-3, layout, entries))
        for n in range(self.profile.rpdo_count):
            cob = self.get(0x1400 + n, 1)
            if not cob >> 31 and self.get(0x1600 + n, 0):
                layout, entries = self._layout(0x1600 + n)
                rpdos[cob & 0x7FF] = _Pdo(cob & 0x7FF, self.get(0x1400 + n, 2), 0.0, self.optional(0x1400 + n, 5) * 1e-3,
                                          layout, entries)
        for cob in self._rpdo_subscribed:
            self.network.unsubscribe(cob, self._on_rpdo)
        self.rpdos = rpdos
        self._rpdo_subscribed = list(rpdos)
        for cob in rpdos:
            self.network.subscribe(cob, self._on_rpdo)
        self._pdos_dirty = False

    def _operational(self) -> bool:
        if self._pdos_dirty:
            self._build_pdos()
        return self.node.nmt._state == NMT_OPERATIONAL and not self.silent

    def _send(self, pdo: _Pdo, now: float) -> bytes:
        data = pdo.layout.pack(*[self.get(i, s) for i, s in pdo.entries])
        pdo.last_sent = now
        self.network.send_message(pdo.cob_id, data)
        return data

    def send_sync_tpdos(self, sync_count: int) -> None:
        """Send the SYNC-triggered TPDOs due at SYNC number ``sync_count`` (1, 2, ...)."""
        self._sync_frames = []
        if not self._operational():
            return
        now = None
        for pdo in self.tpdos:
            if pdo.trans_type <= 240 and sync_count % max(pdo.trans_type, 1) == 0:
                now = now or self._clock()
                self._sync_frames.append((pdo.cob_id, self._send(pdo, now)))

    def resend_sync_tpdos(self) -> None:
        """Send the frames of the last :meth:`send_sync_tpdos` again, unchanged (a repeated SYNC)."""
        if self._operational():
            for cob_id, data in self._sync_frames:
                self.network.send_message(cob_id, data)

    def awaits_setpoint(self) -> bool:
        """Streaming with a synchronous RPDO mapped, and no set-point received since the last SYNC."""
        return (self._operational() and not self._pending_rpdo
                and any(pdo.trans_type <= 240 for pdo in self.rpdos.values()))

    def send_event_tpdos(self, now: float, changed=None) -> None:
        """Send the event-driven TPDOs whose event timer ran out, or that map ``changed`` (index, sub)."""
        if not self._operational():
            return
        for pdo in self.tpdos:
            if pdo.trans_type < 254 or now - pdo.last_sent < pdo.inhibit:
                continue
            if (changed in pdo.entries) or (pdo.event_timer and now - pdo.last_sent >= pdo.event_timer):
                self._send(pdo, now)

    def _on_rpdo(self, can_id, data, timestamp) -> None:
        with self._lock:
            if not self._operational() or can_id not in self.rpdos:
                return
            pdo = self.rpdos[can_id]
            if len(data) < pdo.layout.size:
                self.emcy(EMCY_PDO_LENGTH, fault=False)
                return
            if pdo.trans_type <= 240:
                self._pending_rpdo[can_id] = bytes(data)
            else:
                self._apply_rpdo(pdo, data)

    def _apply_rpdo(self, pdo: _Pdo, data) -> None:
        # the mapped values, decoded by the mapping's own struct, are written as an SDO download
        # would write them (without its encoding to bytes and back: the hot path at 1 kHz)
        pdo.last_received = self._clock()
        for (index, sub), value in zip(pdo.entries, pdo.layout.unpack_from(data)):
            try:
                self._write(index, sub, value)
            except SdoAbortedError as exc:
                logger.warning("node %d: RPDO 0x%03X value for 0x%04X:%02X refused (%s)",
                               self.id, pdo.cob_id, index, sub, exc)

    def apply_pending_rpdos(self) -> None:
        """Apply the synchronous RPDOs received since the last SYNC."""
        pending, self._pending_rpdo = self._pending_rpdo, {}
        for cob, data in pending.items():
            if cob in self.rpdos:
                self._apply_rpdo(self.rpdos[cob], data)

    @property
    def streaming(self) -> bool:
        """OPERATION ENABLED in the cyclic position mode: the drive's time is the SYNC's."""
        return self.state == ENABLED and self.get(0x6060) == self.profile.cyclic_mode

    @property
    def interpolation_period(self) -> float | None:
        """The EPOS4's interpolation period ``0x60C2`` in s while streaming (EPOS2: None)."""
        ref = self.profile.interpolation_period
        if ref is None or not self.streaming:
            return None
        return self.get(ref.index, ref.subindex) * 10.0 ** self.get(ref.index, ref.subindex + 1)

    def check_rpdo_timeout(self, now: float) -> None:
        """RPDO timeout (EMCY 0x8250, fault reaction) while streaming: the deadline monitoring of
        CiA 301, with the RPDO's event timer ``0x140x:05`` (ms, 0 = off) as the deadline.

        A synchronous RPDO's value takes effect at a SYNC, so the deadline counts from the last
        SYNC that applied one: missing SYNC frames and missing set-points both count. As CiA 301
        says, the watch starts with the first value received (and again after each timeout).
        """
        if not self.streaming or self.silent:
            return
        for pdo in self.rpdos.values():
            if pdo.event_timer and pdo.last_received is not None and now - pdo.last_received > pdo.event_timer:
                logger.warning("node %d: no set-point (RPDO 0x%03X) for %.3f s in the cyclic mode",
                               self.id, pdo.cob_id, now - pdo.last_received)
                pdo.last_received = None
                self.emcy(EMCY_RPDO_TIMEOUT)
                return

    # -- SDO and NMT gates ------------------------------------------------------------------------
    def _on_sdo_request(self, can_id, data, timestamp) -> None:
        with self._lock:
            if self.silent or self.node.nmt._state == NMT_STOPPED:
                return
            ccs = data[0] & 0xE0
            if ccs in (0x20, 0x40) and len(data) >= 4:  # initiate download / upload
                key = (data[1] | data[2] << 8, data[3])
                if key in self.sdo_aborts:
                    self.node.sdo._index, self.node.sdo._subindex = key
                    self.node.sdo.abort(self.sdo_aborts[key])
                    return
            self.node.sdo.on_request(can_id, data, timestamp)

    def _on_nmt_command(self, can_id, data, timestamp) -> None:
        with self._lock:
            if self.silent or len(data) < 2 or data[1] not in (0, self.id):
                return
            command = data[0]
            self.node.nmt.on_command(can_id, data, timestamp)
            if command == 0x81:
                self._reset_application()
                self.boot()
            elif command == 0x82:
                for index in list(self.node.data_store):
                    if 0x1000 <= index < 0x2000:
                        del self.node.data_store[index]
                self.values = {k: v for k, v in self.values.items() if not 0x1000 <= k[0] < 0x2000}
                self._pdos_dirty = True
                self._watch_producer(0)
                self.boot()

    def boot(self) -> None:
        """Boot-up message, then PRE-OPERATIONAL with the heartbeat of ``0x1017``."""
        self.node.emcy.cob_id = self.get(0x1014) & 0x7FF
        self.node.nmt.send_command(0x81)   # -> INITIALISING, sends the boot-up frame
        self.node.nmt.send_command(NMT_ENTER_PRE_OPERATIONAL)   # starts the heartbeat

    # -- EMCY and faults ----------------------------------------------------------------------------
    def emcy(self, code: int, fault: bool = True) -> None:
        """Signal an error: EMCY frame, ``0x1001``/``0x1003`` updated; with ``fault``, go to FAULT."""
        register = error_register(code)
        history = [self.get(0x1003, s) for s in range(1, 8)]
        for sub, value in enumerate([code] + history, start=1):
            self.values[(0x1003, sub)] = value
        self.values[(0x1003, 0)] = min(self.get(0x1003, 0) + 1, 8)
        self.values[(0x1001, 0)] = register
        if fault:
            self._set(self.profile.error_code, code)
            if self.state not in (FAULT_REACTION, FAULT):
                self._enter(FAULT_REACTION if self.powered else FAULT)
        if self.emcy_enabled:
            self.node.emcy.send(code, register)

    def _fault_reset(self) -> None:
        self._set(self.profile.error_code, 0)
        self.values[(0x1001, 0)] = 0
        self._enter(DISABLED)
        if self.emcy_enabled:
            self.node.emcy.reset()

    # -- CiA 402 ----------------------------------------------------------------------------------
    def _statusword(self) -> int:
        sw = state_bits(self.state) | SW_REMOTE
        if self.state not in (NOT_READY, DISABLED):
            sw |= SW_VOLTAGE_ENABLED
        if self.state in (ENABLED, QUICK_STOP):
            sw |= self._mode_bits
        return sw | (SW_HOMED if self._homed else 0)

    def _update_statusword(self) -> None:
        sw = self._statusword()
        if sw != self.get(0x6041):
            self._set(self.profile.statusword, sw)
            self.send_event_tpdos(self._clock(), (0x6041, 0))

    def _enter(self, state: str) -> None:
        if state in (ENABLED, QUICK_STOP) and self.state not in (ENABLED, QUICK_STOP):
            self.demand, self.demand_velocity = float(self.actual), 0.0
            self._last_cyclic, self._profile, self._homing_phase = None, None, None
            for pdo in self.rpdos.values():
                pdo.last_received = None                 # the RPDO watch starts with the next set-point
        if state == QUICK_STOP:
            self._quick_stop_since = None
        self.state = state
        self._update_statusword()

    def _on_controlword(self, cw: int) -> None:
        previous, self._cw = self._cw, cw
        state = self.state
        if state in (FAULT_REACTION, FAULT):
            if state == FAULT and cw & CW_FAULT_RESET and not previous & CW_FAULT_RESET:
                self._fault_reset()
            return
        if cw & CW_FAULT_RESET:
            return
        new = state
        if cw & 0x02 == 0:                                 # disable voltage
            new = DISABLED
        elif cw & 0x06 == 0x02:                            # quick stop
            new = QUICK_STOP if state == ENABLED else (DISABLED if state in (READY, SWITCHED_ON) else state)
        elif cw & 0x07 == 0x06:                            # shutdown
            new = READY if state in (DISABLED, SWITCHED_ON, ENABLED) else state
        elif cw & 0x0F == 0x07:                            # switch on / disable operation
            new = SWITCHED_ON if state in (READY, ENABLED) else state
        elif cw & 0x0F == 0x0F:                            # enable operation
            new = ENABLED if state in (READY, SWITCHED_ON, QUICK_STOP) else state
        if new != state:
            self._enter(new)
        if self.state == ENABLED and cw & CW_NEW_SETPOINT and not previous & CW_NEW_SETPOINT:
            self._start_move(cw)
        elif self.get(0x6060) == MODE_PPM and not cw & CW_NEW_SETPOINT:
            self._mode_bits &= ~SW_BIT12                  # set-point acknowledge follows bit 4
        self._update_statusword()

    def _start_move(self, cw: int) -> None:
        mode = self.get(0x6060)
        if mode == MODE_PPM:
            target = self.get(0x607A) + (self._profile[0] if (cw & CW_RELATIVE and self._profile) else 0)
            lo, hi = self.get(0x607D, 1), self.get(0x607D, 2)
            self._profile = [min(max(target, lo), hi), self.get(0x6081)]
            self._mode_bits = SW_BIT12
        elif mode == MODE_HMM:
            method = self.get(0x6098)
            self._homed = False
            if method in HOME_HERE:
                self._finish_homing()
            else:
                direction = -1 if method % 2 else 1
                travel = direction * HOMING_TRAVEL_TURNS * self.scaling.counts_per_turn
                self._homing_phase = 1
                self._homing_start = self.demand
                self._profile = [self.demand + travel, self.get(0x6099, 1)]
                self._mode_bits = 0

    def _finish_homing(self) -> None:
        # methods 35/37 home on the actual position; a search move ends on the reference it found,
        # where the demand stops (the axis settles onto it)
        end = self.demand if self._next_demand is None else self._next_demand
        reference = self.actual if self._homing_phase is None else round(end)
        shift = reference - self.get(self.profile.home_position.index)
        self.offset += shift
        self.actual -= shift
        self._set(self.profile.position_actual, self.actual)
        self.demand -= shift
        if self._next_demand is not None:
            self._next_demand -= shift
        self.demand_velocity, self._profile, self._homing_phase, self._last_cyclic = 0.0, None, None, None
        self._demand_curve = (0.0, 0.0)                    # at rest on the reference
        self._homed = True
        self._mode_bits = SW_BIT12 | SW_TARGET_REACHED

    # -- per-period motion ---------------------------------------------------------------------------
    @property
    def powered(self) -> bool:
        """The position loop is closed (also while quick-stopping and during the fault reaction)."""
        return self.state in (ENABLED, QUICK_STOP, FAULT_REACTION)

    def plan(self, period: float) -> tuple[float, float, float, float]:
        """The position demand over the coming period: coefficients ``(c0, c1, c2, c3)`` of
        ``q_d(t) = c0 + c1 t + c2 t^2 + c3 t^3`` (counts, ``t`` in s from the period start)."""
        self._demand_curve = (0.0, 0.0)
        history, self._last_cyclic = self._last_cyclic, None     # kept only while streaming
        if not self.powered:
            self.demand, self.demand_velocity = float(self.actual), 0.0
            return self.demand, 0.0, 0.0, 0.0
        mode = self.get(0x6060)
        if self.state in (QUICK_STOP, FAULT_REACTION):
            self._ramp_down(period)
        elif mode == self.profile.cyclic_mode:
            ref = self.profile.cyclic_target
            target = min(max(self.get(ref.index, ref.subindex), self.get(0x607D, 1)), self.get(0x607D, 2))
            self._interpolate(float(target), period, history)
            self._mode_bits = SW_BIT12  # "drive follows the command value"
        elif self._profile is not None and not self._cw & CW_HALT:
            self._profile_step(period)
        else:
            self.demand_velocity = 0.0
        return (self.demand, self.demand_velocity) + self._demand_curve

    def _ramp_down(self, period: float) -> None:
        """Decelerate the demand to standstill at the quick stop deceleration 0x6085 (rpm/s)."""
        deceleration = max(self.get(0x6085), 1) * self.scaling.counts_per_turn / 60.0     # counts/s^2
        v = self.demand_velocity
        if period > 0 and v:
            end = v - math.copysign(min(abs(v), deceleration * period), v)
            self._demand_curve = (0.5 * (end - v) / period, 0.0)

    def _interpolate(self, target: float, period: float, history) -> None:
        """Uniform cubic B-spline segment of the last four targets (see the module docstring);
        ``history``: the three previous targets, or None when streaming starts (the held demand)."""
        p2, p1, p0 = history or (self.demand,) * 3
        self._last_cyclic = (target, p2, p1)
        if not period > 0:
            return
        self.demand = (p0 + 4.0 * p1 + p2) / 6.0
        self.demand_velocity = (p2 - p0) / (2.0 * period)
        self._demand_curve = ((p0 - 2.0 * p1 + p2) / (2.0 * period**2),
                              (target - 3.0 * p2 + 3.0 * p1 - p0) / (6.0 * period**3))

    def _profile_step(self, period: float) -> None:
        """Advance the trapezoidal profile (PPM or homing move) by one period.

        The demand over the period is the cubic through its start and end positions and
        velocities (a parabola while accelerating, cruising or braking); braking starts where
        the stopping distance at the profile acceleration reaches the remaining travel and then
        decelerates uniformly onto the target, so the demand arrives there at rest.
        """
        if not period > 0:
            return
        target, speed_rpm = self._profile
        counts_per_s = self.scaling.counts_per_turn / 60.0
        vmax = max(speed_rpm, 1) * counts_per_s
        acc = max(self.get(0x6083 if self._homing_phase is None else 0x609A), 1) * counts_per_s
        start, v = self.demand, self.demand_velocity
        remaining = target - start
        direction = math.copysign(1.0, remaining)
        new_pos, new_v = float(target), 0.0
        if abs(remaining) >= 1.0:
            if v * direction > 0 and v * v / (2 * acc) >= abs(remaining):      # brake onto the target
                new_v = v - direction * v * v / (2 * abs(remaining)) * period
            else:                                                               # accelerate / cruise
                new_v = max(-vmax, min(vmax, v + direction * acc * period))
            new_pos = start + 0.5 * (v + new_v) * period
            if new_v * direction <= 0 or (target - new_pos) * direction <= 0:
                new_pos, new_v = float(target), 0.0
        travel = new_pos - start
        self._demand_curve = ((3.0 * travel - (2.0 * v + new_v) * period) / period**2,
                              ((v + new_v) * period - 2.0 * travel) / period**3)
        self._next_demand = new_pos
        if new_pos == target:
            self._profile_done()

    def _profile_done(self) -> None:
        if self._homing_phase == 1:
            self._homing_phase = 2
            self._profile = [self._homing_start, self.get(0x6099, 2)]
        elif self._homing_phase == 2:
            self._finish_homing()
        else:
            self._profile = None
            self._mode_bits |= SW_TARGET_REACHED

    def update(self, counts: int, rpm: int, milliamps: int, period: float) -> None:
        """Take the sensor readings of the period start; advance the demand; check the following error."""
        self.actual = counts
        self._set(self.profile.position_actual, counts)
        self._set(self.profile.velocity_actual, rpm)
        self._set(self.profile.current_actual, milliamps)
        if self.profile.current_actual.index == 0x30D1:
            self.values[(0x30D1, 1)] = milliamps
        self._set(self.profile.position_demand, int(round(self.demand)))
        error = int(round(self.demand - counts)) if self.powered else 0
        self._set(self.profile.following_error_actual, error)
        window = self.get(0x6065)
        lo, hi = self.profile.software_position_limit
        if self.state == ENABLED and 0 < window < 0xFFFFFFFF and abs(error) > window:
            self.emcy(EMCY_FOLLOWING_ERROR)
        elif self.powered and not self.get(lo.index, lo.subindex) <= counts <= self.get(hi.index, hi.subindex):
            self.emcy(self.profile.software_limit_error)
        if self.state == QUICK_STOP and rpm == 0 and self.get(0x605A) <= 4:
            self._enter(DISABLED)
        elif self.state == FAULT_REACTION and abs(self.demand_velocity) < 1e-6:
            self._enter(FAULT)                              # ramp done: power off
        c2, c3 = self._demand_curve
        if self._next_demand is not None:                   # exact end of a profile step
            self.demand, self._next_demand = self._next_demand, None
        else:
            self.demand += (self.demand_velocity + (c2 + c3 * period) * period) * period
        self.demand_velocity += (2.0 * c2 + 3.0 * c3 * period) * period
        self._update_statusword()
