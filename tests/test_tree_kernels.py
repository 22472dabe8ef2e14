"""The compiled model of a described robot (:mod:`ident_hw.model.tree_kernels`) held to pinocchio.

On random assembled states of every shipped description file (the 3PRRR, the Delta, the Stewart
platform, the 2R arm), of a planar five-bar written here and of the UR10e's URDF (where its
dataset is at hand), the compiled closure layer and dynamics give what pinocchio's own
algorithms give at the same tree configuration (:mod:`described_reference`: frame Jacobians,
classical accelerations, ``computeJointTorqueRegressor``, ``crba``, ``rnea``, an SVD
pseudo-inverse) to 1e-12 of each quantity's magnitude; the configuration closes the loops (by
pinocchio's placements) to the Newton tolerance. Along a smooth motion each sample's Newton
starts from the previous sample's state, and the answers do not depend on it.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import described_hand as dh
import described_reference as ref
from ident_hw.model.described import DescribedRobot, random_states

#: configs/robots/delta.xml has the hand model's massless elbows and wrists (the described Delta is held
#: equal to it), which the description loader warns of (MasslessBodyWarning, what MuJoCo refuses)
pytestmark = pytest.mark.filterwarnings(r"ignore:.*delta\.xml. moving bodies without mass")

ROBOTS = Path(__file__).resolve().parents[1] / "configs" / "robots"
REL = 1e-12

FIVE_BAR = """<mujoco model="five-bar">
  <option gravity="{gravity}"/>
  <worldbody>
    <body name="base">
      <body name="prox1" pos="-0.1 0 0">
        <joint name="a1" type="hinge" axis="0 0 1"/>
        <inertial pos="0.1 0.01 0" mass="0.5" fullinertia="1e-4 2.1e-3 2.2e-3 1e-5 2e-5 -3e-5"/>
        <body name="dist1" pos="0.2 0 0">
          <joint name="p1" type="hinge" axis="0 0 1"/>
          <inertial pos="0.125 0 0.005" mass="0.4" diaginertia="1e-4 2e-3 2e-3"/>
          <site name="tip1" pos="0.25 0 0"/>
        </body>
      </body>
      <body name="prox2" pos="0.1 0 0">
        <joint name="a2" type="hinge" axis="0 0 1"/>
        <inertial pos="0.1 0 0" mass="0.55" diaginertia="1.1e-4 2e-3 2.1e-3"/>
        <body name="dist2" pos="0.2 0 0">
          <joint name="p2" type="hinge" axis="0 0 1"/>
          <inertial pos="0.12 -0.01 0" mass="0.35" diaginertia="1e-4 1.8e-3 1.9e-3"/>
          <site name="tip2" pos="0.25 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
  <equality>
    <connect site1="tip1" site2="tip2"/>
  </equality>
</mujoco>
"""
FIVE_BAR_HOME = {"a1": 1.8, "p1": -0.8504, "a2": np.pi - 1.8, "p2": 0.8504}


def five_bar(tmp_path: Path, gravity: str = "0 0 -9.81") -> DescribedRobot:
    """A planar five-bar (two actuated hinges on the base, the loop closed by a point joint)."""
    path = tmp_path / "five_bar.xml"
    path.write_text(FIVE_BAR.format(gravity=gravity))
    return DescribedRobot(path, ("a1", "a2"), home=FIVE_BAR_HOME)


def _prrr() -> DescribedRobot:
    hand = _hand("robot-3prrr")
    X0 = np.zeros((1, 3))
    theta, beta = hand.inverse_kinematics(X0, X0)
    home = dict(zip(dh.PRRR_JOINTS, dh.prrr_tree(X0, theta, beta, X0)[0]))
    return DescribedRobot(dh.PRRR_XML, ("theta1", "theta2", "theta3", "zeta1", "zeta2", "zeta3"), home=home)


def _delta() -> DescribedRobot:
    q0 = np.zeros((1, 3))
    home = dict(zip(dh.DELTA_JOINTS, dh.delta_tree_motion(_hand("robot-delta"), q0, q0, q0)[0][0]))
    return DescribedRobot(dh.DELTA_XML, ("q1", "q2", "q3"), home=home)


def _hand(name: str):
    from ident_hw.config import load_config
    from ident_hw.config.robots import model_of
    return model_of(load_config(Path(__file__).resolve().parents[1] / "configs" / f"{name}.yaml").robot)


def _from_config(name: str) -> DescribedRobot:
    from ident_hw.config import load_config
    from ident_hw.config.robots import model_of
    return model_of(load_config(Path(__file__).resolve().parents[1] / "configs" / f"{name}.yaml").robot)


def _ur10e() -> DescribedRobot:
    if not os.environ.get("IDENT_HW_DATASETS"):
        pytest.skip("IDENT_HW_DATASETS is not set (the UR10e's URDF)")
    return _from_config("ur10e")


ROBOT_MAKERS = {"3prrr": _prrr, "delta": _delta, "stewart": lambda: _from_config("robot-stewart"),
                "2r": lambda: _from_config("robot-2r"), "ur10e": _ur10e}


def _close(actual, expected, what: str) -> None:
    scale = max(1.0, float(np.max(np.abs(expected)))) if np.size(expected) else 1.0
    err = float(np.max(np.abs(np.asarray(actual) - expected))) if np.size(expected) else 0.0
    assert err <= REL * scale, f"{what}: off by {err:.3g} of a magnitude {scale:.3g}"


def _check_against_pinocchio(robot: DescribedRobot, samples: int = 12, seed: int = 3) -> None:
    Theta, Thetad, Thetadd = random_states(robot, samples, seed=seed)
    home = np.tile(robot.pose(robot.home_actuated(), None), (samples, 1))    # each state from home
    Y, poses = robot.identification_regressor(Theta, Thetad, Thetadd, home)
    rng = np.random.default_rng(seed)
    params = robot.nominal_parameters() * rng.uniform(0.5, 1.5, len(robot.parameter_names))
    n = len(robot.actuator_names)
    for k, q in enumerate(poses):
        J, r = ref.closure(robot, q)
        assert np.max(np.abs(r), initial=0.0) <= max(robot.tolerance, 1e-12), f"sample {k}: loops open by {r}"
        _close(q[robot.actuated_q], Theta[k], "actuated coordinates")
        tree = robot.tree_motion(Theta[k], Thetad[k], Thetadd[k], q)
        v, a, W = ref.motion(robot, tree.q, Thetad[k], Thetadd[k])
        _close(tree.W, W, f"sample {k}: W")
        _close(tree.v, v, f"sample {k}: v")
        _close(tree.a, a, f"sample {k}: a")
        _close(Y[k, :, :robot._n_body], ref.regressor_rows(robot, q, Thetad[k], Thetadd[k]), f"sample {k}: W^T Y")
        Jk, rk = robot.closure_jacobian(q)
        _close(Jk, J, f"sample {k}: closure Jacobian")
        _close(rk, r, f"sample {k}: closure residual")
        state = robot.plant_dynamics(Theta[k], Thetad[k], params, q)
        M_ref, bias_ref = ref.plant_dynamics(robot, state.pose, Thetad[k], params)
        _close(state.M, M_ref, f"sample {k}: M")
        _close(state.bias, bias_ref, f"sample {k}: bias")
        assert state.M.shape == (n, n)


@pytest.mark.parametrize("name", sorted(ROBOT_MAKERS))
def test_compiled_model_is_pinocchio_on_random_states(name):
    _check_against_pinocchio(ROBOT_MAKERS[name]())


def test_five_bar_is_pinocchio_on_random_states(tmp_path):
    robot = five_bar(tmp_path)
    assert len(robot.closures) == 1 and robot.tree.pas.size == 2      # 3 rows of rank 2: least squares
    _check_against_pinocchio(robot, samples=20)


def test_newton_continues_from_the_previous_sample():
    """Along a smooth motion (250 Hz), each sample from the last one's state, gives what each
    sample solved alone from home gives (the same assembly, to the tolerance)."""
    robot = _from_config("robot-stewart")
    t = np.arange(200)[:, None] / 250.0
    Theta = robot.home_actuated() + 0.03 * np.sin(2 * np.pi * np.linspace(0.3, 0.9, 6) * t)
    series = robot.pose_series(Theta, None)
    alone = np.stack([DescribedRobot.tree_configuration(robot, row) for row in Theta[::20]])
    np.testing.assert_allclose(series[::20], alone, atol=1e-10)
    for k in range(0, 200, 20):
        assert np.max(np.abs(ref.closure(robot, series[k])[1])) <= 1e-12


# ---------------------------------------------------------------- gravity from <option gravity>
def test_gravity_comes_from_the_file(tmp_path):
    """``<option gravity>`` along -y, in the five-bar's plane (pinocchio's reader ignores it): the
    forces at rest are the gradient of the potential energy ``-M g . c`` (pinocchio's centre of
    mass of each assembled configuration, by central differences along the actuated coordinates);
    with gravity along -z, normal to the plane, there are none."""
    import pinocchio as pin

    robot = five_bar(tmp_path, gravity="0 -9.81 0")
    np.testing.assert_array_equal(robot.model.gravity.linear, [0.0, -9.81, 0.0])
    Theta = robot.home_actuated() + np.array([0.1, -0.05])
    zero = np.zeros((1, 2))
    Y, _ = robot.identification_regressor(Theta[None], zero, zero, None)
    tau = Y[0] @ robot.nominal_parameters()

    def potential(Th) -> float:
        q = robot.pose(Th, None)
        data = robot.model.createData()
        com = pin.centerOfMass(robot.model, data, q)
        return -data.mass[0] * np.dot([0.0, -9.81, 0.0], com)

    h = 1e-6
    grad = [(potential(Theta + h * e) - potential(Theta - h * e)) / (2 * h) for e in np.eye(2)]
    np.testing.assert_allclose(tau, grad, rtol=1e-6, atol=1e-9)
    assert np.abs(tau).max() > 0.1
    flat = five_bar(tmp_path, gravity="0 0 -9.81")
    Y, _ = flat.identification_regressor(Theta[None], zero, zero, None)
    assert np.abs(Y[0] @ flat.nominal_parameters()).max() < 1e-12


def test_a_bad_gravity_is_refused_naming_the_file(tmp_path):
    from ident_hw.model.described import DescriptionError
    with pytest.raises(DescriptionError, match=r"five_bar\.xml: <option gravity='0 -9\.81'>: expected three numbers"):
        five_bar(tmp_path, gravity="0 -9.81")


def test_a_moving_body_without_mass_is_named(tmp_path):
    from ident_hw.model.described import MasslessBodyWarning
    path = tmp_path / "five_bar.xml"
    path.write_text(FIVE_BAR.format(gravity="0 0 -9.81").replace(
        '<inertial pos="0.12 -0.01 0" mass="0.35" diaginertia="1e-4 1.8e-3 1.9e-3"/>', ""))
    with pytest.warns(MasslessBodyWarning, match=r"five_bar\.xml: moving bodies without mass: dist2 \(MuJoCo refuses"):
        robot = DescribedRobot(path, ("a1", "a2"), home=FIVE_BAR_HOME)
    assert robot.massless_bodies == ("dist2",)


def test_the_stewart_file_loads_in_mujoco():
    """Its crosses and ball-joint bodies have masses: MuJoCo loads it, and no body is massless."""
    mujoco = pytest.importorskip("mujoco")
    mujoco.MjModel.from_xml_path(str(ROBOTS / "stewart.xml"))
    assert _from_config("robot-stewart").massless_bodies == ()


# ---------------------------------------------------------------- J_p factored loop by loop
def _solve(plan, J, pas, b):
    """``J_p``'s factors by ``plan``, its least-squares solution of ``b`` and ``cond_1(R)``."""
    from ident_hw.model.tree_kernels import _factor, _qr_solve, _r_condition
    m, p = J.shape[0], len(pas)
    QR, tau, x = np.empty((m, p)), np.empty(p), np.empty(p)
    assert _factor(plan, pas, J, QR, tau)
    _qr_solve(plan, QR, tau, b.copy(), x)
    return x, _r_condition(plan, QR, np.empty((p, p)))


@pytest.mark.parametrize("name", ["3prrr", "delta", "stewart"])
def test_loop_by_loop_factorisation_is_the_dense_one(name):
    """The elimination plan found from the tree (each loop's own passive joints on its own rows,
    then the joints several loops share: the Delta's limbs 2 and 3, the Stewart's legs) solves
    ``J_p x = b`` as the dense Householder QR does and as numpy's least squares does, to 1e-12,
    at random states, with right-hand sides the closures cannot meet too (least squares where
    rows are redundant, as the 3PRRR's planar loops in 3-D); its ``cond_1(R)`` is within a
    factor ``p`` of ``cond_2(J_p)`` as the dense one's is."""
    from ident_hw.model.tree_kernels import dense_plan
    robot = ROBOT_MAKERS[name]()
    tree = robot.tree.views()
    m, p = robot.tree.rows, len(tree.pas)
    dense = dense_plan(m, p)
    widest = max(tree.plan[2 + 2 * p + k] - tree.plan[1 + 2 * p + k] for k in range(p))
    assert widest < m, f"{name}: every step works on all {m} rows (the dense factorisation)"
    rng = np.random.default_rng(7)
    data = robot.create_data()
    for Theta in random_states(robot, 6, seed=7)[0]:
        J, _ = robot.closure_jacobian(robot.pose(Theta, None, data=data))
        Jp = J[:, tree.pas]
        cond2 = np.linalg.cond(Jp)
        for b in (Jp @ rng.normal(size=p), rng.normal(size=m)):
            x, cond = _solve(tree.plan, J, tree.pas, b)
            x_dense, cond_dense = _solve(dense, J, tree.pas, b)
            x_ref = np.linalg.lstsq(Jp, b, rcond=None)[0]
            _close(x, x_dense, f"{name}: loop by loop against dense")
            _close(x, x_ref, f"{name}: loop by loop against numpy's least squares")
            for c in (cond, cond_dense):
                assert cond2 / p <= c <= p * cond2, f"{name}: cond_1(R) {c:.3g} against cond_2(J_p) {cond2:.3g}"


def test_one_loop_is_factored_densely(tmp_path):
    """A single loop (the five-bar) has nothing to split: its plan is the dense Householder QR,
    step for step (the same operations in the same order as before plans existed)."""
    from ident_hw.model.tree_kernels import dense_plan
    robot = five_bar(tmp_path)
    np.testing.assert_array_equal(robot.tree.views().plan, dense_plan(robot.tree.rows, robot.tree.pas.size))


def test_the_delta_is_factored_limb_by_limb():
    """The Delta's 12 x 12 ``J_p``: limb 2's four passive joints on closure 1's six rows, limb 3's
    on closure 2's, then limb 1's four (which carry the platform, seen by both) on the four rows
    left: the structure is found from the tree, not written for the Delta."""
    robot = _delta()
    tree = robot.tree.views()
    plan, p = tree.plan, 12
    names = [robot.joint_names[tree.pas[plan[1 + k]]] for k in range(p)]
    rows = [plan[plan[1 + 2 * p + k]:plan[2 + 2 * p + k]].tolist() for k in range(p)]
    assert "".join(name[-3] for name in names) == "222233331111", names        # elbow<i>_y, wrist<i>_n...
    assert [len(r) for r in rows] == [6, 5, 4, 3, 6, 5, 4, 3, 4, 3, 2, 1]
    assert set(sum(rows[:4], [])) == set(range(6)) and set(sum(rows[4:8], [])) == set(range(6, 12))
