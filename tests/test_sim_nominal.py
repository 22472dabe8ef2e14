"""tests/nominal.py (the rig of the tests and benchmarks that run without a config) holds the
same rig as configs/sim-3prrr.yaml: geometry, true parameters, drive scalings."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import nominal
from ident_hw.config import load_config, to_model
from ident_hw.config.robots import model_of
from ident_hw.config.to_drivers import axis_scaling

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "sim-3prrr.yaml"


def test_nominal_rig_equals_the_simulation_config():
    config = load_config(CONFIG)
    geometry = model_of(config.robot).geometry
    # the guides' angles as pinocchio reads the description file: to the rounding of its rotations
    assert geometry.gamma == pytest.approx(nominal.GEOMETRY.gamma, rel=1e-15, abs=1e-15)
    assert dataclasses.replace(geometry, gamma=nominal.GEOMETRY.gamma) == nominal.GEOMETRY
    np.testing.assert_array_equal(to_model.inertial_params(config.sim.truth).as_vector(), nominal.TRUE_PARAMS.as_vector())
    node_ids = [a.node_id for a in config.robot.actuators]
    assert [(a.node_id, a.profile, axis_scaling(a)) for a in config.robot.actuators] == nominal.axes("epos4", node_ids)
