"""The Delta model (ident_hw.model.delta) against the checks of the Delta spec: the spec's test
vectors, FK/IK round trips, finite differences of the kinematics, energy balance and statics with
the energy computed from body poses (never from the regressor), the payload check, the mass
matrix, the base-parameter structure (30 zero columns, rank 34, 40 with drive terms), and the
compiled one-state plant dynamics against the regressor."""

import math

import numpy as np
import pytest

from delta_scenarios import truth
from ident_hw.model import KinematicsError, SingularityError
from ident_hw.model.delta import (BODIES, N_BODY_PARAMS, N_PARAMS, PARAM_NAMES, Delta, DeltaGeometry,
                                  body_parameters, inertia_about_origin, nominal_parameters)

ROBOT = Delta()
PI = nominal_parameters()
G = ROBOT.geometry


@pytest.mark.parametrize("q, qd, qdd, p, tau", [
    ((0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, -0.4273511437), (-6.8774917950,) * 3),
    ((0.3, -0.2, 0.5), (0, 0, 0), (0, 0, 0), (-0.0329804189, 0.1494336283, -0.4708552060),
     (-6.3881955401, -9.1622832490, -4.9235847933)),
    ((0.3, -0.2, 0.5), (1, -2, 0.5), (5, 3, -4), (-0.0329804189, 0.1494336283, -0.4708552060),
     (-5.1529780273, -8.2930534152, -7.2014499667)),
    ((-0.4, 0.1, 0.2), (-1.5, 0.7, 2), (-10, 12, 6), (0.1096103665, 0.0184213896, -0.4043477890),
     (-10.3023355909, -3.4507270314, -4.3216680026)),
])
def test_spec_test_vectors(q, qd, qdd, p, tau):
    q = np.array(q, float)
    np.testing.assert_allclose(ROBOT.fk(q), p, atol=1e-10)
    np.testing.assert_allclose(ROBOT.inverse_dynamics(q, qd, qdd, PI), tau, atol=1e-9)


def random_q(n=200, seed=0):
    return np.random.default_rng(seed).uniform(-0.6, 0.6, size=(n, 3))


def test_fk_ik_round_trips_and_closure():
    q = random_q()
    p = ROBOT.fk(q)
    assert np.abs(ROBOT.ik(p) - q).max() <= 1e-12
    assert np.abs(ROBOT.fk(ROBOT.ik(p)) - p).max() <= 1e-12
    d = p[:, None, :] + G.r * ROBOT._e - ROBOT.elbows(q)
    assert np.abs(np.linalg.norm(d, axis=2) - G.L2).max() <= 1e-12


def test_out_of_reach_names_the_limb():
    with pytest.raises(KinematicsError, match="limb 1") as err:
        ROBOT.ik(np.array([[0.0, 0.0, -0.2], [2.0, 0.0, -0.4]]))
    assert err.value.sample == 0 and err.value.chain == 1


def path(t):
    """A smooth multi-harmonic path (rad) and its exact rates."""
    a = np.array([[0.30, 0.10], [0.25, 0.12], [0.20, 0.15]])
    w = np.array([[1.3, 3.1], [0.9, 2.7], [1.7, 3.9]])
    phase = np.array([[0.1, 0.7], [1.2, 0.3], [2.0, 1.1]])
    arg = w[None] * t[:, None, None] + phase[None]
    q = np.sum(a * np.sin(arg), axis=2)
    qd = np.sum(a * w * np.cos(arg), axis=2)
    qdd = -np.sum(a * w**2 * np.sin(arg), axis=2)
    return q, qd, qdd


def central(f, t, h):
    """Derivative of ``f(t)`` by the 8th-order (9-point) central stencil."""
    c = {1: 4 / 5, 2: -1 / 5, 3: 4 / 105, 4: -1 / 280}
    return sum(ck * (f(t + k * h) - f(t - k * h)) for k, ck in c.items()) / h


def test_jacobian_acceleration_and_rod_rates_against_finite_differences():
    t = np.linspace(0.0, 4.0, 41)
    q, qd, qdd = path(t)
    bodies = ROBOT.bodies(q, qd, qdd)
    h = 1e-3
    pd_fd = central(lambda s: ROBOT.fk(path(s)[0]), t, h)
    pdd_fd = central(lambda s: central(lambda u: ROBOT.fk(path(u)[0]), s, h), t, h)
    platform = BODIES.index("plat")
    np.testing.assert_allclose(bodies.v[platform], pd_fd, rtol=0, atol=1e-6 * np.abs(pd_fd).max())
    np.testing.assert_allclose(np.einsum("nij,nj->ni", ROBOT.jacobian(q), qd), pd_fd,
                               rtol=0, atol=1e-6 * np.abs(pd_fd).max())
    np.testing.assert_allclose(bodies.a[platform], pdd_fd, rtol=0, atol=1e-6 * np.abs(pdd_fd).max())
    for k in range(3, 6):                                   # rods: Qdot Q^T = S(omega)
        Qd = central(lambda s: ROBOT.bodies(*path(s)).Q[k], t, h)
        S = Qd @ np.swapaxes(bodies.Q[k], 1, 2)
        omega_fd = np.stack([S[:, 2, 1], S[:, 0, 2], S[:, 1, 0]], axis=1)
        scale = np.abs(omega_fd).max()
        np.testing.assert_allclose(bodies.omega[k], omega_fd, rtol=0, atol=1e-6 * scale)
        alpha_fd = central(lambda s: ROBOT.bodies(*path(s)).omega[k], t, h)
        np.testing.assert_allclose(bodies.alpha[k], alpha_fd, rtol=0, atol=1e-6 * np.abs(alpha_fd).max())


# a physically consistent robot (no products of inertia): (mass, centre of mass, inertia about it)
ARM = (0.781, (G.L1 / 2, 0.004, -0.003), (4e-4, 6.5e-3, 6.6e-3))
ROD = (1.666, (G.L2 / 2, 0.0, 0.002), (2.0e-3, 4.9e-2, 5.0e-2))
PLATFORM_MASS = 0.637


def physical_parameters():
    def body(m, c, Ig):
        Ig6 = (Ig[0], 0, 0, Ig[1], 0, Ig[2])
        return body_parameters(m, c, inertia_about_origin(m, c, Ig6))
    return np.concatenate([body(*ARM)] * 3 + [body(*ROD)] * 3
                          + [body_parameters(PLATFORM_MASS, (0, 0, 0), (0,) * 6), np.zeros(9)])


def energy(t, h):
    """Kinetic and potential energy (J) from the bodies' poses: centre-of-mass velocities and
    angular velocities by finite differences of the poses along ``path``, never from ``Y``."""
    def centres(s):
        b = ROBOT.bodies(*path(s))
        coms = [np.asarray(c) for c in [ARM[1]] * 3 + [ROD[1]] * 3 + [(0, 0, 0)]]
        return np.stack([b.origin[k] + b.Q[k] @ coms[k] for k in range(7)]), b.Q
    pos, Q = centres(t)
    vel = central(lambda s: centres(s)[0], t, h)
    Qd = central(lambda s: centres(s)[1], t, h)
    masses = [ARM[0]] * 3 + [ROD[0]] * 3 + [PLATFORM_MASS]
    inertias = [np.diag(ARM[2])] * 3 + [np.diag(ROD[2])] * 3 + [np.zeros((3, 3))]
    T = np.zeros(len(t))
    V = np.zeros(len(t))
    for k in range(7):
        S = Qd[k] @ np.swapaxes(Q[k], 1, 2)
        omega = np.stack([S[:, 2, 1], S[:, 0, 2], S[:, 1, 0]], axis=1)
        Iw = Q[k] @ inertias[k] @ np.swapaxes(Q[k], 1, 2)
        T += 0.5 * masses[k] * np.sum(vel[k] ** 2, axis=1) + 0.5 * np.einsum("ni,nij,nj->n", omega, Iw, omega)
        V += masses[k] * 9.81 * pos[k][:, 2]
    return T + V


def test_energy_balance_without_friction():
    pi = physical_parameters()
    t = np.linspace(0.5, 5.0, 91)
    q, qd, qdd = path(t)
    power = np.sum(ROBOT.inverse_dynamics(q, qd, qdd, pi) * qd, axis=1)
    h = 2e-3
    dE = central(lambda s: energy(s, h), t, h)
    assert np.abs(power - dE).max() <= 1e-8 * np.abs(power).max()


def test_statics_gravity_torque_is_the_potential_gradient():
    pi = physical_parameters()
    masses = [ARM[0]] * 3 + [ROD[0]] * 3 + [PLATFORM_MASS]
    coms = [np.asarray(c) for c in [ARM[1]] * 3 + [ROD[1]] * 3 + [(0, 0, 0)]]

    def V(q):
        b = ROBOT.bodies(q, np.zeros_like(q), np.zeros_like(q))
        return sum(masses[k] * 9.81 * (b.origin[k] + b.Q[k] @ coms[k])[:, 2] for k in range(7))

    q = random_q(20, seed=3)
    zero = np.zeros_like(q)
    tau_g = ROBOT.inverse_dynamics(q, zero, zero, pi)
    h = 1e-4
    grad = np.stack([(-V(q + 2 * h * e) + 8 * V(q + h * e) - 8 * V(q - h * e) + V(q - 2 * h * e)) / (12 * h)
                     for e in np.eye(3)], axis=1)
    np.testing.assert_allclose(tau_g, grad, rtol=0, atol=1e-9 * np.abs(tau_g).max())


def test_payload_at_the_platform():
    q = np.array([0.2, -0.1, 0.4])
    loaded = PI.copy()
    loaded[PARAM_NAMES.index("plat.m")] += 1.0
    zero = np.zeros(3)
    change = ROBOT.inverse_dynamics(q, zero, zero, loaded) - ROBOT.inverse_dynamics(q, zero, zero, PI)
    expected = ROBOT.jacobian(q).T @ np.array([0.0, 0.0, 9.81])
    np.testing.assert_allclose(change, expected, rtol=1e-12)
    np.testing.assert_allclose(change, [-1.047854, -1.553334, -0.694087], atol=1e-6)


def test_mass_matrix_symmetric_with_the_spec_eigenvalues():
    M = ROBOT.mass_matrix(random_q(30, seed=5), PI)
    np.testing.assert_allclose(M, np.swapaxes(M, 1, 2), atol=1e-12)
    np.testing.assert_allclose(np.linalg.eigvalsh(ROBOT.mass_matrix(np.zeros(3), PI)),
                               [0.20435, 0.26548, 0.26548], atol=5e-6)


def test_forward_dynamics_inverts_the_inverse_dynamics():
    q, qd, qdd = path(np.linspace(0, 3, 25))
    pi = PI.copy()
    pi[N_BODY_PARAMS:] = [0.1] * 3 + [0.2] * 3 + [0.01] * 3
    tau = ROBOT.inverse_dynamics(q, qd, qdd, pi)
    np.testing.assert_allclose(ROBOT.forward_dynamics(q, qd, tau, pi), qdd, atol=1e-9)


def test_plant_dynamics_equals_the_regressor():
    """The compiled one-state path (ident_hw.model.delta_single) against the vectorised regressor:
    ``M`` with ``Jm``, the bias ``tau(q, qd, 0)`` without ``fv``, ``fc``, and the pose."""
    pi = truth()
    frictionless = pi.copy()
    frictionless[N_BODY_PARAMS:N_BODY_PARAMS + 6] = 0.0
    rng = np.random.default_rng(7)
    for _ in range(20):
        q, qd = rng.uniform(-0.8, 0.8, 3), rng.uniform(-3.0, 3.0, 3)
        state = ROBOT.plant_dynamics(q, qd, pi)
        M, bias, pose = state.M, state.bias, state.pose
        static = ROBOT.vectorised_regressor(q, np.zeros(3), np.zeros(3)) @ frictionless
        M_ref = np.stack([ROBOT.vectorised_regressor(q, np.zeros(3), np.eye(3)[j]) @ frictionless - static
                          for j in range(3)], axis=1)
        bias_ref = ROBOT.vectorised_regressor(q, qd, np.zeros(3)) @ frictionless
        np.testing.assert_allclose(M, M_ref, rtol=1e-12, atol=1e-12 * np.abs(M_ref).max())
        np.testing.assert_allclose(bias, bias_ref, rtol=1e-12, atol=1e-12 * np.abs(bias_ref).max())
        np.testing.assert_allclose(pose, ROBOT.fk(q), rtol=0, atol=1e-15)


def test_the_compiled_regressor_equals_the_vectorised_one():
    """:meth:`Delta.regressor` (the compiled sample loop) against :meth:`Delta.vectorised_regressor`
    (batched NumPy) over the workspace, every column, accelerations included; one sample alone too."""
    rng = np.random.default_rng(11)
    q, qd, qdd = rng.uniform(-0.8, 0.8, (200, 3)), rng.uniform(-3.0, 3.0, (200, 3)), rng.uniform(-30, 30, (200, 3))
    Y, Y_ref = ROBOT.regressor(q, qd, qdd), ROBOT.vectorised_regressor(q, qd, qdd)
    assert Y.shape == Y_ref.shape == (200, 3, N_PARAMS)
    np.testing.assert_allclose(Y, Y_ref, rtol=1e-12, atol=1e-12 * np.abs(Y_ref).max())
    np.testing.assert_allclose(ROBOT.regressor(q[7], qd[7], qdd[7]), Y_ref[7], rtol=1e-12,
                               atol=1e-12 * np.abs(Y_ref).max())


def test_plant_dynamics_raises_as_the_regressor():
    """Sphere centres collinear (every elbow's centre on the z axis): the same error either way."""
    q = np.full(3, math.acos(-(G.R - G.r) / G.L1))
    with pytest.raises(SingularityError, match="collinear"):
        ROBOT.plant_dynamics(q, np.zeros(3), truth())
    with pytest.raises(SingularityError, match="collinear"):
        ROBOT.regressor(q, np.zeros(3), np.zeros(3))


def readable_base(with_drive: bool) -> list[np.ndarray]:
    """The spec's readable base parameters as rows over the 79 parameters."""
    idx = {name: k for k, name in enumerate(PARAM_NAMES)}
    L1, L2 = G.L1, G.L2
    rows = []

    def row(**terms):
        r = np.zeros(N_PARAMS)
        for name, coef in terms.items():
            r[idx[name.replace("__", ".")]] = coef
        return r

    common = row(plat__m=1.0)
    for i in (1, 2, 3):
        common[idx[f"rod{i}.m"]] = 1.0
        common[idx[f"rod{i}.mx"]] = -1.0 / L2
    rows.append(common)
    for i in (1, 2, 3):
        a, r = f"arm{i}__", f"rod{i}__"
        rows.append(row(**{a + "mx": 1.0, r + "mx": L1 / L2}))
        rows.append(row(**{a + "mz": 1.0}))
        iyy = row(**{a + "Iyy": 1.0, r + "mx": L1**2 / L2})
        if with_drive:
            iyy[idx[f"Jm_{i}"]] = 1.0
        rows.append(iyy)
        for p in ("my", "mz", "Ixx", "Ixy", "Ixz", "Iyz"):
            rows.append(row(**{r + p: 1.0}))
        rows.append(row(**{r + "Iyy": 1.0, r + "mx": -L2}))
        rows.append(row(**{r + "Izz": 1.0, r + "mx": -L2}))
    if with_drive:
        for i in (1, 2, 3):
            rows.append(row(**{f"fv_{i}": 1.0}))
            rows.append(row(**{f"fc_{i}": 1.0}))
    return rows


@pytest.mark.parametrize("with_drive, rank", [(False, 34), (True, 40)])
def test_base_parameters_zero_columns_rank_and_readable_combinations(with_drive, rank):
    t = np.linspace(0.0, 12.0, 400)
    q, qd, qdd = path(t)
    Y = ROBOT.regressor(q, qd, qdd).reshape(-1, N_PARAMS)
    cols = slice(None) if with_drive else slice(0, N_BODY_PARAMS)
    Y = Y[:, cols]
    norms = np.linalg.norm(Y, axis=0)
    zero = norms <= 1e-10 * norms.max()
    body_zero = zero[:N_BODY_PARAMS]
    assert body_zero.sum() == 30
    expected_zero = {f"arm{i}.{p}" for i in (1, 2, 3) for p in ("m", "my", "Ixx", "Ixy", "Ixz", "Iyz", "Izz")}
    expected_zero |= {f"plat.{p}" for p in ("mx", "my", "mz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")}
    assert {PARAM_NAMES[k] for k in np.nonzero(body_zero)[0]} == expected_zero
    s = np.linalg.svd(Y / np.where(zero, 1.0, norms), compute_uv=False)
    assert int(np.sum(s > 1e-9 * s[0])) == rank
    # the readable combinations: independent, as many as the rank, and each identifiable (its row
    # lies in the row space of Y: orthogonal to the null space)
    H = np.array(readable_base(with_drive))[:, cols]
    assert len(H) == rank and np.linalg.matrix_rank(H) == rank
    _, sv, Vt = np.linalg.svd(Y, full_matrices=True)
    null = Vt[int(np.sum(sv > 1e-9 * sv[0])):]
    assert np.abs(H @ null.T).max() <= 1e-9


def test_geometry_defaults_are_the_papers():
    assert (G.L1, G.L2, G.R) == (0.309, 0.595, 0.140) and G.r == 0.035
    assert G.psi == pytest.approx((0, 2 * math.pi / 3, 4 * math.pi / 3))
    assert isinstance(G, DeltaGeometry)
