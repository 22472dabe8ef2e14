"""The 3PRRR model against independent computations: closure, finite differences, energy, simulation."""

import numpy as np
import pytest

from ident_hw.model import Geometry, InertialParams, KinematicsError, SingularityError, ThreePRRR

GEO = Geometry(l1=0.30, l2=0.30, s1=0.15, s2=0.15, h=0.12, a=0.40, gamma=tuple(np.radians([0, 120, 240])))
TRUE = InertialParams(
    m_c=603.62, m_l1=0.30, I_l1=0.30 * 0.3**2 / 12, m_l2=0.5723, I_l2=0.5723 * 0.3**2 / 12,
    m_ee=0.2269, I_ee=0.5 * 0.2269 * 0.12**2,
    f_v=(0.02, 0.03, 0.025, 40.0, 45.0, 38.0), f_c=(0.05, 0.04, 0.06, 8.0, 9.0, 7.5),
)
FRICTIONLESS = TRUE.replace(f_v=(0.0,) * 6, f_c=(0.0,) * 6)


@pytest.fixture(scope="module")
def robot():
    return ThreePRRR(GEO)


def smooth_motion(t, seed=0):
    """A smooth analytic pose + carriage motion inside the workspace, with exact derivatives."""
    rng = np.random.default_rng(seed)
    amp = np.array([0.04, 0.04, 0.25, 0.03, 0.03, 0.03])
    freq = rng.uniform(0.3, 1.2, (6, 3))
    phase = rng.uniform(0, 2 * np.pi, (6, 3))
    weight = rng.uniform(0.2, 1.0, (6, 3))
    weight /= weight.sum(1, keepdims=True)
    w = 2 * np.pi * freq
    arg = w[None] * t[:, None, None] + phase[None]
    q = (amp[:, None] * weight * np.sin(arg)).sum(-1)
    qd = (amp[:, None] * weight * w * np.cos(arg)).sum(-1)
    qdd = -(amp[:, None] * weight * w**2 * np.sin(arg)).sum(-1)
    return q[:, :3], qd[:, :3], qdd[:, :3], q[:, 3:], qd[:, 3:], qdd[:, 3:]


def random_poses(n, seed=1):
    rng = np.random.default_rng(seed)
    X = np.c_[rng.uniform(-0.07, 0.07, (n, 2)), rng.uniform(-0.4, 0.4, n)]
    zeta = rng.uniform(-0.08, 0.08, (n, 3))
    return X, zeta


def test_home_pose_matches_hand_geometry(robot):
    # At home each chain is an isosceles triangle: |A C| = a - h, links l1 = l2.
    theta, beta = robot.inverse_kinematics(np.zeros(3), np.zeros(3))
    half = np.degrees(np.arccos((GEO.a - GEO.h) / 2 / GEO.l1))
    direction = np.degrees(GEO.gamma) + 90 + 180  # A -> C points along -n(gamma)
    expected = (direction + half + 180) % 360 - 180
    assert np.allclose(theta[0], np.radians(expected), atol=1e-12)
    assert np.allclose(np.cos(beta[0] - theta[0]), np.cos(np.radians(-2 * half)), atol=1e-12)


def test_ik_satisfies_closure_on_a_grid(robot):
    x, y, alpha = np.meshgrid(np.linspace(-0.07, 0.07, 9), np.linspace(-0.07, 0.07, 9), np.linspace(-0.4, 0.4, 7))
    X = np.c_[x.ravel(), y.ravel(), alpha.ravel()]
    zeta = np.random.default_rng(3).uniform(-0.08, 0.08, (len(X), 3))
    theta, beta = robot.inverse_kinematics(X, zeta)
    # closure written out independently of the model's helpers
    for i, g in enumerate(GEO.gamma):
        A = zeta[:, i, None] * [np.cos(g), np.sin(g)] + GEO.a * np.array([-np.sin(g), np.cos(g)])
        C = X[:, :2] + GEO.h * np.c_[-np.sin(X[:, 2] + g), np.cos(X[:, 2] + g)]
        g_i = C - A - GEO.l1 * np.c_[np.cos(theta[:, i]), np.sin(theta[:, i])] \
            - GEO.l2 * np.c_[np.cos(beta[:, i]), np.sin(beta[:, i])]
        assert np.abs(g_i).max() < 1e-12


def test_ik_follows_eq6_and_its_working_mode(robot):
    """theta from the paper's eq. 6 (half-angle form, sign = working mode) equals the model's."""
    X, zeta = random_poses(200)
    for modes in [(1, 1, 1), (-1, 1, -1)]:
        r = ThreePRRR(Geometry(**{**GEO.__dict__, "modes": modes}))
        theta, _ = r.inverse_kinematics(X, zeta)
        for i, g in enumerate(GEO.gamma):
            A = zeta[:, i, None] * [np.cos(g), np.sin(g)] + GEO.a * np.array([-np.sin(g), np.cos(g)])
            rho = X[:, :2] + GEO.h * np.c_[-np.sin(X[:, 2] + g), np.cos(X[:, 2] + g)] - A
            k1 = (rho**2).sum(1) + GEO.l1**2 - GEO.l2**2
            k2, k3 = -2 * GEO.l1 * rho[:, 0], -2 * GEO.l1 * rho[:, 1]
            t6 = 2 * np.arctan((-k3 + modes[i] * np.sqrt(k2**2 + k3**2 - k1**2)) / (k1 - k2))
            assert np.abs(np.angle(np.exp(1j * (theta[:, i] - t6)))).max() < 1e-10


def test_forward_kinematics_inverts_ik(robot):
    X, zeta = random_poses(500)
    theta, _ = robot.inverse_kinematics(X, zeta)
    Theta = np.c_[theta, zeta]
    X_back = robot.forward_kinematics(Theta, X + np.random.default_rng(0).normal(0, 0.005, X.shape))
    assert np.abs(X_back - X).max() < 1e-12
    # continuation along a time series from a single guess
    t = np.linspace(0, 4, 4001)
    Xs, _, _, zs, _, _ = smooth_motion(t)
    Theta_s = np.c_[robot.inverse_kinematics(Xs, zs)[0], zs]
    assert np.abs(robot.forward_kinematics(Theta_s, np.zeros(3)) - Xs).max() < 1e-12


def test_jacobian_matches_finite_differences_of_ik(robot):
    X, zeta = random_poses(100, seed=5)
    J = robot.jacobian(X, zeta)
    # Thetad = J^+ ... compare the inverse map: dTheta/dX and dTheta/dzeta by central differences.
    eps = 1e-6
    dtheta_dX = np.stack([(robot.inverse_kinematics(X + eps * np.eye(3)[k], zeta)[0]
                           - robot.inverse_kinematics(X - eps * np.eye(3)[k], zeta)[0]) / (2 * eps)
                          for k in range(3)], axis=-1)  # (N, 3, 3)
    dtheta_dz = np.stack([(robot.inverse_kinematics(X, zeta + eps * np.eye(3)[k])[0]
                           - robot.inverse_kinematics(X, zeta - eps * np.eye(3)[k])[0]) / (2 * eps)
                          for k in range(3)], axis=-1)
    rng = np.random.default_rng(9)
    Xd = rng.normal(size=(100, 3))
    zd = rng.normal(size=(100, 3))
    thd_fd = np.einsum("nij,nj->ni", dtheta_dX, Xd) + np.einsum("nij,nj->ni", dtheta_dz, zd)
    # J maps [thd, zd] back to Xd
    Xd_back = np.einsum("nij,nj->ni", J, np.c_[thd_fd, zd])
    assert np.abs(Xd_back - Xd).max() / np.abs(Xd).max() < 1e-6


def test_actuated_rates_match_finite_differences():
    robot = ThreePRRR(GEO)
    t = np.linspace(0, 2, 20001)
    actuated = robot.actuated_motion(*smooth_motion(t, seed=2))
    Theta, Thetad, Thetadd = actuated.q, actuated.qd, actuated.qdd
    h = t[1] - t[0]
    fd_v = (Theta[2:] - Theta[:-2]) / (2 * h)
    fd_a = (Theta[2:] - 2 * Theta[1:-1] + Theta[:-2]) / h**2
    assert np.abs(fd_v - Thetad[1:-1]).max() / np.abs(Thetad).max() < 1e-6
    assert np.abs(fd_a - Thetadd[1:-1]).max() / np.abs(Thetadd).max() < 1e-5


def test_regressor_equals_lagrange_inverse_dynamics(robot):
    t = np.linspace(0, 3, 600)
    motion = smooth_motion(t, seed=4)
    Y = robot.regressor(*motion)
    assert Y.shape == (600, 6, 19) and len(robot.parameter_names) == 19
    rng = np.random.default_rng(0)
    for _ in range(5):
        p = InertialParams.from_vector(rng.uniform(0.01, 2.0, 19) * np.r_[300, np.ones(18)])
        tau = robot.inverse_dynamics(*motion, p)
        assert np.abs(Y @ p.as_vector() - tau).max() / np.abs(tau).max() < 1e-10


def test_energy_balance(robot):
    """Actuated power equals dT/dt (friction off), dT/dt by a 6th-order central difference."""
    t = np.linspace(0, 3, 3001)
    X, Xd, Xdd, z, zd, zdd = smooth_motion(t, seed=7)
    tau = robot.inverse_dynamics(X, Xd, Xdd, z, zd, zdd, FRICTIONLESS)
    Thetad = robot.actuated_motion(X, Xd, Xdd, z, zd, zdd).qd
    power = (tau * Thetad).sum(1)
    T = robot.kinetic_energy(X, Xd, z, zd, FRICTIONLESS)
    h = t[1] - t[0]
    c = np.array([-1, 9, -45, 0, 45, -9, 1]) / 60
    dT = sum(ck * T[3 + k - 3: len(T) - 3 + k - 3 or None] for k, ck in enumerate(c)) / h
    assert np.abs(dT - power[3:-3]).max() / np.abs(power).max() < 1e-6


def test_inverse_then_forward_dynamics_reproduces_the_trajectory(robot):
    t = np.linspace(0, 2, 401)
    X, Xd, Xdd, z, zd, zdd = smooth_motion(t, seed=11)
    actuated = robot.actuated_motion(X, Xd, Xdd, z, zd, zdd)
    Theta, Thetad = actuated.q, actuated.qd

    def force(time, Th, Thd):
        # the forces of inverse dynamics along the reference, evaluated at the reference state
        Xr, Xdr, Xddr, zr, zdr, zddr = smooth_motion(np.array([time]), seed=11)
        return robot.inverse_dynamics(Xr, Xdr, Xddr, zr, zdr, zddr, TRUE)[0]

    sim = robot.simulate(t, Theta[0], Thetad[0], force, TRUE, X[0])
    assert np.abs(sim.Theta - Theta).max() < 1e-6
    assert np.abs(sim.X - X).max() < 1e-6
    assert robot.closure_residual(sim.X, sim.Theta).max() < 1e-9


def test_out_of_reach_names_chain_and_sample(robot):
    X = np.zeros((5, 3))
    X[3] = [0.0, -0.5, 0.0]
    with pytest.raises(KinematicsError) as err:
        robot.inverse_kinematics(X, np.zeros((5, 3)))
    assert err.value.sample == 3 and err.value.chain == 1
    assert "chain 1" in str(err.value) and "sample 3" in str(err.value)


def test_serial_singularity_is_an_error_not_a_nan(robot):
    # chain 2 stretched: |C_2 - A_2| = l1 + l2, found by moving its carriage along its guide.
    g = GEO.gamma[1]
    X = np.zeros(3)
    C = GEO.h * np.array([-np.sin(g), np.cos(g)])
    # A_2(zeta) = zeta e(g) + a n(g); solve |C - A_2| = l1 + l2 for zeta
    d = C - GEO.a * np.array([-np.sin(g), np.cos(g)])
    u = np.array([np.cos(g), np.sin(g)])
    zeta2 = d @ u + np.sqrt((d @ u) ** 2 - d @ d + (GEO.l1 + GEO.l2) ** 2)
    with pytest.raises(SingularityError) as err:
        robot.inverse_kinematics(X, np.array([0.0, zeta2, 0.0]))
    assert err.value.chain == 2


def test_bad_input_shapes_and_nan():
    robot = ThreePRRR(GEO)
    with pytest.raises(ValueError, match="X must have shape"):
        robot.inverse_kinematics(np.zeros((4, 2)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="NaN"):
        robot.inverse_kinematics(np.full(3, np.nan), np.zeros(3))
    with pytest.raises(ValueError, match="l2 must be positive"):
        Geometry(l1=0.3, l2=-0.3, s1=0.1, s2=0.1, h=0.1, a=0.4, gamma=(0, 2, 4))


def test_reduced_mass_matrix_gives_the_kinetic_energy(robot):
    """T = 1/2 Thetad^T M_r Thetad, with T from the body velocities (eqs. 17-20)."""
    t = np.linspace(0, 3, 50)
    X, Xd, Xdd, z, zd, zdd = smooth_motion(t, seed=13)
    actuated = robot.actuated_motion(X, Xd, Xdd, z, zd, zdd)
    Theta, Thetad = actuated.q, actuated.qd
    M, c = robot.reduced_dynamics(Theta, Thetad, TRUE, X)
    assert np.allclose(M, np.swapaxes(M, 1, 2), rtol=0, atol=1e-12 * np.abs(M).max())
    assert np.all(np.linalg.eigvalsh(M) > 0)
    T = robot.kinetic_energy(X, Xd, z, zd, TRUE)
    assert np.allclose(0.5 * np.einsum("ni,nij,nj->n", Thetad, M, Thetad), T, rtol=1e-12, atol=0)
    # at rest, the bias forces vanish (no gravity, friction zero at zero velocity)
    _, c0 = robot.reduced_dynamics(Theta, np.zeros_like(Thetad), TRUE, X)
    assert np.abs(c0).max() < 1e-12


def test_forward_kinematics_refuses_another_working_mode(robot):
    X, zeta = random_poses(5, seed=21)
    other = ThreePRRR(Geometry(**{**GEO.__dict__, "modes": (1, -1, 1)}))
    theta_other, _ = other.inverse_kinematics(X, zeta)
    with pytest.raises(KinematicsError, match="working mode") as err:
        robot.forward_kinematics(np.c_[theta_other, zeta], X)
    assert err.value.chain == 2


def test_forward_kinematics_refuses_another_assembly_mode(robot):
    """At home the platform has a second assembly (same elbows, rotated about -91 deg): Newton started
    next to it converges there, and the det(A) sign check refuses it."""
    theta, _ = robot.inverse_kinematics(np.zeros(3), np.zeros(3))
    Theta = np.r_[theta[0], 0.0, 0.0, 0.0]
    # the other solution satisfies every closure constraint, so only the assembly check can tell
    other = np.array([0.0, 0.0, np.radians(-91.1626)])
    X_other, ok = robot.kinematics._newton(other[None], theta, np.zeros((1, 3)))
    assert ok[0] and abs(X_other[0, 2] - other[2]) < 1e-3
    assert robot.closure_residual(X_other, Theta).max() < 1e-12
    with pytest.raises(KinematicsError, match="assembly mode"):
        robot.forward_kinematics(Theta, other)
    assert np.abs(robot.forward_kinematics(Theta, np.array([0.01, -0.01, 0.1]))).max() < 1e-12
