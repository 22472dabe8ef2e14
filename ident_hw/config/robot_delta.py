"""The Delta's section of ``robot`` (``robot.delta``) and of ``sim`` (``sim.delta_truth``): its
geometry and its parameters (SI units)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ident_hw.model import DeltaGeometry

from .schema import non_negative, positive, spec


@dataclass(frozen=True)
class DeltaGeometryConfig:
    """Geometry of the Delta, per ``docs/delta-model.md`` (defaults: the SVD-DLS paper's Table 1)."""

    L1: float = field(default=DeltaGeometry.L1, metadata=spec(positive, unit="m", doc="upper arm"))
    L2: float = field(default=DeltaGeometry.L2, metadata=spec(positive, unit="m", doc="parallelogram rods"))
    R: float = field(default=DeltaGeometry.R, metadata=spec(positive, unit="m", doc="radius of the actuated joints"))
    r: float = field(default=DeltaGeometry.r, metadata=spec(positive, unit="m", doc="radius of the platform joints"))
    psi: tuple[float, float, float] = field(default=DeltaGeometry.psi, metadata=spec(
        unit="rad", angle=True, doc="azimuths of the three limbs"))


@dataclass(frozen=True)
class DeltaParametersConfig:
    """The Delta's 79 parameters: the nominal bodies of its geometry (``docs/delta-model.md``)
    with ``factors`` applied by name (``plat.m: 1.2`` = 20 % heavier), and the drive terms per arm."""

    fv: tuple[float, float, float] = field(default=(0.0,) * 3, metadata=spec(non_negative, unit="N m s/rad"))
    fc: tuple[float, float, float] = field(default=(0.0,) * 3, metadata=spec(non_negative, unit="N m"))
    Jm: tuple[float, float, float] = field(default=(0.0,) * 3, metadata=spec(
        non_negative, unit="kg m^2", doc="rotor inertia reflected through the gear"))
    factors: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class DeltaConfig:
    """The Delta: geometry and CAD parameters (the start and reference of the identification)."""

    geometry: DeltaGeometryConfig = DeltaGeometryConfig()
    cad: DeltaParametersConfig = DeltaParametersConfig()
