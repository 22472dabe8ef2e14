"""Config sections → the drivers' own settings (:mod:`drivers`): an actuator's unit scaling and
axis settings, the bus's python-can settings, and the simulated rig's encoder edges. The master
side of the drivers never reads the config."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

import drivers.axis
import drivers.bus
import drivers.errors
import drivers.supervision
import drivers.timing
from drivers.units import AxesScaling, AxisScaling

from .actuators import ActuatorConfig
from .bus import BusConfig
from .sim import SeedStream, SimConfig


def axis_scaling(actuator: ActuatorConfig) -> AxisScaling:
    """Drive-unit ↔ SI scaling of an actuator's axis."""
    return AxisScaling(kind=actuator.kind, counts_per_turn=actuator.counts_per_turn,
                       torque_constant=actuator.torque_constant, gear_ratio=actuator.gear_ratio,
                       screw_lead=actuator.screw_lead)


def axes_scaling(actuators: Sequence[ActuatorConfig]) -> AxesScaling:
    """The scalings of ``actuators`` as arrays over them (``counts_per_unit``, ``force_per_amp``,
    each (a,)), in their order."""
    return AxesScaling([axis_scaling(a) for a in actuators])


def axis_config(actuator: ActuatorConfig, base_dir: Path | None = None,
                current: str = drivers.axis.INSTANTANEOUS) -> drivers.axis.AxisConfig:
    """The drive driver's axis settings (SI) of an actuator; ``base_dir``: the folder its
    ``object_dictionary`` is relative to (the config file's, ``Config.base_dir``; None: the working directory); ``current``: the motor
    current it streams (``bus.current``).

    Raises:
        drivers.errors.ConfigError: the actuator has no ``node_id`` or no ``profile`` (a config
            that only identifies recordings made elsewhere may leave them out; a drive needs both).
    """
    node_id, profile = actuator.node_id, actuator.profile
    if node_id is None or profile is None:
        missing = "node_id" if node_id is None else "profile"
        raise drivers.errors.ConfigError(f"actuator {actuator.name!r}: no {missing}: a drive on the bus needs its "
                                         f"node-ID and profile (robot.actuators[].{missing})")
    od_file = actuator.object_dictionary
    if od_file is not None and base_dir is not None:
        od_file = str(Path(base_dir) / od_file)
    limits = actuator.limits
    return drivers.axis.AxisConfig(
        name=actuator.name, node_id=node_id, profile=profile, scaling=axis_scaling(actuator),
        position_min=limits.position[0], position_max=limits.position[1], max_velocity=limits.velocity,
        max_current=limits.current, following_error_window=limits.following_error,
        product_code=actuator.product_code, homing=actuator.homing, object_dictionary=od_file, current=current)


def bus_settings(bus: BusConfig, ignore_config: bool = True) -> drivers.bus.BusConfig:
    """python-can settings of the bus (``ignore_config``: ignore the user's python-can files; a
    virtual bus has no bitrate)."""
    bitrate = None if bus.interface == "virtual" else bus.bitrate
    return drivers.bus.BusConfig(interface=bus.interface, channel=bus.channel, bitrate=bitrate,
                                 ignore_config=ignore_config)


def encoder_edge_counts(sim: SimConfig, axes: int) -> np.ndarray:
    """(axes,) counts: each simulated axis's count-edge shift (``sim.encoder_edges``: 0 when
    ``fixed``, drawn from ``sim.seed`` when ``random``)."""
    if sim.encoder_edges == "fixed":
        return np.zeros(axes)
    return SeedStream.ENCODER_EDGES.rng(sim.seed).uniform(-0.5, 0.5, axes)


def watchdogs(bus: BusConfig) -> drivers.supervision.Watchdogs:
    """The heartbeat period and the time limits of ``bus.watchdogs`` (defaults filled in)."""
    w = bus.watchdogs
    return drivers.supervision.Watchdogs(heartbeat_period=bus.heartbeat, drive_heartbeat=w.drive_heartbeat,
                                         master_heartbeat=w.master_heartbeat, sync_progress=w.sync_progress,
                                         master_progress=w.master_progress)


def timing_settings(bus: BusConfig) -> drivers.timing.TimingConfig:
    """Where the bus's timers run (``bus.timing``) and the timing process's watch of the master."""
    return drivers.timing.TimingConfig(where=bus.timing, master_progress=bus.watchdogs.master_progress)
