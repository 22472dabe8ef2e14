"""The 3PRRR's parameter set (``sim.truth``: the simulated robot's true values; SI units). Its geometry
and CAD values are its description file's (``robot.description``, :mod:`ident_hw.model.prrr_file`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from .schema import non_negative, spec


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
