"""The generic model (MJCF + pinocchio) against the two hand-derived models.

``configs/robots/3prrr.xml`` and ``configs/robots/delta.xml`` describe the nominal 3PRRR
(``configs/robot-3prrr.yaml``) and the nominal Delta (``ident_hw.model.delta``); their frames are
chosen so that the tree joint values are the hand models' coordinates (the files' headers).
``tests/described_hand.py`` maps a hand model's parameters to the described vector (the hand
bodies about the described joint frames; bodies the hand model does not have: 0) and turns a hand
pose into the tree configuration. The hand models are the reference throughout.

- the files, with raw pinocchio: at hand poses the closures hold (pinocchio's own constraint
  placements), the end-effector sits at the hand pose, pinocchio's constraint Jacobian has the
  rank that leaves the actuated count of degrees of freedom and annihilates the tree rates the
  hand kinematics give; the tree inertias are the mapped nominal hand bodies; and the virtual work
  of pinocchio's tree inverse dynamics (rnea) along the hand's tree rates is the hand model's
  actuator force, random parameters;
- :class:`~ident_hw.model.described.DescribedRobot` on these files: names and nominal vector; its
  forward kinematics (Newton on the closures) gives the hand pose; ``Y pi`` is the hand's
  ``Y pi`` (friction and rotor inertia included) on random states and random parameters; its
  ``plant_dynamics`` gives the hand's actuated mass matrix and bias forces; its
  ``energy_regressor`` gives the hand's energy (3PRRR: the hand's kinetic-energy regressor;
  Delta: kinetic plus potential energy summed here over the hand model's body motions).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import described_hand as dh
import nominal
from ident_hw.model import Delta, ThreePRRR
from ident_hw.model.delta import BODY_PARAMS as DELTA_BODY_PARAMS
from ident_hw.model.delta import DeltaGeometry, physical_parameters
from ident_hw.model.kinematics import wrap
from ident_hw.model.parameters import ACTUATOR_NAMES as PRRR_ACTUATORS
from ident_hw.model.parameters import InertialParams

#: the shipped files load without a MasslessBodyWarning (every moving body has mass: MuJoCo loads them)
pytestmark = pytest.mark.filterwarnings("error::ident_hw.model.described.MasslessBodyWarning")

N = 16          # random states per test
TOL = 1e-9      # relative agreement with the hand models
POSE_TOL = 1e-9  # rad, m: Newton stops at a closure residual of 1e-12 (configurations good to ~1e-11)


# ----------------------------------------------------------------------------- hand models
@pytest.fixture(scope="module")
def prrr():
    """The nominal hand 3PRRR (``tests/nominal.py``, written independently of the file):
    ``(model, geometry, cad params)``."""
    return ThreePRRR(nominal.GEOMETRY, coulomb_width=1e-3), nominal.GEOMETRY, nominal.CAD_PARAMS


@pytest.fixture(scope="module")
def delta():
    return Delta(DeltaGeometry(), coulomb_width=0.01)


def random_prrr_params(rng, geometry) -> InertialParams:
    """Physically plausible hand parameters: positive masses, slender-rod-like inertias, friction."""
    m_l1, m_l2, m_ee = rng.uniform(0.1, 1.0, 3)
    return InertialParams(
        m_c=rng.uniform(5.0, 800.0),
        m_l1=m_l1, I_l1=m_l1 * geometry.l1**2 / 12 * rng.uniform(0.5, 1.5),
        m_l2=m_l2, I_l2=m_l2 * geometry.l2**2 / 12 * rng.uniform(0.5, 1.5),
        m_ee=m_ee, I_ee=m_ee * geometry.h**2 / 2 * rng.uniform(0.5, 1.5),
        f_v=tuple(rng.uniform(0.05, 2.0, 3)) + tuple(rng.uniform(10.0, 200.0, 3)),
        f_c=tuple(rng.uniform(0.05, 1.0, 3)) + tuple(rng.uniform(2.0, 50.0, 3)))


def random_body(rng, mass_range, com_centre, com_spread, size):
    """10 hand-order parameters ``[m, mx, my, mz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` about the body
    origin of a physical body: principal moments from a positive mass distribution (triangle
    inequality holds), random principal axes, centre of mass in a box."""
    m = rng.uniform(*mass_range)
    c = np.asarray(com_centre) + com_spread * rng.uniform(-1, 1, 3)
    spread = m * (size * rng.uniform(0.1, 1.0, 3)) ** 2          # second moments along principal axes
    principal = np.array([spread[1] + spread[2], spread[0] + spread[2], spread[0] + spread[1]])
    Rq, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    I = Rq @ np.diag(principal) @ Rq.T + m * (c @ c * np.eye(3) - np.outer(c, c))
    return np.concatenate([[m], m * c, I[[0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]])


def random_delta_params(rng, geometry) -> np.ndarray:
    """(79,) physically plausible hand parameters with drive terms."""
    arms = [random_body(rng, (0.3, 1.5), (geometry.L1 / 2, 0, 0), 0.03, geometry.L1 / 3) for _ in range(3)]
    rods = [random_body(rng, (0.5, 2.5), (geometry.L2 / 2, 0, 0), 0.05, geometry.L2 / 3) for _ in range(3)]
    plat = random_body(rng, (0.2, 1.5), (0, 0, 0), 0.02, geometry.r)
    drives = np.concatenate([rng.uniform(0.05, 1.0, 3), rng.uniform(0.05, 0.5, 3), rng.uniform(0.001, 0.02, 3)])
    return np.concatenate([*arms, *rods, plat, drives])


def prrr_states(hand: ThreePRRR, rng, n=N):
    """Random actuated states near home: ``Theta``, ``Thetad``, ``Thetadd`` (n, 6) and the hand motion."""
    Theta = hand.home_actuated() + np.concatenate([rng.uniform(-0.05, 0.05, (n, 3)),
                                                   rng.uniform(-0.03, 0.03, (n, 3))], axis=1)
    Thetad = np.concatenate([rng.normal(0, 0.5, (n, 3)), rng.normal(0, 0.05, (n, 3))], axis=1)
    Thetadd = np.concatenate([rng.normal(0, 5.0, (n, 3)), rng.normal(0, 0.5, (n, 3))], axis=1)
    motion = hand.motion_from_actuated(Theta, Thetad, Thetadd, np.zeros((n, 3)))
    return Theta, Thetad, Thetadd, motion


def delta_states(rng, n=N):
    return rng.uniform(-0.4, 0.4, (n, 3)), rng.normal(0, 1.5, (n, 3)), rng.normal(0, 10.0, (n, 3))


def per_actuator_error(value, reference) -> np.ndarray:
    """(n,) ``max |value - reference|`` over the samples, relative to each actuator's ``max |reference|``."""
    return np.abs(value - reference).max(axis=0) / np.abs(reference).max(axis=0)


def mass_matrix_error(M, M_ref) -> float:
    """Largest ``|M_ij - M_ref_ij| / sqrt(M_ref_ii M_ref_jj)`` (unit-free for mixed kinds of joints)."""
    d = np.sqrt(np.einsum("...ii->...i", M_ref))
    return float(np.max(np.abs(M - M_ref) / (d[..., :, None] * d[..., None, :])))


# ----------------------------------------------------------------------------- raw pinocchio helpers
def load(path):
    model, points, frames = pin.buildModelAndConstraintsFromMJCF(str(path))
    return model, model.createData(), list(points), list(frames)


def closure_residual(model, data, q, points, frames) -> float:
    """Largest mismatch (m, rad) of pinocchio's constraint placements at ``q``."""
    pin.forwardKinematics(model, data, q)
    out = [0.0]
    for c, rigid in [(c, False) for c in points] + [(c, True) for c in frames]:
        a, b = data.oMi[c.joint1_id] * c.joint1_placement, data.oMi[c.joint2_id] * c.joint2_placement
        out.append(np.abs(pin.log6(a.inverse() * b).vector if rigid else a.translation - b.translation).max())
    return max(out)


def constraint_jacobian(model, data, q, points, frames) -> np.ndarray:
    """pinocchio's constraint Jacobian (rows, nv) of the file's closures at ``q``."""
    models = pin.StdVec_ConstraintModel()
    for c in points + frames:
        models.append(pin.ConstraintModel(c))
    datas = pin.StdVec_ConstraintData()
    for c in models:
        datas.append(c.createData())
    pin.computeJointJacobians(model, data, q)
    for c, d in zip(models, datas):
        c.calc(model, data, d)
    return pin.getConstraintsJacobian(model, data, models, datas)


def set_inertias(model, bodies: dict, names) -> None:
    for j, name in enumerate(names, start=1):
        model.inertias[j] = pin.Inertia.FromDynamicParameters(bodies.get(name, np.zeros(10)))


def check_joint_names(model, joints):
    assert tuple(model.names[j] for j in range(1, model.njoints)) == joints
    assert model.nq == model.nv == len(joints)


# ----------------------------------------------------------------------------- 3PRRR file
def prrr_velocity_map(hand: ThreePRRR, Theta, X) -> np.ndarray:
    """``S`` (10, 6): tree rates per unit actuated rate, from the hand kinematics."""
    zero = np.zeros((1, 6))
    cols = []
    for j in range(6):
        m = hand.motion_from_actuated(Theta[None], np.eye(6)[j:j + 1], zero, X[None])
        cols.append(dh.prrr_tree_motion(m)[1][0])
    return np.stack(cols, axis=1)


def test_3prrr_file_closes_on_hand_poses(prrr):
    hand, geometry, _ = prrr
    model, data, points, frames = load(dh.PRRR_XML)
    check_joint_names(model, dh.PRRR_JOINTS)
    assert (len(points), len(frames)) == (2, 0)
    rng = np.random.default_rng(1)
    Theta, _, _, motion = prrr_states(hand, rng)
    Q = dh.prrr_tree(motion.X, motion.theta, motion.beta, motion.zeta)
    ee = model.getFrameId(dh.PRRR_EE_SITE)
    for k in range(N):
        assert closure_residual(model, data, Q[k], points, frames) < 1e-12
        pin.framesForwardKinematics(model, data, Q[k])
        place = data.oMf[ee]
        np.testing.assert_allclose(place.translation, [*motion.X[k, :2], 0.0], rtol=0, atol=1e-12)
        yaw = np.arctan2(place.rotation[1, 0], place.rotation[0, 0])
        assert abs(wrap(yaw - motion.X[k, 2])) < 1e-12
        np.testing.assert_allclose(place.rotation[2], [0, 0, 1], atol=1e-15)
    # two point closures in the plane: 6 rows, 4 independent (the z rows vanish): 10 - 4 = 6 dofs
    G = constraint_jacobian(model, data, Q[0], points, frames)
    assert G.shape == (6, 10)
    s = np.linalg.svd(G, compute_uv=False)
    assert np.sum(s > 1e-9 * s[0]) == 4 and model.nv - 4 == 6
    S = prrr_velocity_map(hand, Theta[0], motion.X[0])
    assert np.abs(G @ S).max() < 1e-12 * np.abs(S).max()
    assert np.linalg.matrix_rank(S) == 6


def prrr_file_bodies(cad, geometry) -> dict[str, np.ndarray]:
    """The bodies of 3prrr.xml: the hand CAD values, plus what the planar motion never moves and a
    physical body has (the header's choice): the carriages' rotational inertia (a 0.1 m cube of
    780 kg: m a^2 / 6), the links' axial inertia (rods of radius 1 cm: m r^2 / 2), the end-effector
    disc's thickness (1 cm: m t^2 / 12 about x and y)."""
    bodies = dh.prrr_bodies(cad, geometry)
    bodies["ee"] = bodies["ee"] + dh.pin_body(0.0, np.zeros(3), np.diag([1.0, 1.0, 0.0]) * cad.m_ee * 0.01**2 / 12)
    for i in (1, 2, 3):
        bodies[f"carriage{i}"] = bodies[f"carriage{i}"] + dh.pin_body(0.0, np.zeros(3), 780 * 0.1**2 / 6 * np.eye(3))
        for link, mass in (("link1", cad.m_l1), ("link2", cad.m_l2)):
            bodies[f"{link}_{i}"] = bodies[f"{link}_{i}"] + dh.pin_body(0.0, np.zeros(3), np.diag([mass * 0.01**2 / 2, 0, 0]))
    return bodies


def test_3prrr_file_inertias_are_the_cad_values(prrr):
    _, geometry, cad = prrr
    model, _, _, _ = load(dh.PRRR_XML)
    bodies = prrr_file_bodies(cad, geometry)
    for j, name in enumerate(dh.PRRR_BODIES, start=1):
        np.testing.assert_allclose(model.inertias[j].toDynamicParameters(), bodies[name], rtol=0, atol=1e-12,
                                   err_msg=name)


def test_3prrr_file_virtual_work_of_rnea_is_the_hand_inverse_dynamics(prrr):
    hand, geometry, _ = prrr
    model, data, _, _ = load(dh.PRRR_XML)
    rng = np.random.default_rng(2)
    Theta, Thetad, Thetadd, motion = prrr_states(hand, rng)
    Q, V, A = dh.prrr_tree_motion(motion)
    worst = 0.0
    for trial in range(3):
        params = random_prrr_params(rng, geometry)
        set_inertias(model, dh.prrr_bodies(params, geometry), dh.PRRR_BODIES)
        # the hand's Lagrange-multiplier route (eqs. 31-35), friction taken off
        tau_hand = hand.inverse_dynamics(motion.X, motion.Xd, motion.Xdd, motion.zeta, motion.zetad,
                                         motion.zetadd, params) - hand.friction(Thetad, params)
        tau = np.stack([prrr_velocity_map(hand, Theta[k], motion.X[k]).T @ pin.rnea(model, data, Q[k], V[k], A[k])
                        for k in range(N)])
        worst = max(worst, per_actuator_error(tau, tau_hand).max())
    assert worst < TOL


# ----------------------------------------------------------------------------- Delta file
def delta_velocity_map(hand: Delta, q) -> np.ndarray:
    """``S`` (15, 3): tree rates per unit arm rate, from the hand kinematics."""
    zero = np.zeros((1, 3))
    return np.stack([dh.delta_tree_motion(hand, q[None], np.eye(3)[j:j + 1], zero)[1][0] for j in range(3)], axis=1)


def test_delta_file_closes_on_hand_poses(delta):
    model, data, points, frames = load(dh.DELTA_XML)
    check_joint_names(model, dh.DELTA_JOINTS)
    assert (len(points), len(frames)) == (0, 2)
    rng = np.random.default_rng(3)
    q, qd, qdd = delta_states(rng)
    Q, _, _ = dh.delta_tree_motion(delta, q, qd, qdd)
    p = delta.fk(q)
    centre = model.getFrameId(dh.DELTA_CENTRE_SITE)
    for k in range(N):
        assert closure_residual(model, data, Q[k], points, frames) < 1e-12
        pin.framesForwardKinematics(model, data, Q[k])
        np.testing.assert_allclose(data.oMf[centre].translation, p[k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(data.oMf[centre].rotation, np.eye(3), rtol=0, atol=1e-12)
    # 15 tree joints, two welds of 6 independent rows: 3 degrees of freedom
    G = constraint_jacobian(model, data, Q[0], points, frames)
    assert G.shape == (12, 15)
    s = np.linalg.svd(G, compute_uv=False)
    assert s[-1] > 1e-3 * s[0] and model.nv - len(s) == 3
    S = delta_velocity_map(delta, q[0])
    assert np.abs(G @ S).max() < 1e-12 * np.abs(S).max()


def lumped_delta_file(model, geometry) -> dict[str, np.ndarray]:
    """The bodies of delta.xml (raw pinocchio, joint frames) with its crosses and yokes lumped as
    the hand model (no crosses) has them, written here from the header: an elbow cross's mass a
    point at ``B_i`` on the arm, a wrist cross's a point at ``P_i`` on the platform, each cross's
    inertia about its ``y`` axis on the rod's ``x`` and ``y`` axes, a yoke ``end<i>`` (axes
    ``R_i`` at ``P_i``) moved onto the platform (frame at ``P_1``, world axes)."""
    raw = {name: np.asarray(model.inertias[j].toDynamicParameters()) for j, name in enumerate(dh.DELTA_BODIES, 1)}
    out = {"platform": raw["platform"].copy()}
    e = np.stack([np.cos(geometry.psi), np.sin(geometry.psi), np.zeros(3)], axis=1)
    for i in (1, 2, 3):
        elbow, wrist = raw[f"elbow{i}"], raw[f"wrist{i}"]
        for cross in (elbow, wrist):
            assert cross[0] > 0 and np.allclose(cross[1:4], 0, atol=1e-15)     # a mass, centred on its joint
        out[f"arm{i}"] = raw[f"arm{i}"] + dh.moved(elbow[0], np.zeros(3), np.zeros((3, 3)), np.eye(3),
                                                   (geometry.L1, 0, 0))
        spin = elbow[dh.PIN_PARAMS.index("Iyy")] + wrist[dh.PIN_PARAMS.index("Iyy")]
        out[f"rod{i}"] = raw[f"rod{i}"] + dh.pin_body(0.0, np.zeros(3), np.diag([spin, spin, 0.0]))
        P_i = geometry.r * (e[i - 1] - e[0])
        out["platform"] = out["platform"] + dh.moved(wrist[0], np.zeros(3), np.zeros((3, 3)), np.eye(3), P_i)
        if i > 1:
            end = raw[f"end{i}"]
            R_i = np.array([[np.cos(geometry.psi[i - 1]), -np.sin(geometry.psi[i - 1]), 0],
                            [np.sin(geometry.psi[i - 1]), np.cos(geometry.psi[i - 1]), 0], [0, 0, 1.0]])
            out["platform"] = out["platform"] + dh.moved(end[0], end[1:4], dh.hand_tensor(
                end[[4, 5, 7, 6, 8, 9]]), R_i, P_i)
    return out


def test_delta_file_inertias_are_the_configs_bodies(delta):
    """With its crosses and yokes lumped, delta.xml is the configs' Delta (``physical_parameters``)
    in the file's frames; the platform's inertia, which never acts (it translates), is the file's
    compact body."""
    model, _, _, _ = load(dh.DELTA_XML)
    bodies = dh.delta_bodies(physical_parameters(delta.geometry), delta.geometry)
    lumped = lumped_delta_file(model, delta.geometry)
    for name in ("arm1", "arm2", "arm3", "rod1", "rod2", "rod3"):
        np.testing.assert_allclose(lumped[name], bodies[name], rtol=0, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(lumped["platform"][:4], bodies["platform"][:4], rtol=0, atol=1e-12)
    assert np.linalg.eigvalsh(dh.hand_tensor(lumped["platform"][[4, 5, 7, 6, 8, 9]])).min() > 0


def test_the_shipped_files_load_in_mujoco():
    """MuJoCo loads delta.xml and 3prrr.xml as shipped (no massless moving body, no tensor it refuses)."""
    mj = pytest.importorskip("mujoco")
    for path in (dh.DELTA_XML, dh.PRRR_XML):
        model = mj.MjModel.from_xml_path(str(path))
        assert model.nbody == len(load(path)[0].names) + 1      # the world and the base, every joint's body


def test_delta_file_virtual_work_of_rnea_is_the_hand_inverse_dynamics(delta):
    model, data, _, _ = load(dh.DELTA_XML)
    assert np.allclose(model.gravity.linear, delta.g)
    rng = np.random.default_rng(4)
    q, qd, qdd = delta_states(rng)
    Q, V, A = dh.delta_tree_motion(delta, q, qd, qdd)
    S = [delta_velocity_map(delta, q[k]) for k in range(N)]
    worst = 0.0
    for trial in range(3):
        pi = random_delta_params(rng, delta.geometry)
        pi[70:] = 0.0                                        # rnea has no drive terms
        set_inertias(model, dh.delta_bodies(pi, delta.geometry), dh.DELTA_BODIES)
        tau = np.stack([S[k].T @ pin.rnea(model, data, Q[k], V[k], A[k]) for k in range(N)])
        worst = max(worst, per_actuator_error(tau, delta.inverse_dynamics(q, qd, qdd, pi)).max())
    assert worst < TOL


# ----------------------------------------------------------------------------- DescribedRobot
@pytest.fixture(scope="module")
def described_prrr(prrr):
    from ident_hw.model.described import DescribedRobot

    hand, _, _ = prrr
    X0 = np.zeros((1, 3))
    theta, beta = hand.inverse_kinematics(X0, X0)
    home = dict(zip(dh.PRRR_JOINTS, dh.prrr_tree(X0, theta, beta, X0)[0]))
    return DescribedRobot(dh.PRRR_XML, actuated=PRRR_ACTUATORS, actuator_names=PRRR_ACTUATORS, home=home,
                          coulomb_width=hand.coulomb_width)


@pytest.fixture(scope="module")
def described_delta(delta):
    from ident_hw.model.described import DescribedRobot

    q0 = np.zeros((1, 3))
    home = dict(zip(dh.DELTA_JOINTS, dh.delta_tree_motion(delta, q0, q0, q0)[0][0]))
    return DescribedRobot(dh.DELTA_XML, actuated=("q1", "q2", "q3"), home=home, coulomb_width=delta.coulomb_width)


def check_names(robot, bodies, actuators):
    from ident_hw.model.described import BODY_PARAMS

    assert BODY_PARAMS == dh.PIN_PARAMS
    assert robot.body_names == bodies
    assert robot.actuator_names == actuators
    assert robot.parameter_names == (tuple(f"{b}.{p}" for b in bodies for p in dh.PIN_PARAMS)
                                     + tuple(f"{d}_{a}" for d in ("fv", "fc", "Jm") for a in actuators))


def test_3prrr_described_names_and_nominal_parameters(prrr, described_prrr):
    hand, geometry, cad = prrr
    robot = described_prrr
    check_names(robot, dh.PRRR_BODIES, PRRR_ACTUATORS)
    assert robot.actuator_kinds == hand.actuator_kinds
    assert robot.pose_size == 10
    np.testing.assert_allclose(robot.home_actuated(), hand.home_actuated(), rtol=0, atol=1e-15)
    expected = dh.described_vector(prrr_file_bodies(cad, geometry), dh.prrr_drives(cad), robot.parameter_names)
    np.testing.assert_allclose(robot.nominal_parameters(), expected, rtol=0, atol=1e-12)


def test_3prrr_described_forward_kinematics_is_the_hand_one(prrr, described_prrr):
    hand, _, _ = prrr
    robot = described_prrr
    rng = np.random.default_rng(5)
    Theta, _, _, motion = prrr_states(hand, rng)
    Q_hand = dh.prrr_tree(motion.X, motion.theta, motion.beta, motion.zeta)
    data = robot.model.createData()
    ee = robot.model.getFrameId(dh.PRRR_EE_SITE)
    for k in range(N):
        q = robot.pose(Theta[k], None)                      # Newton from home
        assert np.abs(wrap(q - Q_hand[k])).max() < POSE_TOL
        pin.framesForwardKinematics(robot.model, data, q)
        np.testing.assert_allclose(data.oMf[ee].translation[:2], motion.X[k, :2], rtol=0, atol=POSE_TOL)
        R = data.oMf[ee].rotation
        assert abs(wrap(np.arctan2(R[1, 0], R[0, 0]) - motion.X[k, 2])) < POSE_TOL
    # a continuous series: each Newton from the last configuration
    s = np.linspace(0, 1, 12)[:, None]
    series = robot.home_actuated() + s * (Theta[0] - robot.home_actuated())
    X = hand.forward_kinematics(series, np.zeros(3))
    theta, beta = hand.inverse_kinematics(X, series[:, 3:])
    Q = robot.pose_series(series, robot.pose(robot.home_actuated(), None))
    assert np.abs(wrap(Q - dh.prrr_tree(X, theta, beta, series[:, 3:]))).max() < POSE_TOL


def test_3prrr_described_regressor_is_the_hand_one(prrr, described_prrr):
    hand, geometry, _ = prrr
    robot = described_prrr
    rng = np.random.default_rng(6)
    Theta, Thetad, Thetadd, motion = prrr_states(hand, rng)
    Q_hand = dh.prrr_tree(motion.X, motion.theta, motion.beta, motion.zeta)
    guess = Q_hand + 1e-3 * rng.normal(size=Q_hand.shape)  # Newton has to work
    Y, poses = robot.identification_regressor(Theta, Thetad, Thetadd, guess)
    assert Y.shape == (N, 6, len(robot.parameter_names))
    assert np.abs(wrap(poses - Q_hand)).max() < POSE_TOL
    Y_hand = hand.regressor_of(motion)
    worst = 0.0
    for trial in range(5):
        pi_hand = random_prrr_params(rng, geometry).as_vector()
        pi = dh.prrr_map(pi_hand, geometry, robot.parameter_names)
        worst = max(worst, per_actuator_error(Y @ pi, Y_hand @ pi_hand).max())
    assert worst < TOL
    # the map is linear: every hand column is reproduced (scaled by the CAD-size parameters)
    T = dh.linear_map(lambda v: dh.prrr_map(v, geometry, robot.parameter_names), 19)
    scale = np.abs(random_prrr_params(rng, geometry).as_vector())
    err = np.abs((Y @ T - Y_hand) * scale).max(axis=(0, 2)) / np.abs(Y_hand @ scale).max(axis=0)
    assert err.max() < TOL


def test_3prrr_described_plant_dynamics_is_the_hand_one(prrr, described_prrr):
    hand, geometry, _ = prrr
    robot = described_prrr
    rng = np.random.default_rng(7)
    Theta, Thetad, _, motion = prrr_states(hand, rng, n=8)
    Q_hand = dh.prrr_tree(motion.X, motion.theta, motion.beta, motion.zeta)
    M_err, b_ref, b_out = 0.0, [], []
    for k in range(8):
        params = random_prrr_params(rng, geometry)
        pi = dh.prrr_map(params.as_vector(), geometry, robot.parameter_names)
        state, hand_state = (robot.plant_dynamics(Theta[k], Thetad[k], pi, Q_hand[k]),
                             hand.plant_dynamics(Theta[k], Thetad[k], params, motion.X[k]))
        M, bias, q = state.M, state.bias, state.pose
        M_hand, bias_hand = hand_state.M, hand_state.bias
        assert np.abs(wrap(q - Q_hand[k])).max() < POSE_TOL
        M_err = max(M_err, mass_matrix_error(M, M_hand))
        b_out.append(bias)
        b_ref.append(bias_hand)
    assert M_err < TOL
    assert per_actuator_error(np.array(b_out), np.array(b_ref)).max() < TOL


def test_3prrr_described_energy_is_the_hand_kinetic_energy(prrr, described_prrr):
    hand, geometry, _ = prrr
    robot = described_prrr
    rng = np.random.default_rng(11)
    Theta, Thetad, _, motion = prrr_states(hand, rng)
    Q_hand = dh.prrr_tree(motion.X, motion.theta, motion.beta, motion.zeta)
    H = robot.energy_regressor(Theta, Thetad, Q_hand)
    # the hand's kinetic energy from the centre-of-mass velocities (eqs. 17-20); planar: no potential
    H_hand = hand.energy_regressor(motion.X, motion.Xd, motion.zeta, motion.zetad)
    for trial in range(3):
        pi_hand = random_prrr_params(rng, geometry).as_vector()
        T = H_hand @ pi_hand[:7]
        E = H @ dh.prrr_map(pi_hand, geometry, robot.parameter_names)
        assert np.abs(E - T).max() < TOL * np.abs(T).max()


def test_delta_described_names_and_nominal_parameters(delta, described_delta):
    robot = described_delta
    check_names(robot, dh.DELTA_BODIES, ("q1", "q2", "q3"))
    assert robot.actuator_kinds == delta.actuator_kinds
    assert robot.pose_size == 15
    model, _, _, _ = load(dh.DELTA_XML)
    raw = np.concatenate([model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)])
    np.testing.assert_array_equal(robot.nominal_parameters(), np.concatenate([raw, np.zeros(6), [0.01] * 3]))


def test_delta_described_forward_kinematics_is_the_hand_one(delta, described_delta):
    robot = described_delta
    rng = np.random.default_rng(8)
    q, _, _ = delta_states(rng)
    Q_hand, _, _ = dh.delta_tree_motion(delta, q, q, q)
    p = delta.fk(q)
    data = robot.model.createData()
    centre = robot.model.getFrameId(dh.DELTA_CENTRE_SITE)
    for k in range(N):
        tree = robot.pose(q[k], None)                       # Newton from home
        assert np.abs(wrap(tree - Q_hand[k])).max() < POSE_TOL
        pin.framesForwardKinematics(robot.model, data, tree)
        np.testing.assert_allclose(data.oMf[centre].translation, p[k], rtol=0, atol=POSE_TOL)
        np.testing.assert_allclose(data.oMf[centre].rotation, np.eye(3), rtol=0, atol=POSE_TOL)


def test_delta_described_regressor_is_the_hand_one(delta, described_delta):
    robot = described_delta
    rng = np.random.default_rng(9)
    q, qd, qdd = delta_states(rng)
    Q_hand, _, _ = dh.delta_tree_motion(delta, q, qd, qdd)
    guess = Q_hand + 1e-3 * rng.normal(size=Q_hand.shape)
    Y, poses = robot.identification_regressor(q, qd, qdd, guess)
    assert Y.shape == (N, 3, len(robot.parameter_names))
    assert np.abs(wrap(poses - Q_hand)).max() < POSE_TOL
    Y_hand = delta.regressor(q, qd, qdd)
    worst = 0.0
    for trial in range(5):
        pi_hand = random_delta_params(rng, delta.geometry)
        pi = dh.delta_map(pi_hand, delta.geometry, robot.parameter_names)
        worst = max(worst, per_actuator_error(Y @ pi, Y_hand @ pi_hand).max())
    assert worst < TOL
    T = dh.linear_map(lambda v: dh.delta_map(v, delta.geometry, robot.parameter_names), 79)
    scale = np.abs(random_delta_params(rng, delta.geometry))
    err = np.abs((Y @ T - Y_hand) * scale).max(axis=(0, 2)) / np.abs(Y_hand @ scale).max(axis=0)
    assert err.max() < TOL


def test_delta_described_plant_dynamics_is_the_hand_one(delta, described_delta):
    robot = described_delta
    rng = np.random.default_rng(10)
    q, qd, _ = delta_states(rng, n=8)
    Q_hand, _, _ = dh.delta_tree_motion(delta, q, qd, qd)
    M_err, b_ref, b_out = 0.0, [], []
    for k in range(8):
        pi_hand = random_delta_params(rng, delta.geometry)
        pi = dh.delta_map(pi_hand, delta.geometry, robot.parameter_names)
        state, hand_state = robot.plant_dynamics(q[k], qd[k], pi, Q_hand[k]), delta.plant_dynamics(q[k], qd[k], pi_hand)
        M, bias, tree = state.M, state.bias, state.pose
        M_hand, bias_hand = hand_state.M, hand_state.bias
        assert np.abs(wrap(tree - Q_hand[k])).max() < POSE_TOL
        M_err = max(M_err, mass_matrix_error(M, M_hand))
        b_out.append(bias)
        b_ref.append(bias_hand)
    assert M_err < TOL
    assert per_actuator_error(np.array(b_out), np.array(b_ref)).max() < TOL


def delta_energy(delta: Delta, q, qd, pi) -> np.ndarray:
    """Kinetic plus potential energy (N,) of the hand Delta's seven bodies (origin velocity ``v``,
    ``omega``, axes ``Q`` from :meth:`Delta.bodies`; first moment and inertia about the origin
    turned to world axes) and its rotors ``Jm qd^2 / 2``."""
    bodies = delta.bodies(q, qd, np.zeros_like(qd))
    E = 0.5 * (pi[76:79] * qd**2).sum(axis=1)
    for k in range(7):
        b = dict(zip(DELTA_BODY_PARAMS, pi[10 * k:10 * k + 10]))
        h_body = np.array([b["mx"], b["my"], b["mz"]])
        I_body = dh.hand_tensor([b[p] for p in ("Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")])
        Qk, v, w, o = bodies.Q[k], bodies.v[k], bodies.omega[k], bodies.origin[k]
        h = np.einsum("nij,j->ni", Qk, h_body)
        Iw = np.einsum("nij,jk,nlk,nl->ni", Qk, I_body, Qk, w)
        E += (0.5 * b["m"] * (v * v).sum(1) + (v * np.cross(w, h)).sum(1) + 0.5 * (w * Iw).sum(1)
              - (b["m"] * o + h) @ delta.g)
    return E


def test_delta_described_energy_is_the_hand_bodies_energy(delta, described_delta):
    robot = described_delta
    rng = np.random.default_rng(12)
    q, qd, _ = delta_states(rng)
    Q_hand, _, _ = dh.delta_tree_motion(delta, q, qd, qd)
    H = robot.energy_regressor(q, qd, Q_hand)
    for trial in range(3):
        pi_hand = random_delta_params(rng, delta.geometry)
        E_hand = delta_energy(delta, q, qd, pi_hand)
        E = H @ dh.delta_map(pi_hand, delta.geometry, robot.parameter_names)
        assert np.abs(E - E_hand).max() < TOL * np.abs(E_hand).max()


def test_plant_dynamics_leaves_the_description_nominal(described_delta):
    """The plant's parameters are the caller's: the description's nominal vector stays the file's."""
    robot = described_delta
    before = robot.nominal_parameters()
    robot.plant_dynamics(np.zeros(3), np.zeros(3), 2.0 * before, None)
    np.testing.assert_array_equal(robot.nominal_parameters(), before)


# ----------------------------------------------------------------------------- base parameters
def row_space_rank(*matrices) -> int:
    """Numerical rank of the stacked rows, each row scaled to unit norm."""
    rows = np.vstack(matrices)
    rows = rows[np.linalg.norm(rows, axis=1) > 0]
    return int(np.linalg.matrix_rank(rows / np.linalg.norm(rows, axis=1, keepdims=True), tol=1e-7))


def test_delta_numerical_base_agrees_with_the_spec_s_readable_base(delta, described_delta):
    """On the hand Delta's parameters, the generic model's numerical base parameters are
    functions of the spec's 40 readable ones and determine them: the rows of ``H_gen T`` span
    exactly the rows of ``H_spec`` (``T``: hand parameters to described ones)."""
    from ident_hw.model.delta import closed_form_base

    basis = described_delta.readable_base()
    kept, H_gen = basis.kept, basis.H
    assert H_gen.shape[1] == len(described_delta.parameter_names)
    T = dh.linear_map(lambda v: dh.delta_map(v, delta.geometry, described_delta.parameter_names), 79)
    H_spec = closed_form_base(delta.geometry, drive_terms=True).H
    assert row_space_rank(H_spec) == 40
    assert row_space_rank(H_gen @ T) == 40
    assert row_space_rank(H_spec, H_gen @ T) == 40
    # each kept parameter is the one its row is named after
    names = described_delta.parameter_names
    for name, row in zip(kept, H_gen):
        assert row[names.index(name)] == 1.0


def test_3prrr_numerical_base_agrees_with_the_hand_regressor_s_rank(prrr, described_prrr):
    """The hand 3PRRR has no readable base: its 19 parameters have rank 18 on rich data. On the
    hand's parameters the generic numerical base has the same rank and the same null space."""
    hand, geometry, _ = prrr
    H_gen = described_prrr.readable_base().H
    T = dh.linear_map(lambda v: dh.prrr_map(v, geometry, described_prrr.parameter_names), 19)
    rng = np.random.default_rng(5)
    from ident_hw.model.described import random_states

    Theta, Thetad, Thetadd = random_states(described_prrr, 40, spread=0.05, seed=2)
    X = np.array([hand.pose(t, np.zeros(3)) for t in Theta])
    Y_hand = hand.regressor_from_actuated(Theta, Thetad, Thetadd, X).reshape(-1, 19)
    scale = np.abs(dh.linear_map(lambda v: v, 19) @ random_prrr_params(rng, geometry).as_vector())
    assert np.linalg.matrix_rank(Y_hand * scale, tol=1e-9 * np.abs(Y_hand * scale).max()) == 18
    assert row_space_rank(H_gen @ T) == 18
    null = np.linalg.svd(Y_hand * scale)[2][-1] * scale          # the hand regressor's null direction
    assert np.abs(H_gen @ T @ null).max() < 1e-8 * np.abs(H_gen @ T).max() * np.abs(null).max()
