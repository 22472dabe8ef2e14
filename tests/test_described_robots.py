"""The two example description files, checked by routes independent of the code under test.

``configs/robots/stewart.xml``: the Stewart platform (6-UPS) after the object-oriented-models
paper ("Object-Oriented Models of Parallel Manipulators"), a closed chain in MJCF;
``configs/robots/2r.urdf``: the planar 2R direct-drive arm after the power-model paper ("Dynamic
Identification of Robots with Power Model"), a serial robot in URDF. Their geometry and numbers:
docs/described-robots.md.

- the files themselves (raw pinocchio): the Stewart tree (21 dofs, 5 point closures, 15 rows,
  6 DoF) closes at home, its joints sit where the design puts them, and this file's own inverse
  kinematics gives the home tree configuration 0; the 2R reads as two vertical hinges 0.4 m apart
  and its pinocchio dynamics is the textbook one;
- the Stewart with :class:`~ident_hw.model.described.DescribedRobot`: its forward kinematics (Newton
  on the closures) gives back the platform poses this file's inverse kinematics started from; and
  along a smooth actuated motion the power of ``tau = Y pi`` integrates (Gauss-Legendre) to the
  change of the tree's kinetic plus potential energy (pinocchio's ``computeKineticEnergy``,
  ``computePotentialEnergy``, the tree rates solved here from the closure Jacobian);
- the 2R: ``tau = Y pi`` against the closed-form dynamics of a planar 2R arm, random states and
  random parameters (friction and rotor inertia included).
"""

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ident_hw.model.described import BODY_PARAMS, DescribedRobot

ROBOTS = Path(__file__).resolve().parents[1] / "configs" / "robots"
STEWART = ROBOTS / "stewart.xml"
TWO_R = ROBOTS / "2r.urdf"

# ---------------------------------------------------------------- the Stewart design
D_B, D_P = 0.50, 0.30                          # joint circle diameters (m): base, platform
ALPHA_B, ALPHA_P = np.radians(20), np.radians(30)   # angle between the two joints of a couple
HEIGHT = 0.35                                  # platform centre above the base plane at home (m)
LEGS = tuple(f"leg{i}" for i in range(1, 7))
G = 9.81


def _design():
    """Base joints ``B`` (6, 3) (world), platform joints ``P`` (6, 3) (platform frame, origin at
    its centre), home leg frames ``R`` (6, 3, 3) (z along B_i -> P_i, x horizontal) and home
    leg lengths (6,)."""
    B, P = [], []
    for k in range(3):
        centre = np.radians(120 * k)
        for side in (-1, 1):
            b = centre + side * ALPHA_B / 2
            p = centre + side * (np.radians(60) - ALPHA_P / 2)
            B.append([D_B / 2 * np.cos(b), D_B / 2 * np.sin(b), 0.0])
            P.append([D_P / 2 * np.cos(p), D_P / 2 * np.sin(p), 0.0])
    B, P = np.array(B), np.array(P)
    d = P + [0, 0, HEIGHT] - B
    frames = []
    for di in d:
        z = di / np.linalg.norm(di)
        x = np.cross([0.0, 0.0, 1.0], z)
        x /= np.linalg.norm(x)
        frames.append(np.column_stack([x, np.cross(z, x), z]))
    return B, P, np.array(frames), np.linalg.norm(d, axis=1)


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i] = R[j, j] = c
    R[i, j], R[j, i] = -s, s
    return R


def stewart_ik(model: pin.Model, p, R):
    """Inverse kinematics of the whole tree: the leg lengths ``Theta`` (6,) (0 = home length)
    and the tree configuration ``q`` (nq,) that put the platform centre at ``p`` with
    orientation ``R`` (world; identity at home)."""
    B, P, frames, L0 = _design()
    q = np.zeros(model.nq)

    def put(name, value):
        q[model.joints[model.getJointId(name)].idx_q] = value

    theta = np.zeros(6)
    rod1 = None
    for i in range(6):
        d = p + R @ P[i] - B[i]
        length = np.linalg.norm(d)
        u = frames[i].T @ d / length            # Rx(u1) Ry(u2) e_z = u in the leg frame
        u2 = np.arcsin(u[0])
        u1 = np.arctan2(-u[1], u[2])
        theta[i] = length - L0[i]
        put(f"leg{i + 1}_u1", u1)
        put(f"leg{i + 1}_u2", u2)
        put(f"leg{i + 1}", theta[i])
        if i == 0:
            rod1 = frames[0] @ _rot(0, u1) @ _rot(1, u2)
    # the platform frame has the axes of the leg-1 frame at home: it turns with the platform
    Q = rod1.T @ R @ frames[0]                 # = Rx(sph_x) Ry(sph_y) Rz(sph_z)
    put("sph_y", np.arcsin(Q[0, 2]))
    put("sph_x", np.arctan2(-Q[1, 2], Q[2, 2]))
    put("sph_z", np.arctan2(-Q[0, 1], Q[0, 0]))
    return theta, q


def _closure_residual(model, data, constraints, q) -> np.ndarray:
    """The world position mismatch (15,) of the five connects at ``q`` (own computation)."""
    pin.forwardKinematics(model, data, q)
    return np.concatenate([(data.oMi[c.joint1_id] * c.joint1_placement).translation
                           - (data.oMi[c.joint2_id] * c.joint2_placement).translation for c in constraints])


def _closure_jacobian(model, data, constraints, q) -> np.ndarray:
    """(15, nv): the world velocity mismatch of the five connects."""
    pin.computeJointJacobians(model, data, q)
    return np.vstack([
        pin.getFrameJacobian(model, data, c.joint1_id, c.joint1_placement, pin.LOCAL_WORLD_ALIGNED)[:3]
        - pin.getFrameJacobian(model, data, c.joint2_id, c.joint2_placement, pin.LOCAL_WORLD_ALIGNED)[:3]
        for c in constraints])


def _stewart_tree():
    model, points, frames = pin.buildModelAndConstraintsFromMJCF(str(STEWART))
    assert not frames
    return model, model.createData(), list(points)


def _stewart() -> DescribedRobot:
    return DescribedRobot(STEWART, actuated=LEGS, actuator_names=LEGS, coulomb_width=1e-3)


# a few platform poses (centre, rotation) inside the workspace
POSES = [
    (np.array([0.0, 0.0, HEIGHT]), np.eye(3)),
    (np.array([0.02, -0.015, HEIGHT + 0.03]), _rot(2, 0.1) @ _rot(1, -0.05) @ _rot(0, 0.08)),
    (np.array([-0.03, 0.02, HEIGHT - 0.04]), _rot(2, -0.15) @ _rot(1, 0.07) @ _rot(0, -0.06)),
    (np.array([0.01, 0.04, HEIGHT + 0.05]), _rot(0, 0.12)),
]


def test_stewart_file_is_the_design_and_closes_at_home():
    model, data, constraints = _stewart_tree()
    assert (model.nq, model.nv, model.njoints - 1) == (21, 21, 21)
    assert len(constraints) == 5 and sum(c.residualSize() for c in constraints) == 15
    assert all(model.joints[j].nq == 1 for j in range(1, model.njoints))
    q0 = np.zeros(model.nq)
    assert np.abs(_closure_residual(model, data, constraints, q0)).max() < 1e-10
    J = _closure_jacobian(model, data, constraints, q0)
    assert model.nv - np.linalg.matrix_rank(J) == 6                         # 6 DoF
    act = [model.joints[model.getJointId(leg)].idx_v for leg in LEGS]
    assert np.linalg.cond(np.vstack([J, np.eye(model.nv)[act]])) < 1e3     # legs drive it, far from singular

    # the joints sit where the design puts them, the platform centre at home
    B, P, frames, L0 = _design()
    pin.forwardKinematics(model, data, q0)
    pin.updateFramePlacements(model, data)
    for i, leg in enumerate(LEGS):
        cross = data.oMi[model.getJointId(f"{leg}_u1")]
        assert np.abs(cross.translation - B[i]).max() < 1e-10
        assert np.abs(cross.rotation - frames[i]).max() < 1e-10
        assert np.abs(model.jointPlacements[model.getJointId(leg)].translation).max() == 0.0
    centre = data.oMf[model.getFrameId("platform_centre")]
    assert np.abs(centre.translation - [0, 0, HEIGHT]).max() < 1e-10
    assert np.abs(centre.rotation - np.eye(3)).max() < 1e-10
    assert np.allclose(L0, L0[0]) and abs(L0[0] - 0.3821826744870) < 1e-12
    masses = {model.names[j]: model.inertias[j].mass for j in range(1, model.njoints)}
    assert masses["sph_z"] == 3.0 and all(masses[f"{leg}_u2"] == 1.2 and masses[leg] == 0.6 for leg in LEGS)
    assert all(masses[f"{leg}_u1"] == 0.15 for leg in LEGS) and masses["sph_x"] == masses["sph_y"] == 0.08
    assert sum(masses.values()) == pytest.approx(6 * (1.8 + 0.15) + 3.0 + 2 * 0.08, abs=1e-12)

    # this file's inverse kinematics at home: every joint at 0
    theta, q = stewart_ik(model, *POSES[0])
    assert np.abs(theta).max() < 1e-10 and np.abs(q).max() < 1e-10
    for p, R in POSES[1:]:                       # and the other poses close the loops
        _, q = stewart_ik(model, p, R)
        assert np.abs(_closure_residual(model, data, constraints, q)).max() < 1e-10


def test_stewart_forward_kinematics_gives_back_the_poses():
    robot = _stewart()
    model, data, constraints = _stewart_tree()
    assert robot.pose_size == model.nq == 21
    centre = robot.model.getFrameId("platform_centre")
    worst = {"q": 0.0, "pose": 0.0, "closure": 0.0}
    guess = None
    frames = robot.model.createData()          # pinocchio's data of the robot's tree, the test's own
    for p, R in POSES + POSES[::-1]:
        theta, q_ik = stewart_ik(model, p, R)
        q = robot.tree_configuration(theta, guess)
        guess = q
        pin.forwardKinematics(robot.model, frames, q)
        pin.updateFramePlacements(robot.model, frames)
        M = frames.oMf[centre]
        worst["q"] = max(worst["q"], np.abs(q - q_ik).max())
        worst["pose"] = max(worst["pose"], np.abs(M.translation - p).max(), np.abs(M.rotation - R).max())
        worst["closure"] = max(worst["closure"], np.abs(_closure_residual(model, data, constraints, q)).max())
    assert worst["q"] < 1e-9, worst
    assert worst["pose"] < 1e-10, worst
    assert worst["closure"] < 1e-10, worst


def _smooth_motion(t):
    """Leg extensions (N, 6) and their exact first and second derivatives: sums of sines of
    small amplitude (<= 0.045 m) about home, not periodic over the window."""
    rng = np.random.default_rng(7)
    amp = rng.uniform(0.004, 0.008, (6, 3))
    omega = 2 * np.pi * np.array([0.4, 0.9, 1.7])
    phase = rng.uniform(0, 2 * np.pi, (6, 3))
    offset = rng.uniform(-0.02, 0.02, 6)
    arg = omega[None, None, :] * t[:, None, None] + phase[None]     # (N, 6, 3)
    theta = offset + (amp * np.sin(arg)).sum(-1) + 0.02 * t[:, None] ** 2 / t[-1] ** 2
    thetad = (amp * omega * np.cos(arg)).sum(-1) + 0.04 * t[:, None] / t[-1] ** 2
    thetadd = -(amp * omega**2 * np.sin(arg)).sum(-1) + 0.04 / t[-1] ** 2
    return theta, thetad, np.broadcast_to(thetadd, theta.shape).copy()


def _gauss_grid(T: float, panels: int, order: int):
    """Composite Gauss-Legendre on [0, T]: times and weights, each panel's start (and T) in the
    grid too with weight 0 so that the energy can be read there; and the index of each of these
    panel boundaries (panels + 1)."""
    x, w = np.polynomial.legendre.leggauss(order)
    h = T / panels
    t = np.concatenate([np.concatenate([[k * h], (k + 0.5) * h + 0.5 * h * x]) for k in range(panels)] + [[T]])
    weights = np.concatenate([np.concatenate([[0.0], 0.5 * h * w]) for _ in range(panels)] + [[0.0]])
    return t, weights, np.arange(panels + 1) * (order + 1)


def test_stewart_energy_balance_along_a_smooth_motion():
    """``int tau . Thetad dt = Delta(T + V)`` over 1.5 s: the regressor's forces against the
    tree's energy computed by pinocchio from the tree rates solved here."""
    robot = _stewart()
    pi = robot.nominal_parameters()
    assert pi.shape == (len(robot.parameter_names),) and not np.any(pi[-18:])
    t, w, bounds = _gauss_grid(1.5, panels=30, order=8)
    theta, thetad, thetadd = _smooth_motion(t)
    Y, poses = robot.identification_regressor(theta, thetad, thetadd, np.zeros((len(t), robot.pose_size)))
    power = np.einsum("kip,p,ki->k", Y, pi, thetad)

    model, data, constraints = _stewart_tree()          # nominal inertias, from the file
    act = [model.joints[model.getJointId(leg)].idx_v for leg in LEGS]

    def energy(k):
        q = poses[k]
        assert np.abs(_closure_residual(model, data, constraints, q)).max() < 1e-10
        A = np.vstack([_closure_jacobian(model, data, constraints, q), np.eye(model.nv)[act]])
        v = np.linalg.solve(A, np.concatenate([np.zeros(15), thetad[k]]))
        return pin.computeKineticEnergy(model, data, q, v) + pin.computePotentialEnergy(model, data, q)

    E0 = energy(0)
    worst = 0.0
    for b in bounds[10::10]:                     # after 0.5 s, 1.0 s, 1.5 s
        work = np.dot(w[:b], power[:b])
        dE = energy(b) - E0
        assert abs(dE) > 0.05 * np.dot(w[:b], np.abs(power[:b]))      # a real change of energy
        worst = max(worst, abs(work - dE) / abs(dE))
    assert worst < 1e-6, worst


# ---------------------------------------------------------------- the 2R arm
L1 = 0.4          # link 1 (m): joint1 to joint2


def _two_r_closed_form(pi, q, qd, qdd, width):
    """Joint torques (2,) of a planar 2R arm with vertical axes (no gravity work), textbook
    Lagrange form, from the parameters in the order of ``DescribedRobot.parameter_names``:
    body 1's ``Izz`` (about joint 1), body 2's ``m``, ``mx``, ``my``, ``Izz`` (about joint 2, in
    link-2 axes), then fv, fc, Jm per joint."""
    b1, b2 = pi[0:10], pi[10:20]
    I1 = b1[BODY_PARAMS.index("Izz")]
    m2, mx2, my2, I2 = (b2[BODY_PARAMS.index(k)] for k in ("m", "mx", "my", "Izz"))
    fv, fc, Jm = pi[20:22], pi[22:24], pi[24:26]
    c2, s2 = np.cos(q[1]), np.sin(q[1])
    h = L1 * (mx2 * c2 - my2 * s2)                 # m2 l1 (c_x cos q2 - c_y sin q2)
    hd = -L1 * (mx2 * s2 + my2 * c2)               # its derivative in q2
    M11 = I1 + I2 + m2 * L1**2 + 2 * h
    M12 = I2 + h
    M22 = I2
    tau = np.array([
        M11 * qdd[0] + M12 * qdd[1] + hd * (2 * qd[0] * qd[1] + qd[1] ** 2),
        M12 * qdd[0] + M22 * qdd[1] - hd * qd[0] ** 2,
    ])
    return tau + fv * qd + fc * np.tanh(qd / width) + Jm * qdd


def test_2r_file_is_the_textbook_arm():
    model = pin.buildModelFromUrdf(str(TWO_R))
    data = model.createData()
    assert [model.names[j] for j in range(1, model.njoints)] == ["joint1", "joint2"]
    assert all(model.joints[j].shortname() == "JointModelRZ" for j in (1, 2))
    assert np.allclose(model.jointPlacements[2].translation, [L1, 0, 0], atol=0)
    assert np.allclose(model.jointPlacements[2].rotation, np.eye(3), atol=0)
    assert np.allclose(model.gravity.linear, [0, 0, -G])
    assert (model.inertias[1].mass, model.inertias[2].mass) == (5.5, 2.0)
    pi = np.concatenate([model.inertias[1].toDynamicParameters(), model.inertias[2].toDynamicParameters(),
                         np.zeros(6)])
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(50):
        q, qd, qdd = rng.uniform(-np.pi, np.pi, 2), rng.normal(0, 2, 2), rng.normal(0, 5, 2)
        ref = _two_r_closed_form(pi, q, qd, qdd, 1e-3)
        worst = max(worst, np.abs(pin.rnea(model, data, q, qd, qdd) - ref).max() / np.abs(ref).max())
    assert worst < 1e-12, worst


def test_2r_regressor_matches_closed_form():
    width = 1e-3
    robot = DescribedRobot(TWO_R, actuated=("joint1", "joint2"), coulomb_width=width)
    assert robot.pose_size == 2 and robot.body_names == ("link1", "link2")
    assert robot.parameter_names[:20] == tuple(f"{b}.{p}" for b in ("link1", "link2") for p in BODY_PARAMS)
    assert robot.parameter_names[20:] == ("fv_joint1", "fv_joint2", "fc_joint1", "fc_joint2",
                                          "Jm_joint1", "Jm_joint2")
    rng = np.random.default_rng(11)
    N = 200
    q = rng.uniform(-np.pi, np.pi, (N, 2))
    qd = rng.normal(0, 2, (N, 2))
    qd[:10] *= 1e-3                                   # inside the Coulomb smoothing band too
    qdd = rng.normal(0, 5, (N, 2))
    Y, poses = robot.identification_regressor(q, qd, qdd, None)
    assert Y.shape == (N, 2, 26) and np.array_equal(poses, q)
    worst = 0.0
    for _ in range(5):
        pi = rng.normal(0, 1, 26)
        tau = Y @ pi
        ref = np.array([_two_r_closed_form(pi, *s, width) for s in zip(q, qd, qdd)])
        worst = max(worst, np.abs(tau - ref).max() / np.abs(ref).max())
    assert worst < 1e-9, worst
