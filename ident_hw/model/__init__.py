"""3PRRR model: kinematics, Lagrange-multiplier dynamics and the regressor (pure math).

This package imports nothing else of the project.
"""

from .errors import KinematicsError, SingularityError
from .kinematics import Motion, SingularityMargins
from .parameters import ACTUATOR_NAMES, Geometry, InertialParams
from .robot import Simulation, ThreePRRR

__all__ = [
    "ACTUATOR_NAMES",
    "Geometry",
    "InertialParams",
    "KinematicsError",
    "Motion",
    "Simulation",
    "SingularityError",
    "SingularityMargins",
    "ThreePRRR",
]
