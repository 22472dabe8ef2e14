"""The 3PRRR's sections of ``robot``: its geometry and its inertial parameters (SI units)."""

from __future__ import annotations

from dataclasses import dataclass, field

from .schema import non_negative, positive, spec


def _plus_minus_one(value) -> None:
    if any(v not in (1, -1) for v in value):
        raise ValueError(f"expected +1 or -1 for each chain, got {list(value)}")


@dataclass(frozen=True)
class GeometryConfig:
    """Geometry of the 3PRRR, per ``docs/3prrr-model.md``."""

    l1: float = field(metadata=spec(positive, unit="m"))
    l2: float = field(metadata=spec(positive, unit="m"))
    s1: float = field(metadata=spec(non_negative, unit="m"))
    s2: float = field(metadata=spec(non_negative, unit="m"))
    h: float = field(metadata=spec(positive, unit="m"))
    a: float = field(metadata=spec(positive, unit="m"))
    gamma: tuple[float, float, float] = field(metadata=spec(unit="rad", angle=True))
    modes: tuple[int, int, int] = field(default=(1, 1, 1), metadata=spec(_plus_minus_one))


@dataclass(frozen=True)
class InertialConfig:
    """Masses (kg), inertias about the centres of mass (kg·m²), friction per actuator."""

    m_c: float = field(metadata=spec(non_negative, unit="kg"))
    m_l1: float = field(metadata=spec(non_negative, unit="kg"))
    I_l1: float = field(metadata=spec(non_negative, unit="kg m^2"))
    m_l2: float = field(metadata=spec(non_negative, unit="kg"))
    I_l2: float = field(metadata=spec(non_negative, unit="kg m^2"))
    m_ee: float = field(metadata=spec(non_negative, unit="kg"))
    I_ee: float = field(metadata=spec(non_negative, unit="kg m^2"))
    f_v: tuple[float, float, float, float, float, float] = field(
        default=(0.0,) * 6, metadata=spec(non_negative, unit="N m s/rad | N s/m"))
    f_c: tuple[float, float, float, float, float, float] = field(
        default=(0.0,) * 6, metadata=spec(non_negative, unit="N m | N"))
