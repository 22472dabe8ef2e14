"""Excitation and validation trajectories of the robots, with feasibility checks: the 3PRRR's
paper set and optimised Fourier excitation, the Delta's paper paths, any robot's joint-space
excitation (:mod:`trajectories.joint_space`), standstills, and trajectory files of any robot's
columns (:mod:`trajectories.files`).

Public API::

    from trajectories import Trajectory, Limits, check_trajectory, load, read, save
    from trajectories import carriage_sweep, five_squares, validation_triangle

Imports :mod:`ident_hw.model` (kinematics for the checks and the excitation's regressor), nothing
else of the project.
"""

import lazy_loader

# Each name is imported from its module on first use (PEP 562, by lazy_loader): the config,
# which names these modules, and ``ident-hw scan`` or ``sim`` do not pay for SciPy's
# interpolation and optimiser modules.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submodules=["delta_paper", "joint_space"], submod_attrs={
    "feasibility": ["InfeasibleTrajectory", "Limits", "Report", "Violation", "check_trajectory"],
    "files": ["TrajectoryFile", "TrajectoryFileError", "load", "read", "save"],
    "fourier": ["FourierExcitation", "optimise_excitation"],
    "motion": ["SampledMotion"],
    "paper": ["carriage_sweep", "five_squares", "square", "validation_triangle"],
    "paths": ["actuator_trajectory", "pose_trajectory"],
    "redundancy": ["CarriageSchedule", "carriage_schedule"],
    "standstill": ["standstill"],
    "trajectory": ["Trajectory"],
})
