"""The model/data split of a described robot (issue 49 item 4): the robot is never changed by a
call, and what calls write lives in a :class:`~ident_hw.model.described.DescribedData` its user
owns.

Two data of one robot give bit for bit what two robots read separately from the same file give,
their calls interleaved (one sample of one motion, then one of the other) or run in two threads;
a plant's periods and an identification on one robot do not disturb each other; and after every
kind of call, with parameters far from the nominal ones, the robot's pinocchio inertias equal a
fresh pinocchio read of the file and its compiled arrays and nominal parameters are unchanged.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ident_hw.config import load_config
from ident_hw.config.robots import model_of
from ident_hw.model.described import DescribedRobot

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
SAMPLES = 120


@pytest.fixture(scope="module")
def stewart_factory():
    """Makes a fresh Stewart platform (six legs closed on one platform: Newton's warm start
    matters) from its description file, each call a separate robot."""
    config = load_config(CONFIGS / "robot-stewart.yaml").robot
    return lambda: model_of(config)


def motion(robot: DescribedRobot, phase: float, samples: int = SAMPLES):
    """A smooth actuated motion (each (N, n)) about home: sines of a few mm per leg."""
    t = np.linspace(0.0, 2.0, samples)[:, None]
    n = len(robot.actuator_names)
    w = 2 * np.pi * (0.5 + 0.1 * np.arange(n))[None, :]
    amp = 0.01
    Theta = robot.home_actuated() + amp * np.sin(w * t + phase)
    return Theta, amp * w * np.cos(w * t + phase), -amp * w**2 * np.sin(w * t + phase)


def regressor_calls(robot, m, data, chunk):
    """Generator: one ``identification_regressor`` call per ``chunk`` samples, yielding (Y, poses);
    a guess of zeros: each call's Newton warm started from the last sample the data solved."""
    guess = np.zeros((chunk, robot.pose_size))
    for k in range(0, len(m[0]), chunk):
        Theta, Thetad, Thetadd = (x[k:k + chunk] for x in m)
        yield robot.identification_regressor(Theta, Thetad, Thetadd, guess[:len(Theta)], data=data)


def plant_calls(robot, m, params, data):
    """Generator: one ``plant_dynamics`` call per sample, each started from the last pose."""
    q = None
    for Theta, Thetad in zip(m[0], m[1]):
        state = robot.plant_dynamics(Theta, Thetad, params, q, data=data)
        q = state.pose
        yield state.M, state.bias, q


def interleave(*generators):
    """The generators' items, one from each in turn, as one list per generator."""
    out: list[list] = [[] for _ in generators]
    for items in zip(*generators):
        for k, item in enumerate(items):
            out[k].append(item)
    return out


def assert_same(a, b):
    for x, y in zip(a, b, strict=True):
        for u, v in zip(x, y, strict=True):
            np.testing.assert_array_equal(u, v)


def test_two_data_of_one_robot_interleaved_equal_two_robots(stewart_factory):
    robot = stewart_factory()
    m1, m2 = motion(robot, 0.0), motion(robot, 1.3)
    d1, d2 = robot.create_data(), robot.create_data()
    own = robot.data.motion.floats.copy()
    together = interleave(regressor_calls(robot, m1, d1, 3), regressor_calls(robot, m2, d2, 3))
    first, second = stewart_factory(), stewart_factory()
    alone1 = list(regressor_calls(first, m1, first.create_data(), 3))
    alone2 = list(regressor_calls(second, m2, second.create_data(), 3))
    assert_same(together[0], alone1)
    assert_same(together[1], alone2)
    # each data holds the closure state of its own motion's last sample (the next call's start)
    for data, calls in ((d1, together[0]), (d2, together[1])):
        assert data.motion.last_valid
        np.testing.assert_array_equal(data.motion.views(robot.tree).last_q, calls[-1][1][-1])
    np.testing.assert_array_equal(robot.data.motion.floats, own)      # the robot's own data untouched
    # the test sees shared state: one data for both motions changes their last bits
    shared = robot.create_data()
    mixed = interleave(regressor_calls(robot, m1, shared, 3), regressor_calls(robot, m2, shared, 3))
    assert any(not np.array_equal(x[0], y[0]) for x, y in zip(mixed[0], alone1))


def test_plant_and_identification_on_one_robot_do_not_disturb_each_other(stewart_factory):
    robot = stewart_factory()
    m1, m2 = motion(robot, 0.0), motion(robot, 2.1)
    heavy = robot.nominal_parameters() * 1.7           # the plant's parameters, not the file's
    plant_data, ident_data = robot.create_data(), robot.create_data()
    plant, ident = interleave(plant_calls(robot, m1, heavy, plant_data),
                              regressor_calls(robot, m2, ident_data, 1))
    other, third = stewart_factory(), stewart_factory()
    assert_same(plant, list(plant_calls(other, m1, heavy, other.create_data())))
    assert_same(ident, list(regressor_calls(third, m2, third.create_data(), 1)))
    # the plant's forces are those of the parameters it was given, not the file's: its bias is
    # the regressor's force at zero acceleration with them, friction left out
    Y, _ = third.identification_regressor(m1[0][:1], m1[1][:1], np.zeros((1, m1[0].shape[1])), None)
    pi = heavy.copy()
    pi[[i for i, name in enumerate(robot.parameter_names) if "." not in name and not name.startswith("Jm_")]] = 0
    bias = Y[0] @ pi
    np.testing.assert_allclose(plant[0][1], bias, rtol=0, atol=1e-9 * np.abs(bias).max())
    assert np.abs(plant[0][1] - Y[0] @ robot.nominal_parameters()).max() > 0.1 * np.abs(bias).max()


def test_threads_with_their_own_data_give_the_sequential_answer(stewart_factory):
    robot = stewart_factory()
    motions = [motion(robot, 0.4 * k) for k in range(4)]
    reference = []
    for m in motions:
        fresh = stewart_factory()
        reference.append(list(regressor_calls(fresh, m, fresh.create_data(), 5)))
    results: list = [None] * len(motions)
    start = threading.Barrier(len(motions))

    def work(k):
        data = robot.create_data()
        start.wait()
        results[k] = list(regressor_calls(robot, motions[k], data, 5))

    threads = [threading.Thread(target=work, args=(k,)) for k in range(len(motions))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for got, want in zip(results, reference, strict=True):
        assert_same(got, want)


def test_no_call_changes_the_robot(stewart_factory):
    robot = stewart_factory()
    tree_ints, tree_floats = robot.tree.ints.copy(), robot.tree.floats.copy()
    nominal = robot.nominal_parameters()
    m = motion(robot, 0.7, samples=40)
    odd = nominal * np.linspace(0.3, 3.0, len(nominal))        # far from the file's parameters
    data = robot.create_data()
    for d in (None, data):
        robot.identification_regressor(*m, None, data=d)
        robot.pose_series(m[0], None, data=d)
        robot.energy_regressor(m[0], m[1], data=d)
        list(plant_calls(robot, m, odd, d))
        robot.tree_motion(m[0][3], m[1][3], m[2][3], data=d)
        robot.condition(m[0][5], data=d)
    robot.with_payload(odd, 2.0, 0.1)
    robot.with_friction(robot.friction).identification_regressor(*m, None)
    robot.readable_base()
    fresh, _, _ = pin.buildModelAndConstraintsFromMJCF(str(robot.path))
    assert robot.model.njoints == fresh.njoints
    for j in range(1, fresh.njoints):
        np.testing.assert_array_equal(robot.model.inertias[j].toDynamicParameters(),
                                      fresh.inertias[j].toDynamicParameters())
    np.testing.assert_array_equal(robot.nominal_parameters(), nominal)
    np.testing.assert_array_equal(robot.tree.ints, tree_ints)
    np.testing.assert_array_equal(robot.tree.floats, tree_floats)
    assert not robot.tree.floats.flags.writeable and not robot.tree.ints.flags.writeable


def test_plant_keeps_its_own_data(stewart_factory):
    """The simulated plant's periods write its own data, not the robot's: an identification
    on the same robot through the robot's own data is unchanged by a plant beside it."""
    from drivers.sim.plant import Plant

    robot = stewart_factory()
    m = motion(robot, 0.2, samples=30)
    before = [x.copy() for x in (robot.data.motion.floats, robot.data.plant.floats)]
    plant = Plant(robot, robot.nominal_parameters())
    n = len(robot.actuator_names)
    demand = np.stack([robot.home_actuated() + 0.002, np.zeros(n)])
    for _ in range(20):
        plant.step(0.004, demand, np.ones(n, dtype=bool), np.full(n, 1e4))
    np.testing.assert_array_equal(robot.data.motion.floats, before[0])
    np.testing.assert_array_equal(robot.data.plant.floats, before[1])
    assert plant._data is not None and plant._data is not robot.data
    assert plant._data.plant.last_valid
    Y, _ = robot.identification_regressor(*m, None)
    other = stewart_factory()
    np.testing.assert_array_equal(Y, other.identification_regressor(*m, None)[0])
