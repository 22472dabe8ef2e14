"""The Delta's parameter set of ``sim`` (``sim.delta_truth``, SI units): the simulated robot's
bodies relative to its description file's (``robot.description``, :mod:`ident_hw.model.delta_file`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from .schema import non_negative, spec


@dataclass(frozen=True)
class DeltaParametersConfig:
    """The Delta's 79 parameters: the bodies of its description file as the hand model takes them
    (:func:`ident_hw.model.delta_file.read_values`) with ``factors`` applied by name (``plat.m: 1.2``
    = 20 % heavier), and the drive terms per arm (default 0)."""

    fv: tuple[float, float, float] = field(default=(0.0,) * 3, metadata=spec(non_negative, unit="N m s/rad"))
    fc: tuple[float, float, float] = field(default=(0.0,) * 3, metadata=spec(non_negative, unit="N m"))
    Jm: tuple[float, float, float] = field(default=(0.0,) * 3, metadata=spec(
        non_negative, unit="kg m^2", doc="rotor inertia reflected through the gear"))
    factors: dict[str, float] = field(default_factory=dict)
