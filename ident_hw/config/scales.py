"""Typical sizes of the parameters, and the kinds of parameters their names tell.

A parameter's scale is its typical magnitude: the online estimators work in parameters divided by
it, and the consistent step's CAD prior has a standard deviation of ``prior`` scales. Scales come
from a config's ``scales`` (by parameter name, friction kind ``fv_zeta`` or drive term ``fv``),
else the magnitude of the CAD value, else :data:`FRICTION_SCALES`, else (a body parameter) the
largest CAD magnitude of its family (:data:`BODY_PARAMETER_FAMILIES`).
"""

from __future__ import annotations

from .schema import FieldError

#: typical magnitudes of the friction coefficients by kind (they have no CAD value): the
#: parameter scales where a config's ``scales`` give none. A lab's rig:
#: revolute joints behind a gear 0.01-0.1 N·m(·s/rad), carriages on ball screws 1-100 N(·s/m).
FRICTION_SCALES = {"fv_theta": 0.01, "fc_theta": 0.01, "fv_zeta": 10.0, "fc_zeta": 1.0}


def parameter_kind(name: str) -> str:
    """The kind of a parameter, for scales given per kind: ``fv_theta1`` → ``fv_theta``,
    ``fv_1`` → ``fv``, ``rod2.Ixy`` → ``Ixy``; an inertial parameter of the 3PRRR is its own kind."""
    if "." in name:
        return name.split(".", 1)[1]
    if drive_term(name) is not None:
        return name.rstrip("0123456789").rstrip("_")
    return name


#: a body parameter's family, whose largest CAD magnitude scales a member whose CAD value is 0
#: (a product of inertia, the first moment of a body whose centre of mass is on its joint axis)
BODY_PARAMETER_FAMILIES = {"m": "mass", "mx": "first moment", "my": "first moment", "mz": "first moment",
                           **{i: "inertia" for i in ("Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")}}


def drive_term(name: str) -> str | None:
    """``fv``, ``fc``, ``Jm``, ``fs`` or ``f0`` for an actuator's drive parameter (``fv_elbow``;
    ``fc2_elbow``, a Maxwell-slip element's Coulomb force: ``fc``), else None."""
    head = name.split("_", 1)[0]
    if head[:2] == "fc" and head[2:].isdigit():
        head = "fc"
    return head if "_" in name and head in ("fv", "fc", "Jm", "fs", "f0") else None


def check_scales(scales: dict[str, float]) -> None:
    """Every scale a config gives is positive (FieldError naming the first that is not)."""
    for name, value in scales.items():
        if not value > 0:
            raise FieldError(f"scales.{name}", f"must be positive, got {value}")


def parameter_scales(names, cad, scales: dict[str, float], where: str) -> tuple[float, ...]:
    """(n,) the scale of every parameter ``names`` (n,) with CAD values ``cad`` (module
    docstring); ``scales`` the config's overrides, ``where`` their key (for the error).

    Raises:
        FieldError: a parameter with no CAD value and no scale given.
    """
    typical: dict[str, float] = {}       # largest CAD magnitude of each body-parameter family
    for name, value in zip(names, cad):
        if "." in name:
            family = BODY_PARAMETER_FAMILIES.get(parameter_kind(name), "")
            typical[family] = max(typical.get(family, 0.0), abs(value))
    out = []
    for name, value in zip(names, cad):
        kind, term = parameter_kind(name), drive_term(name)
        body_family = BODY_PARAMETER_FAMILIES.get(kind) if "." in name else None
        default = abs(value) or FRICTION_SCALES.get(kind, 0.0) or (typical.get(body_family, 0.0) if body_family else 0.0)
        given = [scales[key] for key in (name, kind, term) if key is not None and key in scales]
        scale = given[0] if given else default
        if not scale > 0:
            raise FieldError(f"scales.{name}", f"{where}.{name}: no CAD value to take a scale from: give one "
                             "(or one for its kind)")
        out.append(float(scale))
    return tuple(out)
