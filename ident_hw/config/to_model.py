"""Config sections → the model's own types (:mod:`ident_hw.model`): the 3PRRR's inertial
parameters, the Delta's parameter vector, a described robot's parameter
vector. The model never reads the config; the robot as a whole is its kind's
(:func:`ident_hw.config.robots.model_of`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ident_hw.model import Delta, InertialParams
from ident_hw.model.friction import FrictionModel

from .robot_3prrr import InertialConfig
from .robot_delta import DeltaParametersConfig
from .robot_described import ParameterSetConfig

if TYPE_CHECKING:  # pinocchio, which described imports, is imported by described robots only
    from ident_hw.model.described import DescribedRobot


#: rad | m, the Dahl presliding distance a model is built with where the config says ``auto`` and
#: the identification has not chosen one yet (:mod:`ident_hw.experiment.friction_choice`)
DEFAULT_PRESLIDING = 5e-4
#: rad/s | m/s, the Stribeck velocity likewise
DEFAULT_STRIBECK = 0.2


def friction_model(robot, presliding: float | tuple[float, ...] | None = None,
                   stribeck: float | tuple[float, ...] | None = None) -> FrictionModel:
    """The friction model of a ``robot`` section (``robot.friction``, smoothing
    ``robot.coulomb_width``); ``presliding``, ``stribeck``: the Dahl distance and the Stribeck
    velocity (one, or one per actuator) to use where the config says ``auto`` (default :data:`DEFAULT_PRESLIDING`,
    :data:`DEFAULT_STRIBECK`)."""
    f = robot.friction
    chosen = f.presliding if f.presliding != "auto" else (DEFAULT_PRESLIDING if presliding is None else presliding)
    if f.stribeck is False:
        velocity = None
    elif f.stribeck == "auto":
        velocity = DEFAULT_STRIBECK if stribeck is None else stribeck
    else:
        velocity = float(f.stribeck)
    return FrictionModel(kind=f.model, width=robot.coulomb_width, rest_speed=f.rest_speed, presliding=chosen,
                         stribeck_velocity=velocity, offset=f.offset, elements=f.elements)


def inertial_params(p: InertialConfig) -> InertialParams:
    """The 3PRRR's inertial and friction parameters."""
    return InertialParams(m_c=p.m_c, m_l1=p.m_l1, I_l1=p.I_l1, m_l2=p.m_l2, I_l2=p.I_l2, m_ee=p.m_ee,
                          I_ee=p.I_ee, f_v=p.f_v, f_c=p.f_c)


def delta_parameters(p: DeltaParametersConfig, bodies: np.ndarray) -> np.ndarray:
    """(79,) the Delta's parameters in the order of :data:`ident_hw.model.delta.PARAM_NAMES`: its
    ``bodies`` (79,) (its description file's, :func:`ident_hw.model.delta_file.read_values`) with
    the factors applied, then the drive terms given (0 where not)."""
    pi = np.array(bodies, dtype=float)
    names = Delta.parameter_names
    for name, factor in p.factors.items():
        pi[names.index(name)] *= factor
    pi[-9:] = [*p.fv, *p.fc, *p.Jm]
    return pi


def described_parameters(p: ParameterSetConfig, model: DescribedRobot) -> np.ndarray:
    """(P,) a described robot's parameters in the order of ``model.parameter_names``: its
    description's bodies with the factors then the values applied, then the drive terms given."""
    pi = model.nominal_parameters()
    names = model.parameter_names
    for name, factor in p.factors.items():
        pi[names.index(name)] *= factor
    for name, value in p.values.items():
        pi[names.index(name)] = value
    n = len(model.actuator_names)
    start = len(pi) - 3 * n
    for k, key in enumerate(("fv", "fc", "Jm")):
        given = getattr(p, key)
        if given:
            pi[start + k * n:start + (k + 1) * n] = given
    return pi
