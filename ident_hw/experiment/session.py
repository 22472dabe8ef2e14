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
from typing import TYPE_CHECKING, Iterator

import can
import canopen

from drivers.affinity import one_cpu
from drivers.axis import AxisConfig
from drivers.bus import open_network
from drivers.epos import DriveGroup
from drivers.errors import BusOpenError
from drivers.gc_freeze import frozen_gc
from drivers.sim.lockstep import LockstepSync
from drivers.sync import PeriodicSync, SyncSource
from drivers.units import MA_PER_AMP
from ident_hw.config import Config
from ident_hw.config.robots import true_parameters
from ident_hw.config.to_drivers import axis_scaling, bus_settings, encoder_edge_counts
from ident_hw.config.robots import model_of
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
    settings (:func:`ident_hw.experiment.plan.drive_axes`), the bus's heartbeat period and timeout
    and SDO timeout (s), and the SYNC producer: the simulated rig's lockstep at ``lockstep_period``
    (s; None: the periodic SYNC of real drives) waiting at most ``lockstep_timeout`` (s)."""

    axes: tuple[AxisConfig, ...]
    heartbeat: float
    heartbeat_timeout: float
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
        return cls(axes=tuple(drive_axes(config.robot.actuators, config.base_dir, config.current)), heartbeat=bus.heartbeat, heartbeat_timeout=bus.heartbeat_timeout,
                   sdo_timeout=bus.sdo_timeout, lockstep_period=sync_period(bus) if lockstep else None,
                   lockstep_timeout=bus.lockstep_timeout)

    def sync_source(self) -> SyncSource:
        """The SYNC producer of the runs (``bus.sync``): the simulated rig's lockstep, or the
        periodic SYNC of real drives."""
        if self.lockstep_period is not None:
            return LockstepSync(self.lockstep_period, timeout=self.lockstep_timeout)
        return PeriodicSync()


@dataclass(frozen=True)
class Session:
    """An open bus: ``network`` (the master), ``rig`` (the in-process simulated rig, or None), and
    how its drive group is made (``drives``)."""

    network: canopen.Network
    rig: SimulatedRig | None
    drives: DriveSettings

    def drive_group(self) -> DriveGroup:
        """The robot's drives, in actuator order, with the bus settings of the config."""
        d = self.drives
        return DriveGroup(self.network, list(d.axes), heartbeat_period=d.heartbeat,
                          heartbeat_timeout=d.heartbeat_timeout, sdo_timeout=d.sdo_timeout, sync=d.sync_source())


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
        network = open_network(bus_settings(config.bus))
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
