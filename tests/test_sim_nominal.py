"""tests/nominal.py (the rig of the tests and benchmarks that run without a config) holds the
same rig as configs/sim-3prrr.yaml: geometry, true parameters, drive scalings."""

from pathlib import Path

import numpy as np

import nominal
from ident_hw.config import load_config, to_model
from ident_hw.config.to_drivers import axis_scaling

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "sim-3prrr.yaml"


def test_nominal_rig_equals_the_simulation_config():
    config = load_config(CONFIG)
    assert to_model.geometry(config.robot.geometry) == nominal.GEOMETRY
    np.testing.assert_array_equal(to_model.inertial_params(config.sim.truth).as_vector(), nominal.TRUE_PARAMS.as_vector())
    node_ids = [a.node_id for a in config.robot.actuators]
    assert [(a.node_id, a.profile, axis_scaling(a)) for a in config.robot.actuators] == nominal.axes("epos4", node_ids)
