"""Robot models (pure math): the 3PRRR (kinematics, Lagrange-multiplier dynamics, regressor) and
the Delta of the SVD-DLS paper (:mod:`ident_hw.model.delta`: kinematics, virtual-work regressor),
both implementing :class:`~ident_hw.model.interface.RobotModel` (what the simulated rig's plant
asks of a robot).

This package imports nothing else of the project.
"""

from .delta import Delta, DeltaGeometry
from .errors import KinematicsError, SingularityError
from .kinematics import Motion, SingularityMargins
from .interface import RobotModel
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
    "RobotModel",
    "Simulation",
    "SingularityError",
    "SingularityMargins",
    "ThreePRRR",
]
