"""A whole config file: its sections, the file it was read from and the folder its relative
paths start from."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import drivers.axis

from .bus import BusConfig
from .identification import IdentificationConfig
from .recordings import RecordingsConfig
from .robot import RobotConfig
from .schema import spec
from .sim import SimConfig
from .trajectory import TrajectoryConfig


@dataclass(frozen=True)
class OutputConfig:
    """Where results go (relative paths are relative to the working directory)."""

    dir: str = "results"
    raw_log: Literal[".log", ".asc", ".blf"] = ".log"


@dataclass(frozen=True)
class Config:
    """A whole config file. Only ``robot`` is required; a campaign also needs ``bus``,
    ``trajectories`` and ``identification``; ``recorded`` trajectories (recordings made
    elsewhere) need ``recordings``, which says how their files are read."""

    robot: RobotConfig
    bus: BusConfig | None = None
    sim: SimConfig | None = None
    trajectories: tuple[TrajectoryConfig, ...] = ()
    identification: IdentificationConfig | None = None
    recordings: RecordingsConfig | None = None
    output: OutputConfig = OutputConfig()
    source: str = field(default="", compare=False, metadata=spec(
        key=False, doc="the file it was read from (for messages, and the copy a results folder keeps)"))
    base_dir: Path | None = field(default=None, compare=False, metadata=spec(
        key=False, doc="the folder the relative paths of trajectories and actuators are relative to (the "
                       "file's); None: the working directory"))

    @property
    def simulated(self) -> bool:
        """True when the bus is served by the simulated rig and cannot reach hardware."""
        return self.sim is not None and self.bus is not None and self.bus.is_local

    @property
    def sync_mode(self) -> str:
        """The SYNC producer of the runs: ``bus.sync``, by default lockstep on the simulated rig."""
        if self.bus is not None and self.bus.sync is not None:
            return self.bus.sync
        return "lockstep" if self.simulated else "periodic"

    @property
    def current(self) -> str:
        """The motor current the drives stream: ``bus.current`` (the instantaneous one without a bus)."""
        return self.bus.current if self.bus is not None else drivers.axis.INSTANTANEOUS

    def trajectory(self, name: str) -> TrajectoryConfig:
        return next(t for t in self.trajectories if t.name == name)
