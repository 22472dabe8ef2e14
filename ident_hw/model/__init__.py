"""Robot models (pure math): the 3PRRR (kinematics, Lagrange-multiplier dynamics, regressor) and
the Delta of the SVD-DLS paper (:mod:`ident_hw.model.delta`: kinematics, virtual-work regressor).

This package imports nothing else of the project.
"""

from .delta import Delta, DeltaGeometry
from .errors import KinematicsError, SingularityError
from .kinematics import Motion, SingularityMargins
from .parameters import ACTUATOR_NAMES, Geometry, InertialParams
from .robot import Simulation, ThreePRRR

__all__ = [
    "ACTUATOR_NAMES",
    "Delta",
    "DeltaGeometry",
    "Geometry",
    "InertialParams",
    "KinematicsError",
    "Motion",
    "Simulation",
    "SingularityError",
    "SingularityMargins",
    "ThreePRRR",
]
