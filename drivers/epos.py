"""Master-side driver of maxon EPOS2/EPOS4 drives on canopen: one :class:`EposDrive` per node,
:class:`DriveGroup` for the six drives of the rig.

Everything that talks SDO (bring-up, limits, modes, the CiA 402 power state machine, homing,
point-to-point moves, stopping after a fault) runs in the calling thread. The streaming run
(:meth:`DriveGroup.run_cyclic`) takes its SYNC from the group's :class:`drivers.sync.SyncSource`
(for real drives :class:`drivers.sync.PeriodicSync`: the kernel BCM on SocketCAN, else a
:class:`drivers.bus.GridPeriodicTask` that skips late slots instead of bursting) and, from the
notifier thread, answers each SYNC with the next set-points as RPDO frames; it never calls SDO
there. The waits of the calling thread count in the SYNC source's time. State machine transitions use canopen's CiA 402 tables (:class:`canopen.profiles.p402.State402`)
over SDO, which also covers the EPOS2's maxon-specific negative modes (canopen's ``op_mode``
property does not know them).
"""

from __future__ import annotations

import logging
import os
import time
from contextlib import AbstractContextManager, nullcontext
from typing import Any, Callable, Sequence

import canopen
import numpy as np
from canopen.profiles.p402 import Homing, State402
from canopen.sdo import SdoAbortedError, SdoCommunicationError, SdoVariable

from drivers.acquisition import PdoFrame, cycle_frame_sizes, master_layouts
from drivers.axis import AxisConfig, check_setpoints
from drivers.bus import BusConfig, check_bus_load, frame_bits, notifier_of
from drivers.cia import (CW_CHANGE_IMMEDIATELY, CW_ENABLE_OPERATION, CW_FAULT_RESET, CW_NEW_SETPOINT, ERROR_REGISTER,
                         HEARTBEAT_CONSUMER, MODE_HMM, MODE_PPM, NMT_ENTER_PRE_OPERATIONAL, NMT_OPERATIONAL, RPDO_COMM,
                         SW_BIT12, SW_BIT13, SW_FAULT, SW_TARGET_REACHED, is_node_id, state_of)
from drivers.cia import DISABLED, ENABLED, FAULT, FAULT_REACTION, FAULTED, NOT_READY, QUICK_STOP
from drivers.emcy import describe
from drivers.errors import BringUpError, ConfigError, DriveError, DriveFault, NodeError
from drivers.firmware import REVISION, USES, absent, firmware_of, load_object_dictionary, objects_used, refusal
from drivers.profiles import VENDOR_ID_MAXON, ObjectRef, make_object_dictionary
from drivers.recording import Recording
from drivers.recording_metadata import RecordingMetadata
from drivers.sdo import MasterNode
from drivers.stream import CyclicStream
from drivers.supervision import Supervisor, Watchdogs
from drivers.sync import PeriodicSync, SyncSource

logger = logging.getLogger(__name__)

WAIT_POLL = 0.02  # s between two statusword polls of the drives while they home or move


class EposDrive:
    """One EPOS2/EPOS4 node seen from the master.

    Args:
        network: the connected :class:`canopen.Network`.
        axis: the axis settings (node-ID, profile, scaling, limits, homing).
        supervisor: where EMCY and heartbeat faults of this node are reported.
        sdo_timeout: SDO response timeout in s.
        timebase: the clock and the pause of the state waits (quick stop, fault reaction, mode
            switch): the drive group's SYNC source.
        uses: what the run asks of the drive (:data:`drivers.firmware.USES`): its objects are
            checked at bring-up (:meth:`check_objects`), and in its dictionary file if it has one.
    """

    def __init__(self, network: canopen.Network, axis: AxisConfig, supervisor: Supervisor,
                 sdo_timeout: float = 0.5, timebase: SyncSource | None = None, uses: Sequence[str] = USES):
        self.axis = axis
        self.profile = axis.drive_profile
        self.label = axis.label
        self.supervisor = supervisor
        self.used = objects_used(self.profile, axis.current, uses)
        if axis.object_dictionary is None:
            od = make_object_dictionary(axis.profile, axis.node_id)
        else:
            try:
                od = load_object_dictionary(axis.object_dictionary, axis.profile, axis.node_id, axis.current, uses)
            except ValueError as exc:
                raise ConfigError(f"{axis.label}: {exc}") from None
        self.node = MasterNode(axis.node_id, od)
        self.node.sdo.RESPONSE_TIMEOUT = sdo_timeout
        network.add_node(self.node)
        self.node.emcy.add_callback(supervisor.emcy_callback(self.label, self.profile.name))
        self.frames: tuple[PdoFrame, ...] = ()
        self.timebase = timebase or PeriodicSync()

    # -- SDO access, errors naming node and object ---------------------------------------------
    def _var(self, ref: ObjectRef | tuple[int, int]) -> SdoVariable:
        index, subindex = (ref.index, ref.subindex) if isinstance(ref, ObjectRef) else ref
        entry = self.node.sdo[index]
        return entry if isinstance(entry, SdoVariable) else entry[subindex]

    def read(self, ref: ObjectRef | tuple[int, int]) -> Any:
        """Read an object by SDO (raw drive units)."""
        try:
            return self._var(ref).raw
        except (SdoAbortedError, SdoCommunicationError, KeyError) as exc:
            raise NodeError(self.label, f"reading {_name(ref)}: {exc}") from exc

    def write(self, ref: ObjectRef | tuple[int, int], value: Any) -> None:
        """Write an object by SDO (raw drive units)."""
        try:
            self._var(ref).raw = value
        except (SdoAbortedError, SdoCommunicationError, KeyError, ValueError) as exc:
            raise NodeError(self.label, f"writing {value!r} to {_name(ref)}: {exc}") from exc

    # -- bring-up ---------------------------------------------------------------------------------
    def wait_present(self, timeout: float) -> None:
        """Wait until the node answers (boot-up/heartbeat seen, or an SDO answer)."""
        deadline = time.monotonic() + timeout
        while True:
            if self.node.nmt.timestamp is not None:
                return
            self.node.nmt.send_command(NMT_ENTER_PRE_OPERATIONAL)  # a STOPPED node answers no SDO
            try:
                self._var((0x1000, 0)).raw
                return
            except SdoCommunicationError:
                pass
            except SdoAbortedError:
                return  # it answered
            if time.monotonic() > deadline:
                raise BringUpError(self.label, f"no boot-up, heartbeat or SDO answer within {timeout:g} s")

    def wait_operational(self, timeout: float) -> None:
        """Wait for a heartbeat that reports OPERATIONAL (after the start command).

        A heartbeat sent before the node processed the start command may still be in flight (a slow
        node, a loaded bus); supervision starts only once the node confirms its new state.
        """
        deadline = time.monotonic() + timeout
        while (remaining := deadline - time.monotonic()) > 0:
            try:
                if self.node.nmt.wait_for_heartbeat(remaining) == "OPERATIONAL":
                    return
            except canopen.nmt.NmtError:
                break
        raise BringUpError(self.label, f"no heartbeat reporting OPERATIONAL within {timeout:g} s of the "
                                       f"start command (last state {self.node.nmt.state})")

    def check_identity(self) -> None:
        """Compare 0x1018 (vendor, product) and 0x1008 (device name) with the configuration."""
        vendor = self.read((0x1018, 1))
        if vendor != VENDOR_ID_MAXON:
            raise BringUpError(self.label, f"vendor-ID 0x{vendor:08X} is not maxon (0x{VENDOR_ID_MAXON:08X})")
        product = self.read((0x1018, 2))
        expected = self.axis.product_code
        if expected is not None and product != expected:
            raise BringUpError(self.label, f"product code 0x{product:08X}, configured 0x{expected:08X}")
        name = self.read((0x1008, 0))
        if not str(name).startswith(self.profile.name):
            raise BringUpError(self.label, f"device name {name!r} is not an {self.profile.name} "
                               f"(profile {self.axis.profile!r} in the configuration)")

    def firmware(self) -> int | None:
        """The drive's firmware version (``0x1018:03``, upper 16 bits), None if it does not say."""
        try:
            return firmware_of(int.from_bytes(self.node.sdo.upload(*REVISION)[:4], "little"))
        except (SdoAbortedError, SdoCommunicationError):
            return None

    def check_objects(self) -> None:
        """Ask the drive for every object the run uses (:func:`drivers.firmware.absent`): a
        firmware without one of them is refused now, naming the node, the firmware and the
        objects, instead of failing after homing and the move to the start."""
        try:
            missing = absent(self.node.sdo, self.used)
        except SdoCommunicationError as exc:
            raise NodeError(self.label, f"asking for the objects the run uses: {exc}") from exc
        if missing:
            raise BringUpError(self.label, refusal(self.profile, self.firmware(), missing, self.used)
                               + "; nothing has moved")

    def write_limits(self) -> None:
        """Software position limits, current limit, max profile velocity, following-error window."""
        s, a, p = self.axis.scaling, self.axis, self.profile
        lo, hi = p.software_position_limit
        self.write(lo, s.counts_from_position(a.position_min))
        self.write(hi, s.counts_from_position(a.position_max))
        self.write(p.current_limit, s.ma_from_current(a.max_current))
        self.write(p.max_profile_velocity, s.rpm_from_velocity(a.max_velocity))
        self.write(p.following_error_window, s.counts_from_position(a.following_error_window))

    def configure_pdos(self, frames: Sequence[PdoFrame]) -> None:
        """Write the PDO mapping over SDO (PRE-OPERATIONAL); unused PDOs are disabled.

        canopen's maps subscribe to their frames when saved; the master decodes PDOs in
        :class:`~drivers.acquisition.CycleAssembler` instead, so they are unsubscribed again (at
        1 kHz, 18 frames a cycle through a ``Condition`` each for nothing).
        """
        by_key = {(f.direction, f.number): f for f in frames}
        for direction, maps in (("tpdo", self.node.tpdo), ("rpdo", self.node.rpdo)):
            count = self.profile.tpdo_count if direction == "tpdo" else self.profile.rpdo_count
            for number in range(1, count + 1):
                pdo = maps[number]
                frame = by_key.get((direction, number))
                pdo.clear()
                pdo.cob_id = (frame or PdoFrame(direction, number, (), 255)).cob_id(self.axis.node_id)
                pdo.enabled = frame is not None
                if frame is not None:
                    for _, ref in frame.entries:
                        pdo.add_variable(ref.index, ref.subindex)
                    pdo.trans_type = frame.trans_type
                try:
                    pdo.save()
                except (SdoAbortedError, SdoCommunicationError) as exc:
                    raise NodeError(self.label, f"configuring {direction.upper()}{number}: {exc}") from exc
                if pdo.enabled:
                    self.node.network.unsubscribe(pdo.cob_id, pdo.on_message)
        self.frames = tuple(frames)

    def bring_up(self, frames: Sequence[PdoFrame], heartbeat_ms: int, consumer_heartbeat: int,
                 timeout: float) -> None:
        """Presence, PRE-OPERATIONAL, identity, the objects the run uses, fault reset, limits,
        PDOs, heartbeats.

        Args:
            frames: the PDOs to configure.
            heartbeat_ms: the drive's producer heartbeat time (0x1017), ms.
            consumer_heartbeat: 0x1016:01, ``master node-ID << 16 | consumer time in ms``
                (0: the drive does not watch the master).
            timeout: s to wait for the node to show up.
        """
        self.wait_present(timeout)
        try:
            self.node.nmt.state = "PRE-OPERATIONAL"
            self.check_identity()
            self.check_objects()
            self.reset_fault()
            self.disable()
            self.write_limits()
            self.configure_pdos(frames)
            self.write((0x1017, 0), heartbeat_ms)
            self.write(HEARTBEAT_CONSUMER, consumer_heartbeat)
        except BringUpError:
            raise
        except NodeError as exc:
            raise BringUpError(self.label, f"bring-up failed: {str(exc).split(': ', 1)[-1]}") from exc

    # -- CiA 402 power state machine (SDO) ---------------------------------------------------------
    @property
    def statusword(self) -> int:
        return self.read(self.profile.statusword)

    @property
    def state(self) -> str:
        """CiA 402 state name, from the statusword read by SDO."""
        return state_of(self.statusword)

    def _controlword(self, value: int) -> None:
        self.write(self.profile.controlword, value)

    def fault_code(self) -> int | None:
        """The code of the drive's present error (``None``: none), over SDO: ``None`` while the
        error register ``0x1001`` is 0, else the profile's error code object (``0x603F``; on a
        drive without it the newest entry of the error history ``0x1003:01``, bits 0-15)."""
        if not self.read((ERROR_REGISTER, 0)):
            return None
        return self.read(self.profile.error_code) & 0xFFFF or None

    def _error(self) -> tuple[int | None, str]:
        """The present error's code and text (the code ``None`` when there is none or it is unreadable)."""
        try:
            code = self.fault_code()
        except NodeError as exc:
            return None, f"error code unreadable ({exc})"
        return code, (f"0x{code:04X} {describe(code, self.profile.name)}" if code else "no error code")

    def error_text(self) -> str:
        """The drive's present error as text (:meth:`fault_code`)."""
        return self._error()[1]

    def reset_fault(self, timeout: float = 1.0) -> None:
        """Clear a FAULT (rising edge of controlword bit 7)."""
        if self.state not in FAULTED:
            return
        logger.warning("%s: in FAULT at start (%s), resetting", self.label, self.error_text())
        self._controlword(State402.CW_DISABLE_VOLTAGE)
        self._controlword(CW_FAULT_RESET)
        deadline = self.timebase.now() + timeout
        while self.state in FAULTED:
            if self.timebase.now() > deadline:
                raise NodeError(self.label, f"still in FAULT after a fault reset ({self.error_text()})")
            self.timebase.tick()

    def set_state(self, target: str, timeout: float = 1.0) -> None:
        """Walk the CiA 402 state machine to ``target`` (one transition per controlword write)."""
        deadline = self.timebase.now() + timeout
        state = self.state
        while state != target:
            if state in FAULTED:
                code, text = self._error()
                raise DriveFault(self.label, code, f"in {state} while switching to {target} ({text})")
            step = target if (state, target) in State402.TRANSITIONTABLE else \
                State402.next_state_indirect(state)
            if (state, step) not in State402.TRANSITIONTABLE:
                raise NodeError(self.label, f"no transition from {state} towards {target}")
            self._controlword(State402.TRANSITIONTABLE[(state, step)])
            while True:
                state = self.state
                if state == step or state in FAULTED:
                    break
                if self.timebase.now() > deadline:
                    raise NodeError(self.label, f"stays in {state}, expected {step} on the way to "
                                    f"{target} (statusword 0x{self.statusword:04X})")
                self.timebase.tick()

    def enable(self) -> None:
        self.set_state(ENABLED)

    def _wait_while(self, busy, timeout: float) -> int:
        """Poll the statusword until ``busy(state, statusword)`` is false or ``timeout`` s passed;
        return the last statusword."""
        deadline = self.timebase.now() + timeout
        while True:
            sw = self.statusword
            if not busy(state_of(sw), sw) or self.timebase.now() > deadline:
                return sw
            self.timebase.tick()

    def disable(self, timeout: float = 1.0) -> None:
        """Disable voltage: SWITCH ON DISABLED (the motor is not powered). A drive in its fault
        reaction (braking on its own) is left to end it in FAULT, waiting up to ``timeout`` s."""
        sw = self._wait_while(lambda state, _: state == FAULT_REACTION, timeout)
        state = state_of(sw)
        if state == FAULT_REACTION:
            raise NodeError(self.label, f"still in FAULT REACTION ACTIVE after {timeout:g} s")
        if state not in (DISABLED, FAULT, NOT_READY):
            self.set_state(DISABLED)

    def quick_stop(self, timeout: float = 1.0) -> None:
        """Quick stop (decelerate with 0x6085) until halted (statusword bit 10 in QUICK STOP
        ACTIVE, at most ``timeout`` s), then disable."""
        if self.state == ENABLED:
            self._controlword(State402.CW_QUICK_STOP)
            self._wait_while(lambda state, sw: state == ENABLED or (
                state == QUICK_STOP and not sw & SW_TARGET_REACHED), timeout)
        self.disable(timeout)

    # -- modes -------------------------------------------------------------------------------------
    def set_mode(self, mode: int, timeout: float = 0.5) -> None:
        """Write 0x6060 and wait until 0x6061 shows it (works for the EPOS2's negative modes)."""
        if mode not in self.profile.supported_modes:
            raise NodeError(self.label, f"mode {mode} is not supported by an {self.profile.name} "
                            f"(supported: {dict(self.profile.supported_modes)})")
        self.write(self.profile.modes_of_operation, mode)
        deadline = self.timebase.now() + timeout
        while (shown := self.read(self.profile.modes_display)) != mode:
            if self.timebase.now() > deadline:
                raise NodeError(self.label, f"mode display shows {shown}, expected {mode}")
            self.timebase.tick()

    def prepare_cyclic(self, period: float) -> None:
        """Select the cyclic position mode (EPOS4: CSP with 0x60C2 = SYNC period; EPOS2: mode -1)."""
        ip = self.profile.interpolation_period
        if ip is not None:
            ms = period * 1e3
            if abs(ms - round(ms)) > 1e-9 or not 1 <= round(ms) <= 255:
                raise ConfigError(f"{self.label}: an {self.profile.name} needs a SYNC period of "
                                  f"1..255 whole ms (0x60C2), got {ms:g} ms")
            self.write(ip, int(round(ms)))
            self.write((ip.index, ip.subindex + 1), -3)
        self.set_mode(self.profile.cyclic_mode)

    def watches_setpoints(self) -> bool:
        """The drive has a deadline on its set-point RPDO (``0x1400:05`` > 0, ms): it faults with
        EMCY 0x8250 when the set-points stop in a cyclic mode. A drive without the object has none."""
        try:
            return bool(self._var((RPDO_COMM, 5)).raw)
        except (SdoAbortedError, KeyError):
            return False
        except SdoCommunicationError as exc:
            raise NodeError(self.label, f"reading 0x1400:05: {exc}") from exc

    def hold_position(self, counts: int) -> None:
        """Leave the cyclic mode standing still: profile position with its target at ``counts``
        (the last cyclic set-point). Done while the SYNC/RPDO stream still runs, so that a drive
        watching it (an RPDO deadline ``0x140x:05``) never sees it stop in the cyclic mode."""
        self.write(self.profile.target_position, counts)
        self.set_mode(MODE_PPM)

    # -- positions (SI) ----------------------------------------------------------------------------
    def position(self) -> float:
        """Actual position in rad or m (SDO)."""
        return float(self.axis.scaling.position_from_counts(self.read(self.profile.position_actual)))

    def start_homing(self) -> None:
        h = self.axis.homing
        if h is None:
            raise ConfigError(f"{self.label}: no homing configured")
        s, p = self.axis.scaling, self.profile
        self.set_mode(MODE_HMM)
        self.write(p.homing_method, h.method)
        self.write(p.home_position, s.counts_from_position(h.offset))
        self.write(p.homing_speeds[0], s.rpm_from_velocity(h.switch_speed))
        self.write(p.homing_speeds[1], s.rpm_from_velocity(h.zero_speed))
        self.write(p.homing_acceleration, s.rpm_from_velocity(h.acceleration))
        self.enable()
        self._controlword(CW_ENABLE_OPERATION | CW_NEW_SETPOINT)

    def homing_done(self) -> bool:
        """True when homing is attained; raises on a homing error."""
        sw = self.statusword
        if sw & SW_FAULT:
            code, text = self._error()
            raise DriveFault(self.label, code, f"fault during homing ({text})")
        for name, (mask, value) in Homing.STATES.items():
            if sw & mask == value:
                if name.startswith("ERROR") or name == "INTERRUPTED":
                    raise DriveFault(self.label, None, f"homing failed: {name.lower()}")
                return name in ("ATTAINED", "TARGET REACHED") and bool(sw & SW_TARGET_REACHED)
        return False

    def start_move(self, position: float, velocity: float, acceleration: float) -> None:
        """Start a profile-position move to ``position`` (rad or m)."""
        s, p = self.axis.scaling, self.profile
        self.set_mode(MODE_PPM)
        self.write(p.profile_velocity, max(1, s.rpm_from_velocity(velocity)))
        self.write(p.profile_acceleration, max(1, s.rpm_from_velocity(acceleration)))
        self.write(p.profile_deceleration, max(1, s.rpm_from_velocity(acceleration)))
        self.write(p.target_position, s.counts_from_position(position))
        self.enable()
        self._controlword(CW_ENABLE_OPERATION | CW_NEW_SETPOINT | CW_CHANGE_IMMEDIATELY)

    def move_done(self) -> bool:
        sw = self.statusword
        if sw & (SW_FAULT | SW_BIT13):
            code, text = self._error()
            raise DriveFault(self.label, code, f"fault during the move, statusword 0x{sw:04X} ({text})")
        if sw & SW_BIT12:
            self._controlword(CW_ENABLE_OPERATION)  # release the new-set-point handshake
            return False
        return bool(sw & SW_TARGET_REACHED)


def _name(ref) -> str:
    if isinstance(ref, ObjectRef):
        return str(ref)
    return f"0x{ref[0]:04X}:{ref[1]:02X}"


class DriveGroup:
    """The drives of the rig, brought up, commanded and streamed together.

    Heartbeats run both ways once :meth:`bring_up` started: every drive produces one every
    ``watchdogs.heartbeat_period`` and the master watches them (a node silent for
    ``watchdogs.drive_heartbeat`` stops the run with a :class:`~drivers.errors.HeartbeatTimeout`); the master
    produces its own (COB-ID ``0x700 + master_id``, state OPERATIONAL, from the SYNC source:
    ``network.send_periodic``, i.e. a timing process, the kernel BCM on SocketCAN, or a thread;
    in lockstep every so many SYNC cycles) and writes every drive's consumer heartbeat time
    0x1016:01 (``watchdogs.master_heartbeat``), so that a drive stops itself (heartbeat error,
    EMCY 0x8130, fault reaction) when the master is lost.

    Args:
        network: the network opened by :func:`drivers.bus.open_network`; its
            :class:`~drivers.bus.BusConfig` gives the bitrate of the bus-load check
            (``None``: no check).
        axes: the axes in sample order (theta1..3, zeta1..3 on the rig).
        watchdogs: the heartbeat period and every time limit that stops a run
            (:class:`drivers.supervision.Watchdogs`; default its defaults).
        uses: what the run asks of the drives (:data:`drivers.firmware.USES`, default all):
            each drive's firmware is checked against the objects they read or write at bring-up.
        master_id: node-ID under which the master produces its heartbeat (not a drive's).
        sdo_timeout: SDO response timeout (s).
        sync: the SYNC producer and the clock of every wait for the drives (homing, moves,
            stops): :class:`drivers.sync.PeriodicSync` (the default: real drives) or another
            :class:`~drivers.sync.SyncSource`.

    Use as a context manager: on exit every drive is quick-stopped/disabled and the heartbeats
    are stopped (:meth:`close`).
    """

    def __init__(self, network: canopen.Network, axes: Sequence[AxisConfig],
                 watchdogs: Watchdogs | None = None, master_id: int = 127,
                 sdo_timeout: float = 0.5, sync: SyncSource | None = None, uses: Sequence[str] = USES):
        bus_config = getattr(network, "config", None)
        if not isinstance(bus_config, BusConfig):
            raise ConfigError("DriveGroup: open the network with drivers.bus.open_network (its "
                              "BusConfig gives the bitrate of the bus-load check)")
        if not axes:
            raise ConfigError("a drive group needs at least one axis")
        seen: dict[int, str] = {}
        for axis in axes:
            if axis.node_id in seen:
                raise ConfigError(f"axis {axis.name!r}: node_id {axis.node_id} already used by "
                                  f"axis {seen[axis.node_id]!r}")
            seen[axis.node_id] = axis.name
        if not is_node_id(master_id) or master_id in seen:
            raise ConfigError(f"master_id must be a node-ID in 1..127 that no drive uses, got "
                              f"{master_id!r} (drives: {sorted(seen)})")
        self.sync: SyncSource = sync or PeriodicSync()
        self._sync_attached = False
        self.watchdogs = watchdogs or Watchdogs()
        self.network = network
        self.axes = list(axes)
        self.bitrate = bus_config.bitrate
        self.heartbeat_period = self.watchdogs.heartbeat_period
        self.master_id = master_id
        self._master_heartbeat = None  # the periodic task, while running
        self.supervisor = Supervisor(self.sync.watch_clock(), alive=getattr(network, "alive", None))
        self.drives = [EposDrive(network, a, self.supervisor, sdo_timeout, self.sync, uses) for a in self.axes]
        for drive in self.drives:
            self.supervisor.watch_heartbeat(drive.label, network, drive.axis.node_id, self.watchdogs.drive_timeout)
        self._bus_time_listened = False
        self.layouts = master_layouts(self.axes)

    def __enter__(self) -> "DriveGroup":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    # -- set-up ------------------------------------------------------------------------------------
    def bring_up(self, timeout: float = 5.0) -> None:
        """Start the master heartbeat, bring every drive up (each then watches the master), start
        them (NMT OPERATIONAL) and watch their heartbeats."""
        if not self._bus_time_listened:
            notifier_of(self.network).add_listener(self.supervisor.bus_time)
            self._bus_time_listened = True
        if self._master_heartbeat is None:
            self._master_heartbeat = self.sync.start_heartbeat(
                self.network, 0x700 + self.master_id, bytes([NMT_OPERATIONAL]), self.heartbeat_period)
        consumer = self.master_id << 16 | round(self.watchdogs.master_timeout * 1e3)
        for drive, layout in zip(self.drives, self.layouts):
            drive.bring_up(layout.frames, round(self.heartbeat_period * 1e3), consumer, timeout)
        for drive in self.drives:
            drive.node.nmt.state = "OPERATIONAL"
        for drive in self.drives:
            drive.wait_operational(timeout)
        if not self._sync_attached:
            tpdos = {f.cob_id(d.axis.node_id): d.label for d, layout in zip(self.drives, self.layouts)
                     for f in layout.frames if f.direction == "tpdo" and f.per_sync}
            self.sync.attach(self.network, tpdos, self._barrier)
            self._sync_attached = True
        self.supervisor.start_heartbeat_monitoring()
        self.supervisor.raise_if_fault()

    def _barrier(self) -> None:
        """An SDO round trip to the first drive that answers: a device answers frames in the order
        they came, so its response comes after its answers to every SYNC sent before."""
        for drive in self.drives:
            try:
                drive.read(drive.profile.statusword)
                return
            except NodeError:
                continue

    def close(self) -> None:
        """Quick-stop and disable every drive, switch off their watch of the master (0x1016:01 =
        0, so that they do not fault when the master heartbeat ends), stop the master heartbeat.
        Best effort: errors are logged, not raised."""
        self.stop_motion()
        self.supervisor.stop_heartbeat_monitoring()
        if self._bus_time_listened:
            notifier_of(self.network).remove_listener(self.supervisor.bus_time)
            self._bus_time_listened = False
        if self._sync_attached:
            self.sync.detach()
            self._sync_attached = False
        if self._master_heartbeat is None:
            return
        for d in self.drives:
            try:
                d.write(HEARTBEAT_CONSUMER, 0)
            except NodeError as exc:
                logger.error("%s: could not switch off its heartbeat consumer: %s", d.label, exc)
        self._master_heartbeat.stop()
        self._master_heartbeat = None

    def check_bus_load(self, period: float) -> float:
        """Worst-case bus load of a run at SYNC ``period`` (raises :class:`~drivers.errors.BusLoadError`)."""
        hb_bits = frame_bits(1) * (len(self.drives) + 1) / self.heartbeat_period
        return check_bus_load(cycle_frame_sizes(self.layouts), period, self.bitrate, hb_bits)

    # -- commanding (calling thread) -------------------------------------------------------------
    def _wait_all(self, done, timeout: float, what: str) -> None:
        pending = list(self.drives)
        deadline = self.sync.now() + timeout
        while pending:
            self.supervisor.raise_if_fault()
            pending = [d for d in pending if not done(d)]
            if pending and self.sync.now() > deadline:
                raise NodeError(pending[0].label, f"{what} not finished within {timeout:g} s")
            if pending:
                self.sync.wait(WAIT_POLL)

    def guarded(self, action):
        """``action()``; on any exception the motion is stopped (:meth:`stop_motion`) first."""
        try:
            return action()
        except BaseException:
            self.stop_motion()
            raise

    def positions(self) -> np.ndarray:
        """Actual positions (n_axes,) in rad|m, read by SDO."""
        return np.array([d.position() for d in self.drives])

    def enable(self) -> None:
        """Enable every drive; on any exception the motion is stopped first (:meth:`guarded`)."""
        def run() -> None:
            for d in self.drives:
                d.enable()
        self.guarded(run)

    def disable(self) -> None:
        for d in self.drives:
            d.disable()

    def home(self) -> None:
        """Home every axis that has a homing configuration, all at once."""
        drives = [d for d in self.drives if d.axis.homing is not None]

        def run():
            for d in drives:
                d.start_homing()
            timeout = max(d.axis.homing.timeout for d in drives) if drives else 0
            self._wait_all(lambda d: d not in drives or d.homing_done(), timeout, "homing")
            for d in drives:
                d._controlword(CW_ENABLE_OPERATION)
        self.guarded(run)

    def move_to(self, positions: Sequence[float], speed_fraction: float = 0.2,
                timeout: float | None = None) -> None:
        """Slow point-to-point move (profile position) of all axes to ``positions`` (rad|m).

        Each axis moves at ``speed_fraction`` of its ``max_velocity``, accelerating in 0.5 s.
        """
        targets = np.asarray(positions, dtype=float)
        check_setpoints(self.axes, targets[None, :], "move_to target")
        start = self.positions()
        speeds = [speed_fraction * a.max_velocity for a in self.axes]
        durations = [abs(p - s) / v + 1.0 for p, s, v in zip(targets, start, speeds)]

        def run():
            for d, p, v in zip(self.drives, targets, speeds):
                d.start_move(float(p), v, v / 0.5)
            self._wait_all(EposDrive.move_done, timeout or 2 * max(durations) + 2.0, "move")
        self.guarded(run)

    def stop_motion(self) -> None:
        """Quick stop and disable every drive, best effort (errors are logged, not raised)."""
        for d in self.drives:
            try:
                d.quick_stop()
            except DriveError as exc:
                logger.error("%s: could not quick-stop/disable: %s", d.label, exc)

    def with_error_code(self, error: BaseException) -> BaseException:
        """A statusword fault has no code: complete it with the drive's present error over SDO
        (:meth:`EposDrive.fault_code`: ``0x603F``, or ``0x1003:01`` on a drive without it). A
        fault an EMCY announced carries the EMCY's code already."""
        if not isinstance(error, DriveFault) or error.code is not None:
            return error
        drive = next((d for d in self.drives if d.label == error.node), None)
        if drive is None:
            return error
        try:
            code = drive.fault_code()
        except NodeError:
            return error
        if not code:
            return error
        return DriveFault(error.node, code, f"{describe(code, drive.profile.name)} ({error.text})")

    # -- streaming ---------------------------------------------------------------------------------
    def run_cyclic(self, targets: np.ndarray, period: float, output: str | os.PathLike | None = None,
                   raw_log: str | os.PathLike | None = None, metadata: RecordingMetadata | None = None,
                   queue_size: int = 100_000, sync_timeout: float | None = None,
                   quiet: Callable[[], AbstractContextManager] = nullcontext) -> Recording:
        """Stream ``targets`` (n_cycles, n_axes) in rad|m, one row per SYNC, and record.

        The drives must stand at ``targets[0]`` (within their following-error window), e.g. after
        :meth:`move_to`. Row k of the result holds the state the drives reported at SYNC k and
        ``target[k]``, the set-point in force from SYNC k on; ``t[k]`` is the measured bus time
        of SYNC k (not ``k * period``: the SYNC producer drifts, see :mod:`drivers.recording`).
        On a fault (EMCY, heartbeat, statusword fault/following-error bit, bus error) or any
        exception (Ctrl-C included) the SYNC stops, the drives are quick-stopped and disabled,
        the samples so far are saved and the error is raised (a :class:`DriveFault` carries
        ``recording``, the NPZ path). At a normal end, if any drive watches its set-points (an
        RPDO deadline, :meth:`EposDrive.watches_setpoints`), every drive is switched to profile
        position holding the last set-point before the SYNC stops (:meth:`EposDrive.hold_position`),
        as it would fault if the stream stopped in the cyclic mode; that SDO traffic waits behind
        any SYNCs a drive has not worked off yet, so a device slower than the SYNC rate must have
        no deadline. Otherwise the SYNC stops first and the drives hold the last set-point in the
        cyclic mode. Either way they stay enabled, e.g. for :meth:`move_to`. The metadata keeps
        ``gc_collections`` and ``gc_longest_pause`` (s) of the run and what the SYNC source
        reports (``sync_report``, :meth:`drivers.sync.SyncSource.report`), e.g. ``sync_slots_skipped``: the SYNC
        slots a thread-timed producer left out because the host woke it too late (``None`` under
        a bus timer); a skipped slot leaves a gap of whole periods in ``t``, the cycles stay
        consecutive.

        Args:
            targets: set-points, shape (n_cycles, n_axes), rad or m.
            period: SYNC period in s.
            output: NPZ file for the samples (``None``: memory only).
            raw_log: raw CAN log (``.log``/``.asc``/``.blf``), ``None`` for none.
            metadata: the caller's part of the recording's metadata (the trajectory, the
                config, free-form ``extra``); the stream fills the rest.
            queue_size: bounded buffer between the notifier and the recorder thread (rows).
            sync_timeout: s without a SYNC before the run is declared stalled
                (default: max(0.5 s, 50 periods)).
            quiet: a context entered while the SYNC runs, the caller's choice of how the host
                keeps out of the way (e.g. :func:`drivers.gc_freeze.frozen_gc`).
        """
        return CyclicStream(self, targets, period, output, raw_log, metadata, queue_size, sync_timeout,
                            quiet).run()
