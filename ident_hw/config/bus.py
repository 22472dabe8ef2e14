"""The ``bus`` section: the CAN bus (python-can), its SYNC and the drives' streamed current."""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from typing import Literal

import can

import drivers.bus
import drivers.supervision

from .schema import in_range, positive, spec


def _python_can_interface(name: str) -> None:
    """An interface name python-can knows (``can.interfaces.VALID_INTERFACES``)."""
    if name not in can.interfaces.VALID_INTERFACES:
        close = difflib.get_close_matches(name, sorted(can.interfaces.VALID_INTERFACES), n=1)
        hint = f"did you mean {close[0]!r}?" if close else \
            f"python-can has {', '.join(sorted(can.interfaces.VALID_INTERFACES))}"
        raise ValueError(f"python-can has no interface {name!r}; {hint}")


@dataclass(frozen=True)
class WatchdogsConfig:
    """The ``bus.watchdogs`` section: every time limit that stops a run when one side goes silent
    (:class:`drivers.supervision.Watchdogs`); ``ident-hw check`` prints what each one is for a
    config."""

    drive_heartbeat: float | None = field(default=None, metadata=spec(
        positive, unit="s", doc="the master stops the run when a drive's heartbeat is this late, counted in the time "
                                "the master was running and watching (in lockstep the simulated time). Default 3.5 "
                                "heartbeat periods: three heartbeats lost in a row (a drive's heartbeat comes from "
                                "its firmware, on time)"))
    master_heartbeat: float | None = field(default=None, metadata=spec(
        positive, unit="s", doc="every drive's consumer time of the master's heartbeat (0x1016:01): a drive faults "
                                "(EMCY 0x8130) when the master's heartbeat is this late. Default 3.5 heartbeat "
                                "periods: the master's heartbeat comes from a timer outside its process (a timing "
                                "process, SocketCAN's BCM), not from a thread that the master's own hold-ups stop"))
    sync_progress: float = field(default=drivers.supervision.SYNC_PROGRESS, metadata=spec(
        positive, unit="s", doc="the master stops a stream when no new SYNC cycle came for this long, counted in the "
                                "time it was running and watching (a hold-up of its own process is no stall of the "
                                "SYNC); the drives hold their last set-point meanwhile"))
    master_progress: float = field(default=drivers.supervision.MASTER_PROGRESS, metadata=spec(
        positive, unit="s", doc="a timing process (bus.timing) stops the SYNC, the set-points and the master's "
                                "heartbeat when the master's own loop made no progress for this long, so that the "
                                "drives fault within this plus master_heartbeat of a hung master; a longer hold-up of "
                                "the master's process stops the run. Default 5 s: twice the longest hold-ups seen on "
                                "loaded lab PCs (2.18 s at load 9; a 1 s GIL hold at load 8 once became 3 s)"))


@dataclass(frozen=True)
class BusConfig:
    """The CAN bus (python-can) and the SYNC rate of the cyclic exchange."""

    interface: str = field(metadata=spec(_python_can_interface, doc="a python-can interface name"))
    channel: str
    bitrate: int = field(default=1_000_000, metadata=spec(
        positive, unit="bit/s", doc="the bus's nominal bitrate, the budget of the bus-load check of the SYNC rate "
                                    "(drivers.bus.check_bus_load); a 'virtual' bus has none and ignores it (a lab's "
                                    "config extended onto a virtual bus inherits its hardware's)"))
    sync_rate: float = field(default=250.0, metadata=spec(in_range(1.0, 2000.0), unit="Hz"))
    sdo_timeout: float = field(default=0.5, metadata=spec(positive, unit="s"))
    heartbeat: float = field(default=0.1, metadata=spec(
        positive, unit="s", doc="producer heartbeat period of the drives (0x1017) and of the master"))
    heartbeat_timeout: float | None = field(default=None, metadata=spec(
        positive, unit="s", doc="retired: one timeout for both sides; now bus.watchdogs.drive_heartbeat and "
                                "bus.watchdogs.master_heartbeat"))
    watchdogs: WatchdogsConfig = field(default=WatchdogsConfig(), metadata=spec(
        doc="the time limits that stop a run when one side goes silent"))
    timing: Literal["auto", "process", "thread"] = field(default="auto", metadata=spec(
        doc="where a periodic SYNC, the set-points and the master's heartbeat are timed: 'process' (a timing process "
            "of their own beside the master's, which owns the bus: no GIL hold, garbage collection or busy core of the "
            "master's process stops them), 'thread' (the bus's own timer where it has one, SocketCAN's BCM, else "
            "threads of the master's process; the set-points from its notifier), 'auto' (a process on every bus "
            "another process can open: all but python-can's 'virtual')"))
    bring_up_timeout: float = field(default=5.0, metadata=spec(
        positive, unit="s", doc="time for every drive to answer and reach PRE-OPERATIONAL at bring-up"))
    sync: Literal["periodic", "lockstep"] | None = field(default=None, metadata=spec(
        doc="SYNC producer: 'periodic' (real drives) or 'lockstep' (the simulated rig: SYNC k+1 once "
            "cycle k is in, simulated time = SYNC count x period); default lockstep against the "
            "simulated rig, periodic otherwise"))
    lockstep_timeout: float = field(default=10.0, metadata=spec(
        positive, unit="s", doc="wall-clock time a lockstep cycle may take before it is a fault"))
    current: Literal["instantaneous", "averaged"] = field(default="instantaneous", metadata=spec(
        doc="the motor current TPDO1 carries: 'instantaneous' (the drive's current actual value, sampled at "
            "each SYNC: EPOS4 0x30D1:02, EPOS2 0x6078) or 'averaged' (its running 50 Hz first-order low-pass: "
            "EPOS4 0x30D1:01, EPOS2 0x2027; the identification then filters the regressor by the same filter)"))

    @property
    def is_local(self) -> bool:
        """True for buses that cannot reach hardware (:func:`drivers.bus.is_local`)."""
        return drivers.bus.is_local(self.interface, self.channel)
