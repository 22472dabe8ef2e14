"""Dynamics of the 3PRRR (spec eqs. 15–35), linear in the parameters.

Two independent routes to the actuator forces:

* :func:`regressor`: virtual power. Every body's velocity is linear in ``Thetad``,
  ``v_b = Jv_b Thetad``, so ``tau = sum_b Jv_b^T m_b a_b + Jw_b^T I_b omegadot_b``, one column
  per parameter.
* :func:`lagrange_forces`: the paper's Lagrange-multiplier form in the 12 coordinates
  ``q = [zeta_1, theta_1, beta_1, ..., x, y, alpha]``: ``Q = M qdd + b`` from the body
  Jacobians ``K`` in ``q``, multipliers from the six unactuated rows, ``tau_a = Q_a - G_a^T lambda``.

Shapes: N samples; forces (N, 6) in the order ``[theta1..3 (N·m), zeta1..3 (N)]``.
"""

from __future__ import annotations

import numpy as np

from .kinematics import Kinematics, Motion, dot, e, n
from .parameters import InertialParams

N_INERTIAL = 7
_EYE6 = np.eye(6)
_E_THETA = _EYE6[:3]  # row i selects theta_i in a (6,) actuated vector
_E_ZETA = _EYE6[3:]


def body_jacobians(kin: Kinematics, m: Motion):
    """Velocity Jacobians of every body with respect to ``Thetad``.

    Returns a list, one entry per inertial parameter (order of :data:`~ident_hw.model.parameters.INERTIAL_NAMES`), of
    ``(Jac, acc)`` with ``Jac`` (N, 3 chains or 1, d, 6) and ``acc`` (N, 3 or 1, d) the matching
    accelerations (d = 2 for a translation paired with a mass, 1 for a rotation paired with an
    inertia).
    """
    g = kin.geometry
    N = m.X.shape[0]
    eg = np.broadcast_to(kin._eg, (N, 3, 2))
    nth, eth, nb, eb = n(m.theta), e(m.theta), n(m.beta), e(m.beta)
    th_d, th_dd = m.thetad[..., None], m.thetadd[..., None]
    b_d, b_dd = m.betad[..., None], m.betadd[..., None]
    z_dd = m.zetadd[..., None]

    # dCd_i / dThetad (N, 3, 2, 6) and dbetad_i / dThetad (N, 3, 6)
    phi = m.X[:, 2:3] + kin.gamma
    dCd = m.J[:, None, :2, :] - g.h * e(phi)[..., None] * m.J[:, None, 2:3, :]
    dbetad = (np.einsum("nik,nikj->nij", nb, dCd)
              - np.sin(kin.gamma - m.beta)[..., None] * _E_ZETA
              - g.l1 * np.cos(m.beta - m.theta)[..., None] * _E_THETA) / g.l2

    J_carriage = eg[..., None] * _E_ZETA[None, :, None, :]
    a_carriage = z_dd * eg
    J_link1 = g.s1 * nth[..., None] * _E_THETA[None, :, None, :] + J_carriage
    a_link1 = a_carriage + g.s1 * th_dd * nth - g.s1 * th_d**2 * eth
    J_link2 = g.l1 * nth[..., None] * _E_THETA[None, :, None, :] + J_carriage + g.s2 * nb[..., None] * dbetad[:, :, None, :]
    a_link2 = a_carriage + g.l1 * th_dd * nth - g.l1 * th_d**2 * eth + g.s2 * b_dd * nb - g.s2 * b_d**2 * eb
    J_rot1 = np.broadcast_to(_E_THETA[None, :, None, :], (N, 3, 1, 6))
    return [
        (J_carriage, a_carriage),                          # m_c
        (J_link1, a_link1),                                # m_l1
        (J_rot1, th_dd),                                   # I_l1
        (J_link2, a_link2),                                # m_l2
        (dbetad[:, :, None, :], b_dd),                     # I_l2
        (m.J[:, None, :2, :], m.Xdd[:, None, :2]),         # m_ee
        (m.J[:, None, 2:3, :], m.Xdd[:, None, 2:3]),       # I_ee
    ]


def smooth_sign(velocity: np.ndarray, width: float) -> np.ndarray:
    """``tanh(velocity / width)``: the Coulomb friction direction, smooth through zero."""
    return np.tanh(velocity / width)


def regressor(kin: Kinematics, m: Motion, coulomb_width: float) -> np.ndarray:
    """Regressor ``Y`` (N, 6, 19) with ``tau = Y @ pi`` (parameter order of ``InertialParams.NAMES``)."""
    N = m.X.shape[0]
    Y = np.zeros((N, 6, N_INERTIAL + 12))
    for k, (Jac, acc) in enumerate(body_jacobians(kin, m)):
        Y[:, :, k] = np.einsum("nidj,nid->nj", Jac, acc)
    idx = np.arange(6)
    Thetad = m.Thetad
    Y[:, idx, N_INERTIAL + idx] = Thetad
    Y[:, idx, N_INERTIAL + 6 + idx] = smooth_sign(Thetad, coulomb_width)
    return Y


def reduced_dynamics(kin: Kinematics, m: Motion, params: InertialParams, coulomb_width: float):
    """Mass matrix ``M_r`` (N, 6, 6) and bias forces ``c`` (N, 6) in the actuated coordinates.

    ``M_r = sum_b p_b Jac_b^T Jac_b``; ``c`` is the force at the motion ``m`` (evaluate it with zero
    actuated acceleration to get the velocity terms), friction included.
    """
    pi = params.as_vector()
    bodies = body_jacobians(kin, m)
    M = sum(pi[k] * np.einsum("nidj,nidk->njk", Jac, Jac) for k, (Jac, _) in enumerate(bodies))
    c = sum(pi[k] * np.einsum("nidj,nid->nj", Jac, acc) for k, (Jac, acc) in enumerate(bodies))
    return M, c + friction(m.Thetad, params, coulomb_width)


def friction(Thetad: np.ndarray, params: InertialParams, coulomb_width: float) -> np.ndarray:
    """Friction forces (N, 6): ``f_v Thetad + f_c tanh(Thetad / w)``."""
    return np.asarray(params.f_v) * Thetad + np.asarray(params.f_c) * smooth_sign(Thetad, coulomb_width)


# -- the Lagrange-multiplier route (independent of the regressor) -------------------------------
# q = [zeta_i, theta_i, beta_i for i = 1..3, x, y, alpha]
_Q_ZETA = np.array([0, 3, 6])
_Q_THETA = np.array([1, 4, 7])
_Q_BETA = np.array([2, 5, 8])
_Q_ACTUATED = np.concatenate([_Q_THETA, _Q_ZETA])  # order of Theta
_Q_UNACTUATED = np.concatenate([_Q_BETA, [9, 10, 11]])


def lagrange_forces(kin: Kinematics, m: Motion, params: InertialParams, coulomb_width: float) -> np.ndarray:
    """Actuator forces (N, 6) by eqs. 31–35: ``tau = (I - G^T (N G^T)^-1 N)(M qdd + b)``, actuated rows.

    ``M qdd + b = sum_b K_b^T mu_b (K_b qdd + Kd_b qd)``, with ``K_b`` the Jacobian of body ``b``'s
    centre-of-mass velocity (or angular velocity) with respect to ``qd``.
    """
    g = kin.geometry
    p = params
    N = m.X.shape[0]
    Q = np.zeros((N, 12))
    eg = kin._eg
    for i in range(3):
        zi, ti, bi = _Q_ZETA[i], _Q_THETA[i], _Q_BETA[i]
        th, thd, thdd = m.theta[:, i], m.thetad[:, i], m.thetadd[:, i]
        b, bd, bdd = m.beta[:, i], m.betad[:, i], m.betadd[:, i]
        zdd = m.zetadd[:, i]
        nth, eth, nb, eb = n(th), e(th), n(b), e(b)
        # carriage: K = [e(gamma) at zeta_i]
        a_c = zdd[:, None] * eg[i]
        Q[:, zi] += p.m_c * a_c @ eg[i]
        # link 1: K = [e(gamma) at zeta_i, s1 n(theta) at theta_i]; rotation thetad
        a_1 = a_c + g.s1 * thdd[:, None] * nth - g.s1 * thd[:, None] ** 2 * eth
        Q[:, zi] += p.m_l1 * a_1 @ eg[i]
        Q[:, ti] += p.m_l1 * g.s1 * dot(nth, a_1) + p.I_l1 * thdd
        # link 2: K = [e(gamma), l1 n(theta), s2 n(beta)]; rotation betad
        a_2 = (a_c + g.l1 * thdd[:, None] * nth - g.l1 * thd[:, None] ** 2 * eth
               + g.s2 * bdd[:, None] * nb - g.s2 * bd[:, None] ** 2 * eb)
        Q[:, zi] += p.m_l2 * a_2 @ eg[i]
        Q[:, ti] += p.m_l2 * g.l1 * dot(nth, a_2)
        Q[:, bi] += p.m_l2 * g.s2 * dot(nb, a_2) + p.I_l2 * bdd
    Q[:, 9:11] += p.m_ee * m.Xdd[:, :2]
    Q[:, 11] += p.I_ee * m.Xdd[:, 2]

    # G = dg/dq (N, 6, 12) of g_i = [x, y] + h n(alpha + gamma_i) - zeta_i e(gamma_i) - a n(gamma_i)
    #                               - l1 e(theta_i) - l2 e(beta_i)
    G = np.zeros((N, 6, 12))
    phi = m.X[:, 2:3] + kin.gamma
    for i in range(3):
        rows = slice(2 * i, 2 * i + 2)
        G[:, rows, _Q_ZETA[i]] = -eg[i]
        G[:, rows, _Q_THETA[i]] = -g.l1 * n(m.theta[:, i])
        G[:, rows, _Q_BETA[i]] = -g.l2 * n(m.beta[:, i])
        G[:, rows, 9:11] = np.eye(2)
        G[:, rows, 11] = -g.h * e(phi[:, i])
    Gu, Ga = G[:, :, _Q_UNACTUATED], G[:, :, _Q_ACTUATED]
    lam = np.linalg.solve(np.swapaxes(Gu, 1, 2), Q[:, _Q_UNACTUATED][..., None])[..., 0]
    tau = Q[:, _Q_ACTUATED] - np.einsum("nkj,nk->nj", Ga, lam)
    return tau + friction(m.Thetad, params, coulomb_width)


# -- energy ---------------------------------------------------------------------------------------
def energy_regressor(kin: Kinematics, m: Motion) -> np.ndarray:
    """``H`` (N, 7) with kinetic energy ``T = H @ pi[:7]`` (J), from the body velocities (eqs. 17–20)."""
    g = kin.geometry
    zd, thd, bd = m.zetad[..., None], m.thetad[..., None], m.betad[..., None]
    v_c = zd * kin._eg
    v_1 = v_c + g.s1 * thd * n(m.theta)
    v_2 = v_c + g.l1 * thd * n(m.theta) + g.s2 * bd * n(m.beta)
    half_sq = lambda v: 0.5 * dot(v, v).sum(axis=1)  # noqa: E731 (sum over the chains)
    return np.stack([
        half_sq(v_c), half_sq(v_1), 0.5 * (m.thetad**2).sum(1), half_sq(v_2), 0.5 * (m.betad**2).sum(1),
        0.5 * (m.Xd[:, :2] ** 2).sum(1), 0.5 * m.Xd[:, 2] ** 2,
    ], axis=1)
