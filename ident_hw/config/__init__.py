"""Config files: YAML → validated, typed, frozen dataclasses. Loading never opens a bus.

    from ident_hw.config import load_config, ConfigError, to_model, to_drivers
    cfg = load_config("configs/sim-3prrr.yaml")     # raises ConfigError naming file, line, key
    model_of(cfg.robot)                              # the robot's model (ident_hw.config.robots)
    to_drivers.axis_scaling(cfg.robot.actuators[3])  # drivers.units.AxisScaling

The sections are plain data, one module per family (:mod:`.robot` and the robots' own
:mod:`.robot_3prrr`, :mod:`.robot_delta`, :mod:`.robot_described`; :mod:`.actuators`, :mod:`.bus`, :mod:`.sim`,
:mod:`.trajectory`, :mod:`.identification`; the whole file :mod:`.file`), read by the generic
:mod:`.schema` from what :mod:`.source` composes; their cross-field rules are :mod:`.checks`. The
adapters turn them into the objects of the layers below, in those layers' own types:
:mod:`.to_model`, :mod:`.to_drivers`, :mod:`.to_identification`, and the robot as a whole by
its kind (:mod:`.robots`). The config imports nothing of the trajectories (the runner builds them:
:mod:`ident_hw.experiment.robot_trajectories`), the runner, the report or the CLI.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import yaml

from .actuators import ActuatorConfig, HomingConfig, LimitsConfig
from .bus import BusConfig
from .checks import CHECKS
from .file import Config, OutputConfig
from .identification import (FilterConfig, IdentificationConfig, OnlineConfig, PhysicalConfig, QualityConfig,
                             StepConfig)
from .robot import RobotConfig, SafetyConfig
from .robot_3prrr import InertialConfig
from .robot_delta import DeltaParametersConfig
from .robot_described import DescribedConfig, ParameterSetConfig
from .schema import ConfigError, build
from .sim import SimConfig, SimFaultConfig
from .source import compose_file
from .trajectory import PayloadConfig, TrajectoryConfig

__all__ = [
    "load_config", "resolved_yaml", "ConfigError", "Config", "RobotConfig",
    "InertialConfig", "DeltaParametersConfig", "DescribedConfig",
    "ParameterSetConfig", "ActuatorConfig", "LimitsConfig", "HomingConfig", "SafetyConfig", "BusConfig",
    "SimConfig", "SimFaultConfig", "TrajectoryConfig", "PayloadConfig", "IdentificationConfig", "StepConfig",
    "FilterConfig", "OnlineConfig", "PhysicalConfig", "OutputConfig", "QualityConfig",
]


def load_config(path: str | Path) -> Config:
    """Read, merge (``extends:``) and validate a config file; its relative paths are relative to
    its folder (``Config.base_dir``)."""
    return build(Config, compose_file(path), CHECKS, given={"source": str(path), "base_dir": Path(path).parent})


def resolved_yaml(path: str | Path, replace: Mapping[str, str] | None = None) -> str:
    """The config as one self-contained YAML text, with every ``extends:`` merged in
    (what a results folder keeps as its copy of the config); ``replace``: text values by dotted
    key (``robot.description``; a list's item by its index: ``trajectories.2.path``), e.g. a file
    path that the copy must point elsewhere."""
    node = compose_file(path)
    for dotted, value in (replace or {}).items():
        target = node
        for key in dotted.split("."):
            if isinstance(target, yaml.SequenceNode):      # a list's item by its index
                target = target.value[int(key)]
            else:
                target = next(v for k, v in target.value if k.value == key)
        target.value = value
    return yaml.serialize(node, Dumper=yaml.SafeDumper)
