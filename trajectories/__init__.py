"""Excitation and validation trajectories for the 3PRRR, with feasibility checks.

Public API::

    from trajectories import Trajectory, Limits, check_trajectory, load, save
    from trajectories import carriage_sweep, five_squares, validation_triangle

Imports :mod:`ident_hw.model` (kinematics for the checks and the excitation's regressor), nothing
else of the project.
"""

from .feasibility import InfeasibleTrajectory, Limits, Report, Violation, check_trajectory
from .files import TrajectoryFileError, load, save
from .fourier import FourierExcitation, optimise_excitation
from .paper import carriage_sweep, five_squares, square, validation_triangle
from .paths import actuator_trajectory, pose_trajectory
from .redundancy import CarriageSchedule, carriage_schedule
from .trajectory import Trajectory

__all__ = [
    "CarriageSchedule",
    "FourierExcitation",
    "InfeasibleTrajectory",
    "Limits",
    "Report",
    "Trajectory",
    "TrajectoryFileError",
    "Violation",
    "actuator_trajectory",
    "carriage_schedule",
    "carriage_sweep",
    "check_trajectory",
    "five_squares",
    "load",
    "optimise_excitation",
    "pose_trajectory",
    "save",
    "square",
    "validation_triangle",
]
