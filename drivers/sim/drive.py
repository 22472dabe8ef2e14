"""One emulated EPOS2/EPOS4 drive: a ``canopen.LocalNode`` plus what it lacks.

The drive is built from parts the way canopen splits a node: object values
(:mod:`drivers.sim.objects`), PDOs (:mod:`drivers.sim.pdo`), the CiA 402 state machine
(:mod:`drivers.sim.state_machine`) and the demand of the operating modes
(:mod:`drivers.sim.modes`); this module holds the drive that joins them, with the SDO and NMT
gates, boot-up and reset, EMCY, the heartbeat consumer, the following error, the C2 set-point
interpolation and the averaged current. Positions here are drive units (counts); every handler
runs under the rig's lock, on the rig's clock. How each part is built and why (the set-point
spline, the averaged current's filter, the SDO aborts): ``docs/simulated-rig.md``.
"""

from __future__ import annotations

import logging
import struct

import canopen
from canopen.sdo import SdoAbortedError

from drivers.cia import (CW_FAULT_RESET, CW_HALT, CW_NEW_SETPOINT, CW_RELATIVE, DISABLED, EMCY_COB_ID, ENABLED,
                         ERROR_CODE, ERROR_HISTORY, ERROR_REGISTER, FAULT, FAULT_REACTION, HEARTBEAT_CONSUMER,
                         MODE_HMM, MODE_PPM, NMT_ENTER_PRE_OPERATIONAL, QUICK_STOP, SW_BIT12,
                         SW_TARGET_REACHED)
from drivers.profiles import AveragingStep, get_profile, make_object_dictionary
from drivers.units import AxisScaling

from . import modes
from .objects import ObjectStore
from .pdo import EMCY_RPDO_TIMEOUT, PDO_PARAMETERS, PdoEngine
from .state_machine import POWERED, next_state, statusword

__all__ = ["EmulatedDrive", "error_register"]

logger = logging.getLogger(__name__)

HOME_HERE = (35, 37)  # homing methods "actual position" (CiA 402 35, maxon 37)
HOMING_TRAVEL_TURNS = 0.5  # motor turns of the emulated search move of the other methods

EMCY_FOLLOWING_ERROR, EMCY_OVERCURRENT, EMCY_HEARTBEAT = 0x8611, 0x2310, 0x8130
ABORT_VALUE_RANGE = 0x06090030
#: CiA 301 SDO abort codes: object does not exist in the object dictionary; sub-index does not exist
ABORT_NO_OBJECT, ABORT_NO_SUBINDEX = 0x06020000, 0x06090011
#: how a drive without a quick stop option code 0x605A (the EPOS2) ends a quick stop: on the
#: quick stop ramp, then SWITCH ON DISABLED, as CiA 402 code 2 (the master's quick stop ends in
#: SWITCH ON DISABLED from QUICK STOP ACTIVE too)
FIXED_QUICK_STOP_OPTION = 2
#: NMT command specifiers the drive acts on beyond canopen's state change
NMT_RESET_NODE, NMT_RESET_COMMUNICATION = 0x81, 0x82


def error_register(code: int) -> int:
    """CiA 301 error register (0x1001) bits for an EMCY error code (bit 0 = generic, always)."""
    bits = 0x01
    bits |= {0x2: 0x02, 0x3: 0x04, 0x4: 0x08}.get(code >> 12, 0)
    if code & 0xFF00 == 0x8100:
        bits |= 0x10
    elif code >> 12 == 0x8:
        bits |= 0x20
    return bits


def _sdo_initiate(command: int) -> bool:
    """An SDO client request that names an object: initiate download or upload, or the
    initiation of a block upload or download (CiA 301)."""
    return command & 0xE0 in (0x20, 0x40) or command & 0xE3 == 0xA0 or command & 0xE1 == 0xC0


class EmulatedDrive:
    """One emulated drive on a ``canopen.Network`` (the rig owns the network and the plant).

    Args:
        node_id: CANopen node-ID.
        profile_name: ``"epos2"`` or ``"epos4"``, or a :class:`~drivers.profiles.DriveProfile`
            (e.g. a variant with the RPDO deadline ``0x140x:05``, which neither generation has).
        scaling: the axis' :class:`AxisScaling` (counts per motor turn for the rpm limits).
        network: the rig's network (the node is added to it).
        lock: the rig's lock, held by every handler.
        clock: ``clock() -> float`` seconds (monotonic; the rig's clock), for event timers, inhibit
            times and the RPDO watch.
        heartbeat_clock: the clock of the heartbeat consumer (default ``clock``); in lockstep the
            simulated time, so that the watch of the master counts SYNC periods.
        dictionary: the drive's object dictionary (default the profile's,
            :func:`drivers.profiles.make_object_dictionary`): e.g. one of maxon's files, to emulate
            a firmware with other objects (an SDO request for an object it lacks is aborted as
            the drive would).
    """

    # set at power-up (:meth:`_reset_application`) and by the handlers; declared for their types
    offset: int | None                 # plant counts - reported counts (the rig sets it)
    actual: int                        # reported position, counts
    _consumer_cob: int | None          # the watched producer's heartbeat COB-ID
    _last_cyclic: modes.CyclicTargets | None
    _move: list | None                 # [target counts, speed rpm] of a PPM/homing move
    _homing_phase: int | None
    _quick_stop_since: float | None
    _average_period: float | None

    def __init__(self, node_id: int, profile_name: str, scaling: AxisScaling, network: canopen.Network,
                 lock, clock, heartbeat_clock=None, dictionary=None):
        self.profile = get_profile(profile_name)
        self.scaling = scaling
        self.node = canopen.LocalNode(node_id, dictionary if dictionary is not None
                                      else make_object_dictionary(profile_name, node_id))
        self.id = node_id
        self._lock = lock
        self._clock = clock
        self._heartbeat_clock = heartbeat_clock or clock
        self._counted_heartbeat: float | None = None   # simulated time of the last heartbeat sent by SYNC count
        network.add_node(self.node)
        self.network = network
        self.store = ObjectStore(self.node.object_dictionary)
        self.pdo = PdoEngine(node_id, self.profile, self.store, network, clock, lock, self._write, self.emcy,
                             self._nmt_operational)
        # gate SDO and NMT through this class (silence, STOPPED, injected aborts, resets)
        network.unsubscribe(self.node.sdo.rx_cobid, self.node.sdo.on_request)
        network.unsubscribe(0, self.node.nmt.on_command)
        network.subscribe(self.node.sdo.rx_cobid, self._on_sdo_request)
        network.subscribe(0, self._on_nmt_command)
        self.node.add_read_callback(self._on_read)
        self.node.add_write_callback(self._on_write)
        self.silent = False
        self.sdo_aborts: dict[tuple[int, int], int] = {}
        self._reset_application()

    # -- object values -------------------------------------------------------------------------
    def _reset_application(self) -> None:
        self.node.data_store.clear()
        self.store.values.clear()
        self.state = DISABLED
        self._cw = 0
        self._mode_bits = 0           # statusword bits 10, 12, 13, 15 of the mode logic
        # offset, counts: plant counts - reported counts (set by the rig at power-up); a reset
        # re-zeroes the incremental encoder where the axis stands, as at power-up
        offset = getattr(self, "offset", None)
        self.offset = None if offset is None else offset + self.actual
        self.actual = 0               # reported position, counts
        self._demand = modes.Demand()
        self._last_cyclic = None      # the three last cyclic targets, counts
        self._move = None             # [target counts, speed rpm] of a PPM/homing move
        self._homing_phase = None
        self._homing_start = 0.0
        self._homed = False
        self._quick_stop_since = None
        # the running average of the current (mA, unrounded), from rest at power-up
        self._averaged, self._last_current = 0.0, 0.0
        self._average_period, self._average_step = None, AveragingStep(1.0, 0.0, 0.0)
        self.pdo.reset()
        self._watch_producer(0)
        self.store[self.profile.statusword] = self._statusword()

    @property
    def values(self) -> dict[tuple[int, int], object]:
        """The object dictionary's values by ``(index, sub-index)``, raw (the store's own)."""
        return self.store.values

    @property
    def demand(self) -> float:
        """Position demand at the period start, counts."""
        return self._demand.position

    @property
    def demand_velocity(self) -> float:
        """Demand velocity at the period start, counts/s."""
        return self._demand.velocity

    def get(self, index: int, subindex: int = 0):
        """Current value of an object (written value, live value or default)."""
        return self.store.get(index, subindex)

    def optional(self, index: int, subindex: int = 0, default=0):
        """Value of an object this drive may lack (:meth:`ObjectStore.optional`)."""
        return self.store.optional(index, subindex, default)

    def _on_read(self, index, subindex, od):
        return self.store.values.get((index, subindex))

    def _on_write(self, index, subindex, od, data):
        self._write(index, subindex, od.decode_raw(data))

    def _write(self, index: int, subindex: int, value) -> None:
        """An object written (SDO or RPDO): check it, store it, act on it (may raise an SDO abort)."""
        prof = self.profile
        if index in PDO_PARAMETERS:
            self.pdo.check_write(index, subindex, value)
        elif index == EMCY_COB_ID:
            self._check_emcy_cob_id(value)
        elif index == HEARTBEAT_CONSUMER[0]:
            self._watch_producer(value)
        elif index == ERROR_HISTORY:
            if value != 0:
                raise SdoAbortedError(ABORT_VALUE_RANGE)
            for sub in range(1, prof.error_history + 1):
                self.store.values[(ERROR_HISTORY, sub)] = 0
        elif index == prof.modes_of_operation.index:
            if value not in prof.supported_modes:
                raise SdoAbortedError(ABORT_VALUE_RANGE)
            self.store[prof.modes_display] = value
            self._move = self._homing_phase = None
            self._mode_bits = 0
        self.store.values[(index, subindex)] = value
        if index == prof.controlword.index:
            self._on_controlword(value)

    def _check_emcy_cob_id(self, value: int) -> None:
        """CiA 301 (object 0x1014): bit 31 set = no EMCY; bit 29 (29-bit frame) is refused; the
        CAN-ID may only change while bit 31 is set (old or new value) - SDO abort 0x06090030."""
        old = self.get(EMCY_COB_ID)
        if value & (1 << 29) or (value & 0x7FF != old & 0x7FF and not (value | old) & (1 << 31)):
            raise SdoAbortedError(ABORT_VALUE_RANGE)
        self.node.emcy.cob_id = value & 0x7FF

    @property
    def emcy_enabled(self) -> bool:
        """False when the master invalidated the EMCY COB-ID (0x1014 bit 31)."""
        return not self.get(EMCY_COB_ID) >> 31 and not self.silent

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
            self._consumer_last = self._heartbeat_clock()

    def heartbeat_by_sync(self, now: float) -> None:
        """In lockstep: the producer heartbeat (``0x1017``) in simulated time ``now`` (s), sent when
        a producer period or more has passed since the last one sent so, so that the master, whose
        watch counts SYNC periods too, sees one in every period of simulated time, however the
        host schedules the rig's wall-clock heartbeat."""
        ms = self.optional(0x1017)
        if not ms or self.silent:
            self._counted_heartbeat = None
            return
        if self._counted_heartbeat is not None and now - self._counted_heartbeat < ms * 1e-3 - 1e-9:
            return
        self._counted_heartbeat = now
        self.network.send_message(0x700 + self.id, bytes([self.node.nmt._state]))

    def check_heartbeat(self, now: float) -> None:
        """Heartbeat error (EMCY 0x8130, fault reaction) when the watched producer is overdue."""
        last = self._consumer_last
        if last is not None and now - last > self._consumer_timeout and not self.silent:
            self._consumer_last = None      # one error per loss; the watch restarts with the next heartbeat
            logger.warning("node %d: heartbeat of node %d lost for %.3f s", self.id, self._consumer_cob - 0x700,
                           now - last)
            self.emcy(EMCY_HEARTBEAT)

    # -- PDOs (drivers.sim.pdo) -------------------------------------------------------------------
    def _nmt_operational(self) -> bool:
        return self.node.nmt.state == "OPERATIONAL" and not self.silent

    def send_sync_tpdos(self, sync_count: int) -> None:
        """Send the SYNC-triggered TPDOs due at SYNC number ``sync_count`` (1, 2, ...)."""
        self.pdo.send_sync_tpdos(sync_count)

    def resend_sync_tpdos(self) -> None:
        """Send the frames of the last SYNC's TPDOs again, unchanged (a repeated SYNC)."""
        self.pdo.resend_sync_tpdos()

    @property
    def sync_frames_sent(self) -> int:
        """The TPDO frames the last :meth:`send_sync_tpdos` sent."""
        return len(self.pdo.sync_frames)

    def awaits_setpoint(self) -> bool:
        """Streaming with a synchronous RPDO mapped, and no set-point received since the last SYNC."""
        return self.pdo.awaits_setpoint()

    def send_event_tpdos(self, now: float, changed=None) -> None:
        """Send the event-driven TPDOs whose event timer ran out, or that map ``changed`` (index, sub)."""
        self.pdo.send_event_tpdos(now, changed)

    def apply_pending_rpdos(self) -> None:
        """Apply the synchronous RPDOs received since the last SYNC."""
        self.pdo.apply_pending()

    @property
    def streaming(self) -> bool:
        """OPERATION ENABLED in the cyclic position mode: the drive's time is the SYNC's."""
        return self.state == ENABLED and self.store[self.profile.modes_of_operation] == self.profile.cyclic_mode

    @property
    def interpolation_period(self) -> float | None:
        """The EPOS4's interpolation period ``0x60C2`` in s while streaming (EPOS2: None)."""
        ref = self.profile.interpolation_period
        if ref is None or not self.streaming:
            return None
        return self.get(ref.index, ref.subindex) * 10.0 ** self.get(ref.index, ref.subindex + 1)

    def check_rpdo_timeout(self, now: float) -> None:
        """RPDO timeout (EMCY 0x8250, fault reaction) while streaming: the deadline monitoring of
        CiA 301 with the RPDO's event timer ``0x140x:05`` (:meth:`PdoEngine.check_timeout`)."""
        if self.streaming and not self.silent and self.pdo.check_timeout(now):
            self.emcy(EMCY_RPDO_TIMEOUT)

    # -- SDO and NMT gates ------------------------------------------------------------------------
    def _on_sdo_request(self, can_id, data, timestamp) -> None:
        with self._lock:
            if self.silent or self.node.nmt.state == "STOPPED":
                return
            if _sdo_initiate(data[0]) and len(data) >= 4:
                key = (data[1] | data[2] << 8, data[3])
                code = self.sdo_aborts.get(key)
                if code is None and not self.store.has(*key):
                    code = ABORT_NO_SUBINDEX if key[0] in self.node.object_dictionary else ABORT_NO_OBJECT
                if code is not None:
                    # CiA 301 abort transfer: 0x80, index, sub-index, abort code
                    self.network.send_message(self.node.sdo.tx_cobid, struct.pack("<BHBI", 0x80, *key, code))
                    return
            self.node.sdo.on_request(can_id, data, timestamp)

    def _on_nmt_command(self, can_id, data, timestamp) -> None:
        with self._lock:
            if self.silent or len(data) < 2 or data[1] not in (0, self.id):
                return
            command = data[0]
            self.node.nmt.on_command(can_id, data, timestamp)
            if command == NMT_RESET_NODE:
                self._reset_application()
                self.boot()
            elif command == NMT_RESET_COMMUNICATION:
                for index in list(self.node.data_store):
                    if 0x1000 <= index < 0x2000:
                        del self.node.data_store[index]
                values = self.store.values
                for key in [k for k in values if 0x1000 <= k[0] < 0x2000]:
                    del values[key]
                self.pdo.dirty = True
                self._watch_producer(0)
                self.boot()

    def boot(self) -> None:
        """Boot-up message, then PRE-OPERATIONAL with the heartbeat of ``0x1017``."""
        self.node.emcy.cob_id = self.get(EMCY_COB_ID) & 0x7FF
        self.node.nmt.send_command(NMT_RESET_NODE)               # -> INITIALISING, sends the boot-up frame
        self.node.nmt.send_command(NMT_ENTER_PRE_OPERATIONAL)    # starts the heartbeat

    # -- EMCY and faults ----------------------------------------------------------------------------
    def emcy(self, code: int, fault: bool = True) -> None:
        """Signal an error: EMCY frame, ``0x1001``/``0x1003`` updated (the newest first, as many
        as the drive keeps); with ``fault``, ``0x603F`` (a drive that has it) and FAULT."""
        register = error_register(code)
        values = self.store.values
        depth = self.profile.error_history
        history = [code] + [self.get(ERROR_HISTORY, s) for s in range(1, depth)]
        for sub, value in enumerate(history, start=1):
            values[(ERROR_HISTORY, sub)] = value
        values[(ERROR_HISTORY, 0)] = min(self.get(ERROR_HISTORY, 0) + 1, depth)
        values[(ERROR_REGISTER, 0)] = register
        if fault:
            if self.store.has(ERROR_CODE):
                values[(ERROR_CODE, 0)] = code
            if self.state not in (FAULT_REACTION, FAULT):
                self._enter(FAULT_REACTION if self.powered else FAULT)
        if self.emcy_enabled:
            self.node.emcy.send(code, register)

    def _fault_reset(self) -> None:
        """The error goes (``0x603F`` and the error register cleared; the history stays)."""
        if self.store.has(ERROR_CODE):
            self.store.values[(ERROR_CODE, 0)] = 0
        self.store.values[(ERROR_REGISTER, 0)] = 0
        self._enter(DISABLED)
        if self.emcy_enabled:
            self.node.emcy.reset()

    # -- CiA 402 (drivers.sim.state_machine) --------------------------------------------------------
    def _statusword(self) -> int:
        return statusword(self.state, self._mode_bits, self._homed)

    def _update_statusword(self) -> None:
        sw = self._statusword()
        ref = self.profile.statusword
        if sw != self.store[ref]:
            self.store[ref] = sw
            self.pdo.send_event_tpdos(self._clock(), (ref.index, ref.subindex))

    def _enter(self, state: str) -> None:
        if state in (ENABLED, QUICK_STOP) and self.state not in (ENABLED, QUICK_STOP):
            self._demand.position, self._demand.velocity = float(self.actual), 0.0
            self._last_cyclic, self._move, self._homing_phase = None, None, None
            self.pdo.forget_received()                  # the RPDO watch starts with the next set-point
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
        new = next_state(state, cw)
        if new != state:
            self._enter(new)
        mode = self.store[self.profile.modes_of_operation]
        if self.state == ENABLED and cw & CW_NEW_SETPOINT and not previous & CW_NEW_SETPOINT:
            self._start_move(cw)
        elif mode == MODE_PPM and not cw & CW_NEW_SETPOINT:
            self._mode_bits &= ~SW_BIT12                  # set-point acknowledge follows bit 4
        self._update_statusword()

    # -- operating modes (drivers.sim.modes) --------------------------------------------------------
    def _start_move(self, cw: int) -> None:
        prof, store = self.profile, self.store
        mode = store[prof.modes_of_operation]
        if mode == MODE_PPM:
            target = store[prof.target_position] + (self._move[0] if (cw & CW_RELATIVE and self._move) else 0)
            lo, hi = (store[ref] for ref in prof.software_position_limit)
            self._move = [min(max(target, lo), hi), store[prof.profile_velocity]]
            self._mode_bits = SW_BIT12
        elif mode == MODE_HMM:
            method = store[prof.homing_method]
            self._homed = False
            if method in HOME_HERE:
                self._finish_homing()
            else:
                direction = -1 if method % 2 else 1
                travel = direction * HOMING_TRAVEL_TURNS * self.scaling.counts_per_turn
                self._homing_phase = 1
                self._homing_start = self._demand.position
                self._move = [self._demand.position + travel, store[prof.homing_speeds[0]]]
                self._mode_bits = 0

    def _finish_homing(self) -> None:
        # methods 35/37 home on the actual position; a search move ends on the reference it found,
        # where the demand stops (the axis settles onto it)
        d = self._demand
        end = d.position if d.end is None else d.end
        reference = self.actual if self._homing_phase is None else round(end)
        shift = reference - self.store[self.profile.home_position]
        self.offset += shift
        self.actual -= shift
        self.store[self.profile.position_actual] = self.actual
        d.position -= shift
        if d.end is not None:
            d.end -= shift
        d.velocity, self._move, self._homing_phase, self._last_cyclic = 0.0, None, None, None
        d.curve = (0.0, 0.0)                               # at rest on the reference
        self._homed = True
        self._mode_bits = SW_BIT12 | SW_TARGET_REACHED

    def _quick_stop_option(self) -> int:
        """The quick stop option code: ``0x605A``, or the fixed behaviour of a drive without it."""
        option_code = self.profile.quick_stop_option_code
        return FIXED_QUICK_STOP_OPTION if option_code is None else self.store[option_code]

    @property
    def powered(self) -> bool:
        """The position loop is closed (also while quick-stopping and during the fault reaction)."""
        return self.state in POWERED

    def _average(self, milliamps: float, period: float) -> int:
        """The averaged current (mA, whole, in its object's range) after ``period`` s over which
        the measured current ran linearly from the last sample to ``milliamps`` (mA): the
        generation's running average (:meth:`drivers.profiles.AveragingFilter.over_period`)."""
        if period != self._average_period:
            self._average_period = period
            self._average_step = self.profile.current_averaging.over_period(period)
        step = self._average_step
        a, b0, b1 = step.pole, step.b0, step.b1
        self._averaged = a * self._averaged + b0 * self._last_current + b1 * milliamps
        self._last_current = milliamps
        lowest, highest = self.profile.current_averaged.value_range
        return min(max(int(round(self._averaged)), lowest), highest)

    def plan(self, period: float) -> modes.Cubic:
        """The position demand over the coming period (counts, :class:`~drivers.sim.modes.Cubic`)."""
        prof, store, d = self.profile, self.store, self._demand
        d.curve = (0.0, 0.0)
        history, self._last_cyclic = self._last_cyclic, None     # kept only while streaming
        if not self.powered:
            d.position, d.velocity = float(self.actual), 0.0
            return d.coefficients()
        mode = store[prof.modes_of_operation]
        counts_per_s = self.scaling.counts_per_turn / 60.0       # per rpm
        if self.state in (QUICK_STOP, FAULT_REACTION):
            modes.ramp_down(d, max(store[prof.quick_stop_deceleration], 1) * counts_per_s, period)
        elif mode == prof.cyclic_mode:
            low, high = prof.software_position_limit
            target = min(max(store[prof.cyclic_target], store[low]), store[high])
            self._last_cyclic = modes.cyclic_segment(d, float(target), period, history)
            self._mode_bits = SW_BIT12  # "drive follows the command value"
        elif self._move is not None and not self._cw & CW_HALT:
            if period > 0:
                target, speed_rpm = self._move
                acc = prof.profile_acceleration if self._homing_phase is None else prof.homing_acceleration
                if modes.profile_step(d, target, max(speed_rpm, 1) * counts_per_s,
                                      max(store[acc], 1) * counts_per_s, period):
                    self._move_done()
        else:
            d.velocity = 0.0
        return d.coefficients()

    def _move_done(self) -> None:
        if self._homing_phase == 1:
            self._homing_phase = 2
            self._move = [self._homing_start, self.store[self.profile.homing_speeds[1]]]
        elif self._homing_phase == 2:
            self._finish_homing()
        else:
            self._move = None
            self._mode_bits |= SW_TARGET_REACHED

    def update(self, counts: int, rpm: int, milliamps: float, period: float) -> None:
        """Take the sensor readings of the period start (``milliamps``: the current the drive
        measures, mA, before its 1 mA resolution), the ``period`` (s) since the last ones;
        advance the demand; check the following error."""
        prof, store, d = self.profile, self.store, self._demand
        values = store.values                   # the live values, written straight in
        powered = self.powered
        self.actual = counts
        values[prof.position_actual.key] = counts
        values[prof.velocity_actual.key] = rpm
        values[prof.current_actual.key] = int(round(milliamps))
        values[prof.current_averaged.key] = self._average(milliamps, period)
        values[prof.position_demand.key] = int(round(d.position))
        error = int(round(d.position - counts)) if powered else 0
        lowest, highest = prof.following_error_actual.value_range   # the EPOS2's 0x20F4 is 16 bits
        values[prof.following_error_actual.key] = min(max(error, lowest), highest)
        window = store[prof.following_error_window]
        lo, hi = prof.software_position_limit
        if self.state == ENABLED and 0 < window < 0xFFFFFFFF and abs(error) > window:
            self.emcy(EMCY_FOLLOWING_ERROR)
        elif powered and not store[lo] <= counts <= store[hi]:
            self.emcy(prof.software_limit_error)
        if self.state == QUICK_STOP and rpm == 0 and self._quick_stop_option() <= 4:
            self._enter(DISABLED)
        elif self.state == FAULT_REACTION and abs(d.velocity) < 1e-6:
            self._enter(FAULT)                              # ramp done: power off
        d.advance(period)
        self._update_statusword()
