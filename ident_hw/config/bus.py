"""The ``bus`` section: the CAN bus (python-can), its SYNC and the drives' streamed current."""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from typing import Literal

import can

import drivers.bus

from .schema import in_range, positive, spec


def _python_can_interface(name: str) -> None:
    """An interface name python-can knows (``can.interfaces.VALID_INTERFACES``)."""
    if name not in can.interfaces.VALID_INTERFACES:
        close = difflib.get_close_matches(name, sorted(can.interfaces.VALID_INTERFACES), n=1)
        hint = f"did you mean {close[0]!r}?" if close else \
            f"python-can has {', '.join(sorted(can.interfaces.VALID_INTERFACES))}"
        raise ValueError(f"python-can has no interface {name!r}; {hint}")


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
    heartbeat: float = field(default=0.1, metadata=spec(positive, unit="s"))
    heartbeat_timeout: float | None = field(default=None, metadata=spec(
        positive, unit="s", doc="consumer heartbeat timeout on both sides (default 3.5 heartbeat periods)"))
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
