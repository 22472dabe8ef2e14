"""The configured bus, opened: the master's canopen network and, for an in-process simulated
config, the simulated rig serving the same python-can bus.

    with host.pinned(), open_session(config) as session:
        group = session.drive_group()        # drivers.epos.DriveGroup of the six actuators
        ...

:class:`HostSettings` are how the process hosts a session (the garbage collector while a SYNC
runs, the CPUs of its threads): the command line chooses them, the library only applies them.
"""

from __future__ import annotations

from contextlib import AbstractContextManager, contextmanager, nullcontext
from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterator, Sequence

import can
import canopen

from drivers.affinity import one_cpu
from drivers.axis import AxisConfig
from drivers.bus import has_own_timer, open_network
from drivers.epos import DriveGroup
from drivers.errors import BusOpenError
from drivers.firmware import USES
from drivers.gc_freeze import frozen_gc
from drivers.sim.lockstep import LockstepSync
from drivers.supervision import Watchdogs
from drivers.sync import PeriodicSync, SyncSource
from drivers.timing import TimingConfig
from drivers.units import MA_PER_AMP
from ident_hw.config import BusConfig, Config
from ident_hw.config.robots import model_of, true_parameters
from ident_hw.config.to_drivers import axis_scaling, bus_settings, encoder_edge_counts, timing_settings, watchdogs
from ident_hw.experiment.plan import drive_axes, sync_period

if TYPE_CHECKING:     # the rig (its compiled plant) is imported where one is built
    from drivers.sim import SimulatedRig


def simulated_rig(config: Config) -> SimulatedRig:
    """The simulated rig of ``config`` (truth, noise, position loops) on the config's bus (not started).

    The plant starts at the home pose (``x = y = alpha = 0``, carriages at 0), where the
    actuators' homing offsets put it; currents get ``sim.current_noise`` (A) of Gaussian noise.
    In lockstep (``bus.sync``, the default here) each SYNC advances the plant by exactly one
    SYNC period and nothing else moves it: the same run on any host. On a periodic SYNC the
    plant moves by the time between two SYNCs, as real drives on their own clock do.
    """
    if config.sim is None:
        raise ValueError(f"{config.source}: sim: missing section (the simulated rig's truth and noise)")
    if config.bus is None:
        raise ValueError(f"{config.source}: bus: missing section")
    from drivers.sim import SimulatedRig
    sim, robot = config.sim, config.robot
    lockstep = config.sync_mode == "lockstep"
    axes = [(a.node_id, a.profile, axis_scaling(a)) for a in robot.actuators]
    model = model_of(config.robot)
    return SimulatedRig.build(model, true_parameters(config, model), axes,
                              bandwidth_hz=sim.bandwidth, damping=sim.damping,
                              **({"max_substep": sim.max_substep} if sim.max_substep else {}),
                              sync_period=sync_period(config.bus) if lockstep else None,
                              current_noise_ma=sim.current_noise * MA_PER_AMP, seed=sim.seed, lockstep=lockstep, brakes=sim.brakes,
                              encoder_edges=encoder_edge_counts(sim, len(axes)),
                              interface=config.bus.interface, channel=config.bus.channel, ignore_config=True)


@dataclass(frozen=True)
class HostSettings:
    """How this process hosts a streaming session; the command line chooses
    (:meth:`for_command`), the library applies them. Neither changes a recorded sample.

    Attributes:
        freeze_gc: while a SYNC runs, the garbage collector walks only the objects created
            since it started (:func:`drivers.gc_freeze.frozen_gc`): no full collection stalls the
            SYNC and set-point threads.
        one_cpu: every thread of the session (master and in-process rig) on one CPU
            (:func:`drivers.affinity.one_cpu`): a lockstep cycle's thread hand-offs are cheaper there.
    """

    freeze_gc: bool = False
    one_cpu: bool = False

    @classmethod
    def for_command(cls, config: Config) -> HostSettings:
        """What ``ident-hw`` uses: the GC frozen while a SYNC runs; one CPU where the rig runs in
        this process in lockstep (with a periodic SYNC the rig and the master keep both CPUs)."""
        in_process = config.sim is not None and config.sim.in_process
        return cls(freeze_gc=True, one_cpu=in_process and config.sync_mode == "lockstep")

    def pinned(self) -> AbstractContextManager:
        """The section in which the session's threads are started (one CPU, or as they are)."""
        return one_cpu() if self.one_cpu else nullcontext()

    def quiet(self) -> AbstractContextManager:
        """The section in which a SYNC runs (the GC frozen, or as it is)."""
        return frozen_gc() if self.freeze_gc else nullcontext()


@dataclass(frozen=True)
class DriveSettings:
    """How the session's drive group is made (:meth:`Session.drive_group`): each actuator's axis
    settings (:func:`ident_hw.experiment.plan.drive_axes`), the bus's heartbeat period and
    watchdogs (``bus.watchdogs``) and SDO timeout (s), and the SYNC producer: the simulated rig's
    lockstep at ``lockstep_period`` (s; None: the periodic SYNC of real drives) waiting at most
    ``lockstep_timeout`` (s)."""

    axes: tuple[AxisConfig, ...]
    watchdogs: Watchdogs
    sdo_timeout: float
    lockstep_period: float | None
    lockstep_timeout: float

    @classmethod
    def of(cls, config: Config) -> DriveSettings:
        """The settings of a config with a bus."""
        bus = config.bus
        if bus is None:
            raise ValueError(f"{config.source}: bus: missing section (needed to open the bus)")
        lockstep = config.sync_mode == "lockstep"
        return cls(axes=tuple(drive_axes(config.robot.actuators, config.base_dir, config.current)),
                   watchdogs=watchdogs(bus), sdo_timeout=bus.sdo_timeout,
                   lockstep_period=sync_period(bus) if lockstep else None, lockstep_timeout=bus.lockstep_timeout)

    def sync_source(self) -> SyncSource:
        """The SYNC producer of the runs (``bus.sync``): the simulated rig's lockstep, or the
        periodic SYNC of real drives."""
        if self.lockstep_period is not None:
            return LockstepSync(self.lockstep_period, timeout=self.lockstep_timeout)
        return PeriodicSync()


def timing_of(bus: BusConfig, sync_mode: str) -> TimingConfig | None:
    """Where the timers of a bus run (``bus.timing``) with its SYNC producer ``sync_mode``
    (:attr:`ident_hw.config.file.Config.sync_mode`): a periodic SYNC may get a timing process;
    lockstep is its own timing (the SYNC paced by the rig's answers), so it gets none."""
    if sync_mode == "lockstep":
        return None
    return timing_settings(bus)


@dataclass(frozen=True)
class Session:
    """An open bus: ``network`` (the master), ``rig`` (the in-process simulated rig, or None), and
    how its drive group is made (``drives``)."""

    network: canopen.Network
    rig: SimulatedRig | None
    drives: DriveSettings

    def drive_group(self, uses: Sequence[str] = USES) -> DriveGroup:
        """The robot's drives, in actuator order, with the bus settings of the config; ``uses``:
        what the command asks of them (:data:`drivers.firmware.USES`), whose objects each drive's
        firmware must have."""
        d = self.drives
        return DriveGroup(self.network, list(d.axes), watchdogs=d.watchdogs, sdo_timeout=d.sdo_timeout,
                          sync=d.sync_source(), uses=uses)


@contextmanager
def open_session(config: Config) -> Iterator[Session]:
    """Open the config's bus (and start the in-process rig first when ``sim.in_process``)."""
    if config.bus is None:
        raise ValueError(f"{config.source}: bus: missing section (needed to open the bus)")
    drives = DriveSettings.of(config)
    in_process = config.sim is not None and config.sim.in_process
    rig = None
    if in_process:
        if not config.simulated:
            raise ValueError(f"{config.source}: sim.in_process: the simulated rig only serves a virtual "
                             f"or vcan bus, not {config.bus.interface}:{config.bus.channel}")
        rig = simulated_rig(config)
        try:
            rig.start()
        except (can.CanError, OSError) as exc:
            raise BusOpenError(f"simulated rig: cannot open CAN bus interface={config.bus.interface!r} "
                               f"channel={config.bus.channel!r}: {exc}") from exc
    try:
        network = open_network(bus_settings(config.bus), timing_of(config.bus, config.sync_mode))
    except BaseException:
        if rig is not None:
            rig.stop()
        raise
    try:
        yield Session(network, rig, drives)
    finally:
        network.disconnect()
        if rig is not None:
            rig.stop()


def watchdog_lines(bus: BusConfig, sync_mode: str) -> list[str]:
    """What ``ident-hw check`` says of a bus's timing and of each of its watchdogs (``bus.timing``,
    ``bus.watchdogs``; ``sync_mode``: its SYNC producer, :attr:`ident_hw.config.file.Config.sync_mode`):
    the value, and what it does on this bus."""
    w = watchdogs(bus)
    timing = timing_of(bus, sync_mode)          # None: lockstep
    settings = bus_settings(bus)
    if timing is None:
        where = ("lockstep: the master sends SYNC k+1 once the simulated rig answered SYNC k; the heartbeats go "
                 "out and are watched by SYNC count, in simulated time, both ways")
        unit = " of simulated time"
    elif timing.uses_process(settings):
        where = (f"a timing process of its own beside the master's (bus.timing: {bus.timing}) sends the SYNC, the "
                 f"set-points and the master's heartbeat, with real-time priority where the system grants it")
        unit = ""
    elif has_own_timer(bus.interface):
        where = (f"the bus's own timer ({bus.interface}: the kernel's BCM) sends the SYNC and the master's "
                 f"heartbeat; the master's notifier answers each SYNC with the set-points (bus.timing: thread)")
        unit = ""
    else:
        where = "threads of the master's process send the SYNC, the set-points and the master's heartbeat"
        unit = ""
    periods = w.heartbeat_period
    lines = [f"timing: {where}",
             "watchdogs (bus.watchdogs):",
             f"  drive_heartbeat {w.drive_timeout:g} s{unit}: the master stops the run when a drive's heartbeat "
             f"(every {periods:g} s) is this late ({w.drive_timeout / periods:g} periods)",
             f"  master_heartbeat {w.master_timeout:g} s{unit}: every drive faults (EMCY 0x8130) when the "
             f"master's heartbeat is this late (0x1016:01)"]
    if timing is None:
        lines.append(f"  sync_progress: not used in lockstep (a cycle the rig does not answer is a fault after "
                     f"bus.lockstep_timeout, {bus.lockstep_timeout:g} s)")
        lines.append("  master_progress: not used in lockstep (without SYNC nothing moves)")
        return lines
    lines.append(f"  sync_progress {w.sync_progress:g} s: the master stops a stream when no SYNC cycle came for this "
                 f"long (of the time it was running: a hold-up of its own process does not count)")
    if timing.uses_process(settings):
        lines.append(f"  master_progress {w.master_progress:g} s: the timing process stops the SYNC, the set-points "
                     f"and the heartbeat when the master's loop made no progress for this long: a hung master's "
                     f"drives fault within {w.master_progress + w.master_timeout:g} s, a shorter hold-up is survived")
    elif has_own_timer(bus.interface):
        lines.append("  master_progress: not watched: the kernel sends the SYNC and the heartbeat on while the "
                     "master's process hangs (the drives hold their last set-point, then get those it owes in a "
                     "burst) and stops with the process; bus.timing: process watches it")
    else:
        lines.append("  master_progress: not needed: the SYNC and the heartbeat stop with the master's process, "
                     "and a hold-up of it longer than master_heartbeat faults the drives")
    return lines
