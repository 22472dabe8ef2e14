"""The simulated rig: one emulated EPOS drive per actuator on one CANopen network, driving one plant.

One SYNC callback does the whole cycle for all drives: apply the synchronous RPDOs, plan each
drive's demand, sample the sensors (positions in counts, velocities in rpm, currents in mA),
send every SYNC-triggered TPDO, then integrate the plant over the period. A clock thread sends
the event-driven TPDOs, releases delayed frames and keeps the plant moving when no SYNC comes
(homing and profile moves before the cyclic phase).

Time. While the drives stream (every powered drive OPERATION ENABLED in its cyclic mode) the
simulated time is the SYNC's: each SYNC advances the plant by one period and nothing else does,
so a stalled master (a loaded host, a paused SYNC thread) stalls the robot with it instead of
letting it run on towards a stale set-point. Once one of them quick-stops or faults, the clock
thread moves the plant again (its ramp must end without SYNC). The period is ``sync_period``, else the
EPOS4's interpolation period ``0x60C2``, else the measured SYNC interval (neither generation has
the communication cycle period ``0x1006``). Outside the cyclic
mode the clock thread steps the plant after ``IDLE_AFTER`` without SYNC.

The drives' watches (heartbeat consumer ``0x1016:01``, RPDO deadline ``0x140x:05``: see
:meth:`~drivers.sim.drive.EmulatedDrive.check_heartbeat` and
:meth:`~drivers.sim.drive.EmulatedDrive.check_rpdo_timeout`) and their event timers run on the
rig's clock ``SimulatedRig.time``: it advances with the clock thread's ticks, each counting
at most ``MAX_TICK``, so a hiccup of the host that stops the rig's own thread too does not count
as a silence of the master; a master that stops sending while the rig runs does.

Lockstep (``lockstep=True``, the master's :class:`drivers.sim.lockstep.LockstepSync`): the plant moves
only on SYNC, one ``sync_period`` per SYNC, in every phase (homing, profile moves and stops too),
so the simulated time is the SYNC count times the period and a run is the same on any host. A
SYNC whose counter repeats the last one is a retry of the master: the TPDOs of that cycle are sent
again and nothing moves. A SYNC that finds set-points for only some of the streaming drives
(a frame lost on a lossy transport) is left unanswered until the master repeats it with them.
Each SYNC's answer ends with the answer frame of :mod:`drivers.sim.lockstep` (the frames sent,
or held), so that the master asks a cycle again as soon as one of its frames was lost.
The RPDO deadline watch is off (the set-points come with every SYNC by construction). The
heartbeats count SYNC periods both ways: each drive sends its heartbeat every producer period
of simulated time (besides canopen's wall-clock one, which bring-up waits for) and watches the
master's, which the master's :class:`~drivers.sim.lockstep.LockstepSync` sends by SYNC count, in
simulated time; the master watches the drives' in simulated time too. A busy host, which slows
the SYNC and the wall clock alike, never stops a simulated run.

Fault injection (for tests and demos): :meth:`SimulatedRig.silence`, :meth:`~SimulatedRig.emcy`,
:meth:`~SimulatedRig.sdo_abort`, :meth:`~SimulatedRig.frame_faults` and ``initial_states``;
:meth:`SimulatedRig.schedule` runs any of them at a given simulated time.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import threading
import time
from collections import deque
from contextlib import ExitStack

import canopen
import numpy as np

from drivers.axis import AxisConfig
from drivers.bus import NOTIFIER_CYCLE, BusConfig, FrameSending, open_bus
from drivers.cia import FAULT, FAULT_REACTION, SYNC_COB_ID
from drivers.gc_freeze import frozen_gc
from drivers.sim.lockstep import ANSWER_COB_ID, answer_frame
from drivers.sim.drive import EMCY_FOLLOWING_ERROR, EmulatedDrive
from drivers.sim.plant import DEFAULT_MAX_SUBSTEP, Plant, PlantJammed
from drivers.units import MA_PER_AMP, AxesScaling, AxisScaling
from ident_hw.model.interface import RobotModel

logger = logging.getLogger(__name__)

IDLE_AFTER = 0.05      # s without SYNC after which the clock thread moves the plant
IDLE_STEP = 0.005      # s, plant step of the clock thread
CLOCK_TICK = 0.001     # s
MAX_TICK = 0.01        # s, most the rig's clock advances per tick of the clock thread
MAX_PERIOD = 0.02      # s, longest plant step taken from a measured SYNC interval
STEP_LOG_LENGTH = 100_000  # SYNC cycles whose duration is kept in SimulatedRig.step_seconds


class _RigNetwork(FrameSending):
    """A ``canopen.Network`` whose PDO frames can be dropped or delayed (fault injection).

    A share ``delayed_share`` of the frames (drawn at random; 1: all) is held for ``delay`` plus
    a uniform random share of ``jitter`` (s); no frame overtakes an earlier frame of its COB-ID: a drive's frames leave in order, so a long
    delay holds the following ones back and they go out in a burst.
    """

    NOTIFIER_CYCLE = NOTIFIER_CYCLE

    def __init__(self, bus=None):
        super().__init__(bus)
        self.drop_probability = 0.0
        self.delay = 0.0
        self.jitter = 0.0
        self.delayed_share = 1.0
        self.faulty_nodes = None   # None = all
        self.dropped = 0
        self._rng = np.random.default_rng()
        self._delayed: list = []
        self._release_after: dict[int, float] = {}  # COB-ID -> release time of its last held frame
        self._seq = 0

    def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None:
        pdo = 0x180 <= can_id < 0x580
        if ((self.drop_probability or self.delay or self.jitter) and pdo
                and (self.faulty_nodes is None or can_id & 0x7F in self.faulty_nodes)):
            if self.drop_probability and self._rng.random() < self.drop_probability:
                self.dropped += 1
                return
            if self.delay or self.jitter:
                release = time.monotonic()
                if self.delayed_share >= 1.0 or self._rng.random() < self.delayed_share:
                    release += self.delay + self.jitter * self._rng.random()
                release = max(release, self._release_after.get(can_id, 0.0))
                self._release_after[can_id] = release
                self._seq += 1
                heapq.heappush(self._delayed, (release, self._seq, can_id, bytes(data)))
                return
        super().send_message(can_id, data, remote)

    def release_delayed(self, now: float) -> None:
        while self._delayed and self._delayed[0][0] <= now:
            _, _, can_id, data = heapq.heappop(self._delayed)
            super().send_message(can_id, data)


class SimulatedRig:
    """Emulated EPOS drives (one per actuator) and the simulated robot behind them.

    Args:
        nodes: one ``(node_id, profile, AxisScaling)`` (``profile``: a name or a
            :class:`~drivers.profiles.DriveProfile`) or :class:`drivers.axis.AxisConfig`
            per actuator, in the plant's actuator order (the 3PRRR: ``theta1..3, zeta1..3``).
        plant: the :class:`Plant` (robot, true parameters, position loops).
        bus: an open python-can bus to use (left open on :meth:`stop`); otherwise one is opened
            from ``bus_kwargs`` (e.g. ``interface="virtual", channel="rig", ignore_config=True``).
        sync_period: plant step per SYNC in s. Default: the interpolation period ``0x60C2`` of
            a streaming EPOS4, else the measured SYNC interval.
        current_noise_ma: standard deviation of the Gaussian current noise, mA.
        seed: seed of the current noise and of the frame-loss draws.
        initial_states: ``{node_id: "FAULT" | "STOPPED"}``: drives in the wrong state at start.
        lockstep: the plant moves only on SYNC (see the module docstring); needs ``sync_period``.
        brakes: every axis has a holding brake that holds it where it stands while its drive's
            power stage is off (a robot whose arms carry their weight, such as a Delta, does not
            fall when the run ends and the drives are disabled).
        encoder_edges: (n,) where each axis's encoder counts, in counts: an axis reads
            ``rint(position * counts_per_unit + encoder_edges[j])`` (each in [-0.5, 0.5]; default 0,
            count edges halfway between whole multiples of a count).
        dictionaries: ``{node_id: EDS or DCF file}``: drives whose object dictionary is read from
            a file (e.g. maxon's EDS of an older firmware) instead of their profile's.
    """

    def __init__(self, nodes, plant: Plant, *, bus=None, sync_period=None, current_noise_ma: float = 0.0,
                 seed=None, initial_states=None, lockstep: bool = False, brakes: bool = False,
                 encoder_edges=None, dictionaries=None, **bus_kwargs):
        nodes = [(n.node_id, n.profile, n.scaling) if isinstance(n, AxisConfig) else tuple(n) for n in nodes]
        names = plant.robot.actuator_names
        if len(nodes) != len(names):
            raise ValueError(f"the rig needs one drive per actuator ({', '.join(names)}), got {len(nodes)}")
        ids = [n[0] for n in nodes]
        if len(set(ids)) != len(ids):
            raise ValueError(f"node-IDs must be distinct, got {ids}")
        for node_id, _, scaling in nodes:
            if not isinstance(scaling, AxisScaling):
                raise ValueError(f"node {node_id}: the third item must be an AxisScaling, got {scaling!r}")
        self.initial_states = dict(initial_states or {})
        for node_id, state in self.initial_states.items():
            if node_id not in ids or state not in (FAULT, "STOPPED"):
                raise ValueError(f"initial_states: {node_id}: {state!r} (node-IDs {ids}; FAULT or STOPPED)")
        if sync_period is not None and not sync_period > 0:
            raise ValueError(f"sync_period must be positive, got {sync_period}")
        if lockstep and sync_period is None:
            raise ValueError("a lockstep rig needs its sync_period")
        self.lockstep = lockstep
        self.brakes = brakes
        self._braked_at: dict[int, float] = {}   # axis -> position its brake holds (rad, m)
        self.plant = plant
        self.sync_period = sync_period
        self.current_noise_ma = float(current_noise_ma)
        self._rng = np.random.default_rng(seed)
        self._own_bus = bus is None
        self._bus_kwargs = bus_kwargs
        self.network = _RigNetwork(bus)
        self.network._rng = np.random.default_rng(None if seed is None else seed + 1)
        self._lock = threading.RLock()
        self.time = 0.0    # s, the rig's clock (see the module docstring)
        self.sync_time = 0.0            # s, simulated time of the SYNC cycles finished
        heartbeat_clock = (lambda: self.sync_time) if lockstep else None
        files = dict(dictionaries or {})
        unknown = sorted(set(files) - set(ids))
        if unknown:
            raise ValueError(f"dictionaries: no drive with node-ID {unknown} (node-IDs {ids})")
        self.drives = [EmulatedDrive(node_id, profile, scaling, self.network, self._lock, lambda: self.time,
                                     heartbeat_clock,
                                     canopen.import_od(str(files[node_id]), node_id) if node_id in files else None)
                       for node_id, profile, scaling in nodes]
        self._by_id = {d.id: d for d in self.drives}
        self._units = AxesScaling([n[2] for n in nodes])
        edges = np.zeros(len(nodes)) if encoder_edges is None else np.asarray(encoder_edges, dtype=float)
        if edges.shape != (len(nodes),) or np.any(np.abs(edges) > 0.5):
            raise ValueError(f"encoder_edges: one value in [-0.5, 0.5] counts per drive, got {encoder_edges}")
        self._edge_shift = edges / np.array([n[2].counts_per_unit for n in nodes])   # SI: rad, m
        # the scalings as Python floats, for the per-drive arithmetic of every cycle
        self._counts_per_unit = self._units.counts_per_unit.tolist()
        self._rpm_per_unit = self._units.rpm_per_unit_velocity.tolist()
        self._force_per_amp = self._units.force_per_amp.tolist()
        self.sync_count = 0             # SYNC frames received
        self.syncs_done = 0             # SYNC cycles finished (the TPDOs sent, the plant stepped)
        self.sync_retries = 0           # repeated SYNCs answered (lockstep)
        self.syncs_held = 0             # SYNCs left unanswered for missing set-points (lockstep)
        self._last_counter: int | None = None       # SYNC counter of the last cycle (lockstep)
        self._scheduled: list = []      # heap of (due sync_time, sequence, action)
        self._schedule_seq = itertools.count()
        self.jammed: str | None = None        # why the plant stopped moving, if it did
        self.step_seconds: deque[float] = deque(maxlen=STEP_LOG_LENGTH)   # s, the last SYNC cycles' durations
        self._last_sync: float | None = None          # rig time of the last SYNC
        self._last_sync_stamp: float | None = None    # bus timestamp of the last SYNC
        self._last_step = 0.0           # rig time of the last plant step
        self._last_tick: float | None = None          # monotonic time of the last clock tick
        self._stop = threading.Event()
        self._clock_thread: threading.Thread | None = None
        self._serving = ExitStack()

    @classmethod
    def build(cls, robot: RobotModel, truth, axes, *, bandwidth_hz: float = 20.0, damping: float = 1.0,
              max_substep: float = DEFAULT_MAX_SUBSTEP, Theta0=None, **rig_kwargs) -> SimulatedRig:
        """A rig from plain settings (what a config file holds); not started.

        Args:
            robot: the robot's model (:class:`~ident_hw.model.interface.RobotModel`).
            truth: the plant's TRUE parameters, as the model takes them.
            axes: one drive per actuator, as for ``nodes`` of the constructor.
            bandwidth_hz, damping, max_substep, Theta0: the position loops, integration step (s) and
                initial pose of the :class:`Plant`.
            rig_kwargs: ``sync_period``, ``lockstep``, ``current_noise_ma``, ``seed``, ``initial_states``, ``bus``
                or the python-can bus settings (``interface``, ``channel``, ...).
        """
        plant = Plant(robot, truth, Theta0,
                      bandwidth_hz=bandwidth_hz, damping=damping, max_substep=max_substep)
        return cls(axes, plant, **rig_kwargs)

    # -- life cycle ----------------------------------------------------------------------------------
    def start(self) -> SimulatedRig:
        """Connect, boot every drive (boot-up frames) and start serving.

        While it serves, the garbage collector ignores the objects that existed at the start
        (:func:`drivers.gc_freeze.frozen_gc`): no collection of the whole heap stalls the SYNC
        handling; the per-period logs are bounded numpy buffers, not Python objects.
        """
        if self._own_bus:   # opened as the master's are (drivers.bus.open_bus), without own frames
            settings = dict(self._bus_kwargs, receive_own_messages=False)
            self.network.bus = open_bus(BusConfig.from_mapping(settings, "simulated rig bus"))
        self.network.connect()
        self._serving.enter_context(frozen_gc())
        counts = self._units.counts_from_position(self.plant.Theta + self._edge_shift)
        with self._lock:
            for drive, c in zip(self.drives, counts):
                drive.offset = int(c)   # incremental encoders read 0 at power-up
                drive.boot()
                state = self.initial_states.get(drive.id)
                if state == "STOPPED":
                    drive.node.nmt.send_command(0x02)
                elif state == FAULT:
                    drive.emcy(0x1000)
            self.network.subscribe(SYNC_COB_ID, self._on_sync)
        self._stop.clear()
        self._last_tick = time.monotonic()
        clock = self._clock_thread = threading.Thread(target=self._clock, name="sim-rig-clock", daemon=True)
        clock.start()
        return self

    def stop(self) -> None:
        """Stop serving: heartbeats, clock thread, notifier (and the bus if the rig opened it)."""
        self._stop.set()
        if self._clock_thread is not None:
            self._clock_thread.join()
            self._clock_thread = None
        for drive in self.drives:
            drive.node.nmt.stop_heartbeat()
        if self._own_bus:
            self.network.disconnect()
        elif self.network.notifier is not None:
            self.network.notifier.stop(self.network.NOTIFIER_SHUTDOWN_TIMEOUT)
        self._serving.close()

    def __enter__(self) -> SimulatedRig:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    # -- the cycle ------------------------------------------------------------------------------------
    def _period(self, timestamp: float) -> float:
        """The plant step of a SYNC, s. In lockstep (``sync_period``) the period: the simulated
        time is the SYNC count times the period. Else, as real drives that move on their own
        clock between two SYNCs, the time since the last SYNC (its bus time stamps; at most
        ``IDLE_AFTER``, after which the clock thread moves the plant), the configured SYNC
        period for the first one."""
        last, self._last_sync_stamp = self._last_sync_stamp, timestamp
        if self.sync_period is not None:
            return self.sync_period
        if last is not None and timestamp > last:
            return min(timestamp - last, IDLE_AFTER)
        return self._nominal_period() or 0.0

    def _nominal_period(self) -> float | None:
        """The SYNC period the drives are configured for (``sync_period`` or the EPOS4's
        interpolation period ``0x60C2``), s: what their set-point interpolation assumes, however
        late a SYNC comes (a longer interval extrapolates the interpolated demand)."""
        if self.sync_period is not None:
            return self.sync_period
        for drive in self.drives:
            if drive.interpolation_period:
                return drive.interpolation_period
        return None

    def _on_sync(self, can_id, data, timestamp) -> None:
        started = time.perf_counter()
        with self._lock:
            if self.lockstep:
                counter = data[0] if data else None
                if counter is not None and counter == self._last_counter:
                    self.sync_retries += 1
                    for drive in self.drives:
                        drive.resend_sync_tpdos()
                    self._answer(counter)
                    return
                # a SYNC overtaking some set-points of its cycle waits for its repetition; a drive
                # that stopped streaming (halted, faulted, silent) is not waited for
                awaiting = [d.awaits_setpoint() for d in self.drives if d.streaming and not d.silent]
                if any(awaiting) and not all(awaiting):
                    self.syncs_held += 1
                    if counter is not None:     # the answer names its SYNC's counter (lockstep's SYNCs carry one)
                        self._answer(counter, held=True)
                    return
                self._last_counter = counter
            self.sync_count += 1
            self._last_sync = self.time
            period = self._period(timestamp)
            while self._scheduled and self._scheduled[0][0] <= self.sync_time + 1e-9:
                heapq.heappop(self._scheduled)[2]()
            self._cycle(period, self.sync_count)
            self.syncs_done += 1
            self.sync_time += period
            if self.lockstep:
                for drive in self.drives:            # the heartbeats in simulated time, both ways
                    drive.heartbeat_by_sync(self.sync_time)
                    drive.check_heartbeat(self.sync_time)
                self._answer(data[0] if data else 0)
        self.step_seconds.append(time.perf_counter() - started)

    def _answer(self, counter: int, held: bool = False) -> None:
        """Close the answer to the SYNC with ``counter`` (lockstep): the answer frame of
        :mod:`drivers.sim.lockstep`, counting the SYNC-triggered TPDO frames the drives sent."""
        frames = 0 if held else sum(drive.sync_frames_sent for drive in self.drives)
        self.network.send_message(ANSWER_COB_ID, answer_frame(counter, frames, held))

    def schedule(self, after: float, action) -> None:
        """Run ``action()`` (under the rig's lock) at the first SYNC cycle ``after`` s of simulated
        time from now (e.g. an EMCY or a payload change at a given time of a trajectory)."""
        with self._lock:
            heapq.heappush(self._scheduled, (self.sync_time + after, next(self._schedule_seq), action))

    def cancel_scheduled(self) -> None:
        """Forget every action :meth:`schedule` has not run yet."""
        with self._lock:
            self._scheduled.clear()

    def _cycle(self, period: float, sync_count=None) -> None:
        """One period: RPDOs, demands, sensor sampling, TPDOs (if ``sync_count``), plant step."""
        nominal = (self._nominal_period() or period) if sync_count is not None else period
        # a few drives: each one's conversions in Python floats (the same IEEE operations, in the
        # same order, as AxesScaling's on arrays; round() rounds half to even as np.rint), the
        # arrays built once for the plant
        counts_per_unit, force_per_amp = self._counts_per_unit, self._force_per_amp
        rows, offsets, on, limits = [], [], [], []
        for drive, k, f in zip(self.drives, counts_per_unit, force_per_amp):
            drive.apply_pending_rpdos()      # each drive's set-points, demand and state: its own alone
            c = drive.plan(nominal)
            offset = drive.offset
            if offset is None:
                raise RuntimeError(f"node {drive.id}: its encoder has no offset yet (start() sets it)")
            rows.append(((c.c0 + offset) / k, c.c1 / k, c.c2 / k, c.c3 / k))
            offsets.append(offset)
            on.append(drive.powered)
            limits.append(drive.store[drive.profile.current_limit] / MA_PER_AMP * f)
        demand = np.array(rows).T            # (4, n) rad|m: q_d(t) = sum_i demand[i] t^i over the period
        powered = np.array(on)
        limit = np.array(limits)             # the current limits as forces, N·m|N
        plant = self.plant
        enabled = powered
        if self.brakes:
            demand, enabled, limit = self._brake(demand, powered, limit)
        force = plant.control(demand[0], demand[1], enabled, limit).tolist()
        milliamps = [(F if p else 0.0) / f * MA_PER_AMP for F, f, p in zip(force, force_per_amp, on)]   # before noise, rounding
        if self.current_noise_ma:
            noise = self._rng.normal(0.0, self.current_noise_ma, len(self.drives)).tolist()
            milliamps = [ma + e for ma, e in zip(milliamps, noise)]
        for drive, x, e, k, offset, v, r, ma in zip(self.drives, plant.Theta.tolist(), self._edge_shift.tolist(),
                                                    counts_per_unit, offsets, plant.Thetad.tolist(),
                                                    self._rpm_per_unit, milliamps):
            drive.update(round((x + e) * k) - offset, round(v * r), ma, period)   # each drive rounds to whole mA
        if sync_count is not None:
            for drive in self.drives:
                drive.send_sync_tpdos(sync_count)
        if period > 0:
            try:
                plant.step(period, demand, enabled, limit, remember=sync_count is not None)
            except PlantJammed as exc:   # what a real drive sees: the axis does not follow
                if self.jammed is None:
                    logger.error("%s", exc)
                self.jammed = str(exc)
                for drive in self.drives:
                    if drive.powered:
                        drive.emcy(EMCY_FOLLOWING_ERROR)
        self._last_step = self.time

    def _brake(self, demand, powered, limit):
        """The holding brakes: an axis whose power stage is off is held where it stood when it went
        off, as by a stiff position loop with no force limit; its drive measures no current."""
        demand, enabled, limit = demand.copy(), powered.copy(), limit.copy()
        for j, on in enumerate(powered):
            if on:
                self._braked_at.pop(j, None)
                continue
            demand[:, j] = 0.0
            demand[0, j] = self._braked_at.setdefault(j, float(self.plant.Theta[j]))
            enabled[j], limit[j] = True, np.inf
        return demand, enabled, limit

    @property
    def sync_driven(self) -> bool:
        """Simulated time advances only with SYNC: every powered drive streams (one at least)."""
        powered = [drive for drive in self.drives if drive.powered]
        return bool(powered) and all(drive.streaming for drive in powered)

    def _clock(self) -> None:
        while not self._stop.wait(CLOCK_TICK):
            try:
                with self._lock:
                    now = time.monotonic()
                    last = now if self._last_tick is None else self._last_tick     # set before the thread starts
                    self.time += min(now - last, MAX_TICK)
                    self._last_tick = now
                    self.network.release_delayed(now)
                    for drive in self.drives:
                        if not self.lockstep:            # in lockstep on SYNC, in simulated time
                            drive.check_heartbeat(self.time)
                            drive.check_rpdo_timeout(self.time)
                        drive.send_event_tpdos(self.time)
                    if self.lockstep or self.sync_driven:
                        continue
                    idle = self._last_sync is None or self.time - self._last_sync > IDLE_AFTER
                    if idle and self.time - self._last_step >= IDLE_STEP:
                        self._cycle(min(self.time - self._last_step, MAX_PERIOD))
            except Exception:  # keep serving; a broken bus shows up in the notifier too
                logger.exception("simulated rig clock")

    # -- inspection and payload -------------------------------------------------------------------------
    def drive(self, node_id: int) -> EmulatedDrive:
        """The emulated drive with this node-ID."""
        try:
            return self._by_id[node_id]
        except KeyError:
            raise KeyError(f"no emulated drive with node-ID {node_id} (have {sorted(self._by_id)})") from None

    def set_payload(self, mass: float, inertia: float = 0.0) -> None:
        """Add a payload to the end-effector from now on (see :meth:`Plant.set_payload`)."""
        with self._lock:
            self.plant.set_payload(mass, inertia)

    def set_external_force(self, forces) -> None:
        """Disturbance forces (n,) on the actuated joints (N·m, N), e.g. a hand pushing a carriage."""
        with self._lock:
            self.plant.external_force = np.array(forces, dtype=float).reshape(self.plant.n)

    # -- fault injection ------------------------------------------------------------------------------
    def silence(self, node_id: int, silent: bool = True) -> None:
        """The drive stops answering: no heartbeat, PDO, SDO, EMCY or NMT (``silent=False`` revives it)."""
        drive = self.drive(node_id)
        with self._lock:
            drive.silent = silent
            if silent:
                drive.node.nmt.stop_heartbeat()
            else:
                drive.node.nmt.start_heartbeat(drive.get(0x1017))

    def emcy(self, node_id: int, code: int = 0x2310) -> None:
        """The drive signals error ``code`` (EMCY frame) and goes to FAULT (e.g. 0x2310 overcurrent)."""
        drive = self.drive(node_id)
        with self._lock:
            drive.emcy(code)

    def sdo_abort(self, node_id: int, index: int, subindex: int = 0, code=0x08000020) -> None:
        """SDO requests on ``index:subindex`` abort with ``code`` (``None`` removes the fault)."""
        drive = self.drive(node_id)
        with self._lock:
            if code is None:
                drive.sdo_aborts.pop((index, subindex), None)
            else:
                drive.sdo_aborts[(index, subindex)] = code

    def frame_faults(self, drop_probability: float = 0.0, delay: float = 0.0, node_ids=None,
                     jitter: float = 0.0, delayed_share: float = 1.0) -> None:
        """Drop (probability) or delay (``delay`` s plus up to ``jitter`` s, uniform; a share
        ``delayed_share`` of the frames) the PDO frames of ``node_ids`` (default: all drives);
        see ``_RigNetwork``."""
        if not (0.0 <= drop_probability <= 1.0 and 0.0 <= delayed_share <= 1.0) or delay < 0 or jitter < 0:
            raise ValueError(f"drop_probability and delayed_share in [0, 1], delay >= 0 and jitter >= 0, "
                             f"got {drop_probability}, {delayed_share}, {delay}, {jitter}")
        with self._lock:
            self.network.delayed_share = delayed_share
            self.network.drop_probability = drop_probability
            self.network.delay = delay
            self.network.jitter = jitter
            self.network.faulty_nodes = None if node_ids is None else set(node_ids)

    def faulted(self) -> list[int]:
        """Node-IDs of the drives in FAULT (or in their fault reaction, on the way to it)."""
        return [d.id for d in self.drives if d.state in (FAULT_REACTION, FAULT)]
