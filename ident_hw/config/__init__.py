"""Config files: YAML → validated, typed, frozen dataclasses. Loading never opens a bus.

    from ident_hw.config import load_config, ConfigError
    cfg = load_config("configs/sim-3prrr.yaml")     # raises ConfigError naming file, line, key
    cfg.robot.geometry.to_model()                    # ident_hw.model.Geometry
    cfg.robot.actuators[3].scaling()                 # drivers.units.AxisScaling

Sections turn into the objects of the layers below (model geometry and parameters, drive axis
and bus settings, trajectory limits, filter settings), so the config imports those; it imports
nothing of the runner, the report or the CLI.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from .schema import ConfigError, build
from .sections import (ActuatorConfig, BusConfig, Config, FilterConfig, GeometryConfig, HomingConfig,
                       IdentificationConfig, InertialConfig, LimitsConfig, OnlineConfig,
                       OutputConfig, QualityConfig, RobotConfig, SafetyConfig, SimConfig, SimFaultConfig, StepConfig, TrajectoryConfig)
from .source import compose_file

__all__ = [
    "load_config", "resolved_yaml", "ConfigError", "Config", "RobotConfig", "GeometryConfig",
    "InertialConfig", "ActuatorConfig", "LimitsConfig", "HomingConfig", "SafetyConfig", "BusConfig",
    "SimConfig", "SimFaultConfig", "TrajectoryConfig", "IdentificationConfig", "StepConfig",
    "FilterConfig", "OnlineConfig", "OutputConfig", "QualityConfig",
]


def load_config(path: str | Path) -> Config:
    """Read, merge (``extends:``) and validate a config file."""
    config = build(Config, compose_file(path))
    object.__setattr__(config, "source", str(path))
    return config


def resolved_yaml(path: str | Path, replace: dict[str, str] | None = None) -> str:
    """The config as one self-contained YAML text, with every ``extends:`` merged in
    (what a results folder keeps as its copy of the config); ``replace``: text values by dotted
    key (``robot.described.description``), e.g. a file path that the copy must point elsewhere."""
    node = compose_file(path)
    for dotted, value in (replace or {}).items():
        target = node
        for key in dotted.split("."):
            target = next(v for k, v in target.value if k.value == key)
        target.value = value
    return yaml.serialize(node, Dumper=yaml.SafeDumper)
