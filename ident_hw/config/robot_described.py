"""The sections of a robot from its description file (``robot.description``): its settings
``robot.described`` and a parameter set (its CAD parameters, ``sim.parameters`` its true ones)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from .schema import non_negative, positive, spec


@dataclass(frozen=True)
class ParameterSetConfig:
    """Parameters of a described robot: the description file's bodies with ``factors`` (by
    parameter name, ``platform.m: 1.1`` = 10 % heavier) then ``values`` (by name, in SI units)
    applied, and per actuator, in actuator order, viscous ``fv`` and Coulomb ``fc`` friction and
    the rotor inertia ``Jm`` reflected through the gear (default 0)."""

    factors: dict[str, float] = field(default_factory=dict)
    values: dict[str, float] = field(default_factory=dict)
    fv: tuple[float, ...] = field(default=(), metadata=spec(non_negative, unit="N m s/rad | N s/m"))
    fc: tuple[float, ...] = field(default=(), metadata=spec(non_negative, unit="N m | N"))
    Jm: tuple[float, ...] = field(default=(), metadata=spec(non_negative, unit="kg m^2 | kg"))


@dataclass(frozen=True)
class DescribedConfig:
    """The settings of a robot from its description file (``robot.description``: MJCF for closed
    chains, URDF for serial robots) beyond the file itself; every one has a default, and the
    section may be left out.

    The actuators of ``robot.actuators`` name the joints they drive (``joint``); ``home`` gives
    tree joint values (rad, m) of an assembled configuration near home, whose assembly mode is
    kept; ``end_effector`` is the body a payload goes on; ``cad``: the CAD parameters (the
    description's inertias by default); ``max_condition``: the feasibility check's largest
    condition number of the passive joints' closure Jacobian (distance to a parallel singularity).
    """

    #: keys of earlier versions and what replaced them (the schema's error names it)
    RETIRED_KEYS: ClassVar[dict[str, str]] = {
        "description": "every robot's description file is `robot.description` now, whatever its kind: write "
                       "`description: <file>` (MJCF .xml or URDF .urdf, relative to this file) in the robot "
                       "section beside `kind: described`, and keep home, end_effector, cad, ... here"}

    home: dict[str, float] = field(default_factory=dict)
    home_actuated: tuple[float, ...] | None = field(default=None, metadata=spec(
        unit="rad | m", doc="actuated coordinates of home (default: those of home)"))
    end_effector: str | None = None
    cad: ParameterSetConfig = ParameterSetConfig()
    max_condition: float = field(default=100.0, metadata=spec(positive))
