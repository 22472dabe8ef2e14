"""The ``recordings`` section: how recordings the tool did not make are read (CSV files of a
robot's own controller or of another lab), for ``recorded`` trajectories
(:mod:`ident_hw.experiment.external`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

from .schema import in_range, non_negative, positive, spec

#: SI value of one unit of each quantity a file may give (its ``units``)
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
POSITION_UNITS = {"rad": 1.0, "deg": 0.017453292519943295, "m": 1.0, "mm": 1e-3}
VELOCITY_UNITS = {"rad/s": 1.0, "deg/s": 0.017453292519943295, "m/s": 1.0, "mm/s": 1e-3}
CURRENT_UNITS = {"A": 1.0, "mA": 1e-3}
TORQUE_UNITS = {"N m": 1.0, "N": 1.0, "mN m": 1e-3}

#: a column: its number (1-based, as a spreadsheet counts) or, in a file with a header, its name
Column = int | str


@dataclass(frozen=True)
class ColumnsConfig:
    """Which column holds what: ``time``, and per actuator (in actuator order) ``position``, optionally
    ``velocity`` (differentiated from the positions when absent) and ``current`` or ``torque``
    (the joint force: the actuator's ``torque_constant`` × ``gear_ratio`` turns it back into the
    motor current the identification works with). A column is its number, 1-based, or the name
    the header's last line gives it."""

    time: Column
    position: tuple[Column, ...]
    velocity: tuple[Column, ...] | None = None
    current: tuple[Column, ...] | None = None
    torque: tuple[Column, ...] | None = None


if TYPE_CHECKING:     # a type checker sees text; the schema reads the units at run time
    TimeUnit = str
    PositionUnit = str
    VelocityUnit = str
    CurrentUnit = str
    TorqueUnit = str
else:
    TimeUnit, PositionUnit = Literal[tuple(TIME_UNITS)], Literal[tuple(POSITION_UNITS)]
    VelocityUnit, CurrentUnit = Literal[tuple(VELOCITY_UNITS)], Literal[tuple(CURRENT_UNITS)]
    TorqueUnit = Literal[tuple(TORQUE_UNITS)]


@dataclass(frozen=True)
class UnitsConfig:
    """The unit of each quantity in the file (converted to SI on reading)."""

    time: TimeUnit = "s"
    position: PositionUnit = "rad"
    velocity: VelocityUnit = "rad/s"
    current: CurrentUnit = "A"
    torque: TorqueUnit = "N m"


@dataclass(frozen=True)
class ScaleConfig:
    """Factors applied after the unit (one for all actuators, or one per actuator): a joint whose
    current the file gives with the opposite sign has -1; a position in encoder counts has the
    rad (m) per count."""

    position: float | tuple[float, ...] = 1.0
    velocity: float | tuple[float, ...] = 1.0
    current: float | tuple[float, ...] = 1.0
    torque: float | tuple[float, ...] = 1.0


@dataclass(frozen=True)
class RecordingsConfig:
    """How the files of ``recorded`` trajectories are read.

    ``delimiter``: the CSV field separator (``","``; ``" "`` for any run of blanks); ``header``:
    lines before the data (the last of them names the columns when ``columns`` uses names);
    ``bad_rows``: what a row that is not data does (a line with the wrong number of fields or a
    field that is no number, a value beyond any the robot can reach, a time that does not go
    forward): ``cut`` leaves it out and the report names its line and the reason, ``error``
    stops with that message. ``absurd``: a value is beyond reach when it lies further outside
    the actuator's limits than this many times their size (position range, velocity, current).
    ``gap``: two rows further apart than this many times the median step are a gap: the
    recording is cut there, as the tool's own recordings are at a skipped SYNC slot.
    ``idle_tolerance``: a head or tail where no actuator leaves its first (last) position by more
    than this fraction of its position range is idle, and left out. ``current_delay``: s by which
    the currents (torques) are stamped late against the positions (one for all actuators, or one
    per actuator; negative: early): a logger that takes the two from different buses or filters,
    which the quality verdict's force lag shows; the currents are read at their stamp minus it.
    """

    columns: ColumnsConfig
    delimiter: str = ","
    header: int = field(default=0, metadata=spec(non_negative, doc="lines before the data"))
    units: UnitsConfig = UnitsConfig()
    scale: ScaleConfig = ScaleConfig()
    bad_rows: Literal["cut", "error"] = "cut"
    absurd: float = field(default=1.0, metadata=spec(positive))
    gap: float = field(default=2.5, metadata=spec(in_range(1.5, 100.0)))
    idle_tolerance: float = field(default=1e-3, metadata=spec(in_range(0.0, 0.5)))
    current_delay: float | tuple[float, ...] = field(default=0.0, metadata=spec(in_range(-1.0, 1.0), unit="s"))
