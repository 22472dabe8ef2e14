"""``ident-hw export``: the physically consistent parameters of a results folder written into the
robot's description file (:func:`ident_hw.experiment.description_writer.write_description`).

The results folder holds what it needs: its ``config.yaml`` names the copy of the description
file in ``description/`` (every robot's), ``parameters.json`` the consistent set
(:class:`ident_hw.identification.physical.ConsistentSet`). The 3PRRR and the Delta, identified on
their hand-derived models, have their values mapped onto the file's bodies first
(:func:`ident_hw.model.prrr_file.described_parameters`,
:func:`ident_hw.model.delta_file.described_parameters`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from drivers.errors import ConfigError, RecordingError
from ident_hw.config import load_config
from ident_hw.config.robots import kind_of, model_of
from ident_hw.experiment.description_writer import write_description
from ident_hw.results import load_results


def export_description(results_folder: str | Path, to: str | Path, for_mujoco: bool = False) -> Path:
    """Write the robot of ``results_folder`` with its consistent parameters to ``to`` (MJCF or
    URDF, as the robot's file came); returns the path written. ``for_mujoco``: refuse bodies
    MuJoCo cannot load (:func:`ident_hw.experiment.description_writer.write_description`).

    Raises:
        RecordingError: the folder holds no consistent parameters, or ones of another robot.
        drivers.errors.ConfigError: the folder's robot is not described by a file.
    """
    folder = Path(results_folder)
    results = load_results(folder)
    config = load_config(folder / "config.yaml")
    to_described = kind_of(config.robot).described
    if to_described is None:
        raise ConfigError(f"{folder / 'config.yaml'}: robot.kind {config.robot.kind!r} has no description file to write")
    robot = model_of(config.robot)
    described, mapped = to_described(config.robot)
    consistent = results.consistent
    if consistent is None:
        raise RecordingError(f"{folder}: no physically consistent parameters in parameters.json (they need a "
                             "least-squares step and identification.physical.enabled; the step's record says "
                             "why when the program had no solution)")
    if consistent.names != tuple(robot.parameter_names):
        raise RecordingError(f"{folder}: the consistent parameters ({len(consistent.names)}) are not those of "
                             f"{described.path.name} ({len(robot.parameter_names)})")
    return write_description(described, mapped(np.asarray(consistent.values, dtype=float)), to, for_mujoco=for_mujoco)
