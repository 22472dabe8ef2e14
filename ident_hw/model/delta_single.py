"""The Delta's dynamics state by state, compiled by numba: for a simulator's inner loop, and the
regressor of a recording's every sample.

Both start from the seven bodies' motion at one state (``_bodies``).
:meth:`.delta.Delta.plant_dynamics` is called once per SYNC period; the vectorised regressor costs
about a millisecond for one state. :func:`one_state` computes the same ``M(q)``, bias
``tau(q, qd, 0)`` (gravity and velocity terms, with ``Jm`` but without ``fv``, ``fc``) and
platform position in scalar loops: the kinematics term for term those of
:meth:`.delta.Delta.fk` and :meth:`.delta.Delta.bodies`, each body's wrench that of
:meth:`.delta.Delta.regressor` written in world axes (first moment ``c = Q m c_body``, inertia
``Q I Qᵀ`` about the body origin), ``M = sum_k J_kᵀ M_k J_k + diag(Jm)``. The compiled function
releases the GIL. :func:`body_regressor` fills the bodies' regressor columns sample by sample.
``tests/test_model_delta.py`` holds both equal to
:meth:`.delta.Delta.vectorised_regressor`.

Shapes: ``q`` (3,) rad, ``qd`` (3,) rad/s, ``pi`` (79,) as :mod:`.delta`; ``M`` (3, 3) kg·m²,
``bias`` (3,) N·m, ``p`` (3,) m.
"""

from __future__ import annotations

from math import asin, atan2, cos, pi as PI, sin, sqrt

import numba
import numpy as np

# outcomes of one_state; on any but OK the caller goes the vectorised way, which raises the error
OK, COLLINEAR, NO_ASSEMBLY, SINGULAR, U_JOINT_LIMIT = range(5)

# argument types, so that numba compiles at import (or loads its cache) and refuses other types
_V, _M = numba.float64[::1], numba.float64[:, ::1]


@numba.njit(cache=True, nogil=True)
def _mul(A, B, out):
    """``out = A @ B`` for 3x3 matrices."""
    for r in range(3):
        for c in range(3):
            out[r, c] = A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c]


@numba.njit(cache=True, nogil=True)
def _rot(axis, angle, out):
    """Rotation about world axis ``axis`` (0, 1, 2 = x, y, z) into ``out`` (as ``delta._rot_*``)."""
    c, s = cos(angle), sin(angle)
    for r in range(3):
        for k in range(3):
            out[r, k] = 0.0
    i, j = (axis + 1) % 3, (axis + 2) % 3
    out[axis, axis] = 1.0
    out[i, i], out[i, j], out[j, i], out[j, j] = c, -s, s, c


@numba.njit(cache=True, nogil=True)
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@numba.njit(cache=True, nogil=True)
def _add_body(M, bias, body, Q, am, omega, alpha, Jv, Jw):
    """Add one body's share to ``M`` and ``bias``.

    ``body`` (10,) its parameters; ``Q`` body axes in world; ``am`` origin acceleration minus
    gravity, ``omega``, ``alpha`` (3,) at zero actuated acceleration; ``Jv``, ``Jw`` (3, 3):
    origin velocity and angular velocity per actuated rate.
    """
    m = body[0]
    cw = np.empty(3)                                 # first moment m c, world axes
    for r in range(3):
        cw[r] = Q[r, 0] * body[1] + Q[r, 1] * body[2] + Q[r, 2] * body[3]
    Ib = np.empty((3, 3))
    Ib[0, 0], Ib[0, 1], Ib[0, 2] = body[4], body[5], body[6]
    Ib[1, 0], Ib[1, 1], Ib[1, 2] = body[5], body[7], body[8]
    Ib[2, 0], Ib[2, 1], Ib[2, 2] = body[6], body[8], body[9]
    QI, Iw = np.empty((3, 3)), np.empty((3, 3))      # Iw = Q Ib Qᵀ, about the origin
    _mul(Q, Ib, QI)
    for r in range(3):
        for c in range(3):
            Iw[r, c] = QI[r, 0] * Q[c, 0] + QI[r, 1] * Q[c, 1] + QI[r, 2] * Q[c, 2]
    f, n, tmp, tmp2 = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    # bias: f = m (a - g) + alpha x c + omega x (omega x c); n = c x (a - g) + Iw alpha + omega x Iw omega
    _cross(alpha, cw, f)
    _cross(omega, cw, tmp)
    _cross(omega, tmp, tmp2)
    for r in range(3):
        f[r] += m * am[r] + tmp2[r]
    _cross(cw, am, n)
    for r in range(3):
        tmp[r] = Iw[r, 0] * omega[0] + Iw[r, 1] * omega[1] + Iw[r, 2] * omega[2]
    _cross(omega, tmp, tmp2)
    for r in range(3):
        n[r] += Iw[r, 0] * alpha[0] + Iw[r, 1] * alpha[1] + Iw[r, 2] * alpha[2] + tmp2[r]
    for r in range(3):
        bias[r] += (Jv[0, r] * f[0] + Jv[1, r] * f[1] + Jv[2, r] * f[2]
                    + Jw[0, r] * n[0] + Jw[1, r] * n[1] + Jw[2, r] * n[2])
    # M column j: the wrench of acceleration Jv[:, j], angular acceleration Jw[:, j], no gravity
    av, al = np.empty(3), np.empty(3)
    for j in range(3):
        for r in range(3):
            av[r], al[r] = Jv[r, j], Jw[r, j]
        _cross(al, cw, f)
        _cross(cw, av, n)
        for r in range(3):
            f[r] += m * av[r]
            n[r] += Iw[r, 0] * al[0] + Iw[r, 1] * al[1] + Iw[r, 2] * al[2]
        for r in range(3):
            M[r, j] += (Jv[0, r] * f[0] + Jv[1, r] * f[1] + Jv[2, r] * f[2]
                        + Jw[0, r] * n[0] + Jw[1, r] * n[1] + Jw[2, r] * n[2])


@numba.njit(cache=True, nogil=True)
def _bodies(q, qd, geo, e, y, g, Qs, ams, omegas, alphas, Jvs, Jws, p):
    """The seven bodies' motion at ``(q, qd)`` and zero actuated acceleration, body ``k`` in the
    order of ``pi`` (arms 1-3, rods 1-3, platform): its axes ``Qs[k]`` (3, 3) in world, its
    origin's acceleration minus gravity ``ams[k]`` (3,), ``omegas[k]``, ``alphas[k]`` (3,), and
    ``Jvs[k]``, ``Jws[k]`` (3, 3): origin velocity and angular velocity per actuated rate (an
    actuated acceleration ``qdd`` adds ``Jvs[k] @ qdd`` and ``Jws[k] @ qdd``); the platform
    position ``p`` (3,). Returns ``OK``, or the first failure met (outputs then undefined).
    """
    L1, L2, Rb, rp = geo[0], geo[1], geo[2], geo[3]
    ez = np.array([0.0, 0.0, 1.0])
    A, B, BA, t, C = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    for i in range(3):
        cq, sq = cos(q[i]), sin(q[i])
        for k in range(3):
            A[i, k] = Rb * e[i, k]
            BA[i, k] = L1 * (cq * e[i, k] - sq * ez[k])
            B[i, k] = A[i, k] + BA[i, k]
            t[i, k] = -L1 * (sq * e[i, k] + cq * ez[k])
            C[i, k] = B[i, k] - rp * e[i, k]
    # forward kinematics: the three-sphere intersection below the base (Delta.fk)
    fx, rest, fy, fz = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    for k in range(3):
        fx[k] = C[1, k] - C[0, k]
    dc = sqrt(fx[0] * fx[0] + fx[1] * fx[1] + fx[2] * fx[2])
    for k in range(3):
        fx[k] /= dc
    ii = fx[0] * (C[2, 0] - C[0, 0]) + fx[1] * (C[2, 1] - C[0, 1]) + fx[2] * (C[2, 2] - C[0, 2])
    for k in range(3):
        rest[k] = C[2, k] - C[0, k] - ii * fx[k]
    jj = sqrt(rest[0] * rest[0] + rest[1] * rest[1] + rest[2] * rest[2])
    if not jj > 1e-12 * L2:
        return COLLINEAR
    for k in range(3):
        fy[k] = rest[k] / jj
    _cross(fx, fy, fz)
    x0 = dc / 2
    y0 = (ii * ii + jj * jj - 2 * ii * x0) / (2 * jj)
    z2 = L2 * L2 - x0 * x0 - y0 * y0
    if z2 < 0:
        return NO_ASSEMBLY
    s = sqrt(z2)
    base_z = C[0, 2] + x0 * fx[2] + y0 * fy[2]
    if not (base_z + s * fz[2] < base_z - s * fz[2]):
        s = -s
    for k in range(3):
        p[k] = C[0, k] + x0 * fx[k] + y0 * fy[k] + s * fz[k]
    # platform Jacobian J = D^-1 diag(d_i . t_i), D's rows d_i = p + r e_i - B_i (Delta.bodies)
    D, Dinv = np.empty((3, 3)), np.empty((3, 3))
    dt = np.empty(3)
    for i in range(3):
        for k in range(3):
            D[i, k] = p[k] + rp * e[i, k] - B[i, k]
        dt[i] = D[i, 0] * t[i, 0] + D[i, 1] * t[i, 1] + D[i, 2] * t[i, 2]
    co00 = D[1, 1] * D[2, 2] - D[1, 2] * D[2, 1]
    co01 = D[1, 2] * D[2, 0] - D[1, 0] * D[2, 2]
    co02 = D[1, 0] * D[2, 1] - D[1, 1] * D[2, 0]
    det = D[0, 0] * co00 + D[0, 1] * co01 + D[0, 2] * co02
    if det == 0.0 or det != det:
        return SINGULAR
    rdet = 1.0 / det
    Dinv[0, 0], Dinv[1, 0], Dinv[2, 0] = co00 * rdet, co01 * rdet, co02 * rdet
    Dinv[0, 1] = (D[0, 2] * D[2, 1] - D[0, 1] * D[2, 2]) * rdet
    Dinv[1, 1] = (D[0, 0] * D[2, 2] - D[0, 2] * D[2, 0]) * rdet
    Dinv[2, 1] = (D[0, 1] * D[2, 0] - D[0, 0] * D[2, 1]) * rdet
    Dinv[0, 2] = (D[0, 1] * D[1, 2] - D[0, 2] * D[1, 1]) * rdet
    Dinv[1, 2] = (D[0, 2] * D[1, 0] - D[0, 0] * D[1, 2]) * rdet
    Dinv[2, 2] = (D[0, 0] * D[1, 1] - D[0, 1] * D[1, 0]) * rdet
    J = np.empty((3, 3))
    for r in range(3):
        for j in range(3):
            J[r, j] = Dinv[r, j] * dt[j]
    # platform velocity and acceleration at qdd = 0: D pdd = kappa
    pd, pdd, kappa = np.zeros(3), np.zeros(3), np.empty(3)
    for r in range(3):
        for j in range(3):
            pd[r] += J[r, j] * qd[j]
    Bdd, ddot = np.empty((3, 3)), np.empty(3)
    for i in range(3):
        dBA, dd = 0.0, 0.0
        for k in range(3):
            Bdd[i, k] = -(qd[i] * qd[i]) * BA[i, k]
            ddot[k] = pd[k] - t[i, k] * qd[i]
            dBA += D[i, k] * BA[i, k]
            dd += ddot[k] * ddot[k]
        kappa[i] = -(qd[i] * qd[i]) * dBA - dd
    for r in range(3):
        pdd[r] = Dinv[r, 0] * kappa[0] + Dinv[r, 1] * kappa[1] + Dinv[r, 2] * kappa[2]
    # rod angles, rates and their Jacobian rows, limb coordinates (R_i = [e_i, y_i, ez])
    w, wd, wdd, vec = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    b, cc, sc, cb, sb = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    cr = np.empty(3)
    omega_rod, alpha_rod, nvec = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    beta, gamma = np.empty((3, 3)), np.empty((3, 3))
    Mi, W, ycn = np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    for i in range(3):
        for k in range(3):
            vec[k] = -D[i, k] / L2
        w[0] = e[i, 0] * vec[0] + e[i, 1] * vec[1] + e[i, 2] * vec[2]
        w[1] = y[i, 0] * vec[0] + y[i, 1] * vec[1] + y[i, 2] * vec[2]
        w[2] = vec[2]
        for k in range(3):
            vec[k] = (t[i, k] * qd[i] - pd[k]) / L2
        wd[0] = e[i, 0] * vec[0] + e[i, 1] * vec[1] + e[i, 2] * vec[2]
        wd[1] = y[i, 0] * vec[0] + y[i, 1] * vec[1] + y[i, 2] * vec[2]
        wd[2] = vec[2]
        for k in range(3):
            vec[k] = (Bdd[i, k] - pdd[k]) / L2
        wdd[0] = e[i, 0] * vec[0] + e[i, 1] * vec[1] + e[i, 2] * vec[2]
        wdd[1] = y[i, 0] * vec[0] + y[i, 1] * vec[1] + y[i, 2] * vec[2]
        wdd[2] = vec[2]
        c = asin(min(1.0, max(-1.0, w[1])))
        b[i] = atan2(-w[2], w[0])
        cc[i], sc[i], cb[i], sb[i] = cos(c), sin(c), cos(b[i]), sin(b[i])
        cr[i] = c
        if abs(cc[i]) < 1e-9:
            return U_JOINT_LIMIT
        cd = wd[1] / cc[i]
        bd = -(sb[i] * wd[0] + cb[i] * wd[2]) / cc[i]
        cdd = (wdd[1] + sc[i] * cd * cd) / cc[i]
        bdd = (sc[i] * bd * cd - sb[i] * wdd[0] - cb[i] * wdd[2] - bd * (cb[i] * wd[0] - sb[i] * wd[2])) / cc[i]
        for k in range(3):
            nvec[i, k] = sb[i] * e[i, k] + cb[i] * ez[k]
        _cross(y[i], nvec[i], ycn)
        for k in range(3):
            omega_rod[i, k] = bd * y[i, k] + cd * nvec[i, k]
            alpha_rod[i, k] = bdd * y[i, k] + cdd * nvec[i, k] + (bd * cd) * ycn[k]
        # W_i = R_iᵀ (t_i eps_iᵀ - J) / L2; bd = beta_i . qd, cd = gamma_i . qd
        for r in range(3):
            for j in range(3):
                Mi[r, j] = -J[r, j]
            Mi[r, i] += t[i, r]
        for j in range(3):
            W[0, j] = (e[i, 0] * Mi[0, j] + e[i, 1] * Mi[1, j] + e[i, 2] * Mi[2, j]) / L2
            W[1, j] = (y[i, 0] * Mi[0, j] + y[i, 1] * Mi[1, j] + y[i, 2] * Mi[2, j]) / L2
            W[2, j] = Mi[2, j] / L2
            beta[i, j] = -(sb[i] * W[0, j] + cb[i] * W[2, j]) / cc[i]
            gamma[i, j] = W[1, j] / cc[i]
    # the seven bodies
    Ri, Q1, Q2, Rot = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    for i in range(3):                                                   # arms
        for k in range(3):
            Ri[k, 0], Ri[k, 1], Ri[k, 2] = e[i, k], y[i, k], ez[k]
            ams[i, k] = -g[k]
            omegas[i, k] = qd[i] * y[i, k]
            alphas[i, k] = 0.0
            for j in range(3):
                Jvs[i, k, j] = 0.0
                Jws[i, k, j] = y[i, k] if j == i else 0.0
        _rot(1, q[i], Rot)
        _mul(Ri, Rot, Qs[i])
    for i in range(3):                                                   # rods
        for k in range(3):
            Ri[k, 0], Ri[k, 1], Ri[k, 2] = e[i, k], y[i, k], ez[k]
            ams[3 + i, k] = pdd[k] - g[k]
            omegas[3 + i, k] = omega_rod[i, k]
            alphas[3 + i, k] = alpha_rod[i, k]
            for j in range(3):
                Jvs[3 + i, k, j] = J[k, j]
                Jws[3 + i, k, j] = y[i, k] * beta[i, j] + nvec[i, k] * gamma[i, j]
        _rot(1, b[i], Rot)
        _mul(Ri, Rot, Q1)
        _rot(2, cr[i], Rot)
        _mul(Q1, Rot, Q2)
        _rot(0, -PI / 2, Rot)
        _mul(Q2, Rot, Qs[3 + i])
    for k in range(3):                                                   # platform
        ams[6, k] = pdd[k] - g[k]
        omegas[6, k], alphas[6, k] = 0.0, 0.0
        for j in range(3):
            Qs[6, k, j] = 1.0 if k == j else 0.0
            Jvs[6, k, j] = J[k, j]
            Jws[6, k, j] = 0.0
    return OK


@numba.njit((_V, _V, _V, _V, _V, _M, _M, _V, _M, _V, _V), cache=True, nogil=True)
def one_state(q, qd, pi, Jm, geo, e, y, g, M, bias, p):
    """``M`` (3, 3), ``bias`` (3,) and the platform position ``p`` (3,) at ``(q, qd)``.

    ``pi`` (79,): the model's parameters (the bodies' are read), ``Jm`` (3,) kg·m²: the reflected
    rotor inertias; ``geo`` = ``[L1, L2, R, r]`` (m); ``e``, ``y`` (3 limbs, 3): radial and motor axes; ``g`` (3,)
    gravity (m/s²). Returns ``OK``, or the first failure met (outputs then undefined).
    """
    Qs, Jvs, Jws = np.empty((7, 3, 3)), np.empty((7, 3, 3)), np.empty((7, 3, 3))
    ams, omegas, alphas = np.empty((7, 3)), np.empty((7, 3)), np.empty((7, 3))
    outcome = _bodies(q, qd, geo, e, y, g, Qs, ams, omegas, alphas, Jvs, Jws, p)
    if outcome != OK:
        return outcome
    for r in range(3):
        bias[r] = 0.0
        for j in range(3):
            M[r, j] = 0.0
    for k in range(7):
        _add_body(M, bias, pi[10 * k:10 * k + 10], Qs[k], ams[k], omegas[k], alphas[k], Jvs[k], Jws[k])
    for j in range(3):                                                   # reflected rotor inertia
        M[j, j] += Jm[j]
    return OK


@numba.njit(cache=True, nogil=True)
def _add_body_rows(Y, col, Q, am, omega, alpha, Jv, Jw, qdd, phi, world):
    """Add one body's columns ``col .. col + 9`` of the regressor row block ``Y`` (3, n):
    the actuated forces of its ten parameters ``m, m c (body axes), I (about its origin, body
    axes: xx, xy, xz, yy, yz, zz)`` at actuated acceleration ``qdd`` (3,), as
    :meth:`.delta.Delta.regressor` (its body-axes map ``phi`` (6, 10), then ``Q`` and ``J``ᵀ).
    The motion arguments as ``_bodies`` gives them; ``phi``, ``world`` (6, 10): scratch."""
    a0 = am[0] + Jv[0, 0] * qdd[0] + Jv[0, 1] * qdd[1] + Jv[0, 2] * qdd[2]
    a1 = am[1] + Jv[1, 0] * qdd[0] + Jv[1, 1] * qdd[1] + Jv[1, 2] * qdd[2]
    a2 = am[2] + Jv[2, 0] * qdd[0] + Jv[2, 1] * qdd[1] + Jv[2, 2] * qdd[2]
    l0 = alpha[0] + Jw[0, 0] * qdd[0] + Jw[0, 1] * qdd[1] + Jw[0, 2] * qdd[2]
    l1 = alpha[1] + Jw[1, 0] * qdd[0] + Jw[1, 1] * qdd[1] + Jw[1, 2] * qdd[2]
    l2 = alpha[2] + Jw[2, 0] * qdd[0] + Jw[2, 1] * qdd[1] + Jw[2, 2] * qdd[2]
    # body axes: acceleration minus gravity (ax..), angular velocity (wx..), angular acceleration (lx..)
    ax = Q[0, 0] * a0 + Q[1, 0] * a1 + Q[2, 0] * a2
    ay = Q[0, 1] * a0 + Q[1, 1] * a1 + Q[2, 1] * a2
    az = Q[0, 2] * a0 + Q[1, 2] * a1 + Q[2, 2] * a2
    wx = Q[0, 0] * omega[0] + Q[1, 0] * omega[1] + Q[2, 0] * omega[2]
    wy = Q[0, 1] * omega[0] + Q[1, 1] * omega[1] + Q[2, 1] * omega[2]
    wz = Q[0, 2] * omega[0] + Q[1, 2] * omega[1] + Q[2, 2] * omega[2]
    lx = Q[0, 0] * l0 + Q[1, 0] * l1 + Q[2, 0] * l2
    ly = Q[0, 1] * l0 + Q[1, 1] * l1 + Q[2, 1] * l2
    lz = Q[0, 2] * l0 + Q[1, 2] * l1 + Q[2, 2] * l2
    # force rows: m a + alpha x c + omega x (omega x c); moment rows: c x a + I alpha + omega x I omega
    phi[0, 0], phi[1, 0], phi[2, 0] = ax, ay, az
    phi[0, 1], phi[0, 2], phi[0, 3] = -wy * wy - wz * wz, wx * wy - lz, wx * wz + ly
    phi[1, 1], phi[1, 2], phi[1, 3] = wx * wy + lz, -wx * wx - wz * wz, wy * wz - lx
    phi[2, 1], phi[2, 2], phi[2, 3] = wx * wz - ly, wy * wz + lx, -wx * wx - wy * wy
    for r in range(3):
        for c in range(4, 10):
            phi[r, c] = 0.0
        phi[3 + r, 0] = 0.0
    phi[3, 1], phi[3, 2], phi[3, 3] = 0.0, az, -ay
    phi[4, 1], phi[4, 2], phi[4, 3] = -az, 0.0, ax
    phi[5, 1], phi[5, 2], phi[5, 3] = ay, -ax, 0.0
    # I alpha + omega x (I omega) over [Ixx, Ixy, Ixz, Iyy, Iyz, Izz]
    phi[3, 4], phi[3, 5], phi[3, 6] = lx, ly - wx * wz, lz + wx * wy
    phi[3, 7], phi[3, 8], phi[3, 9] = -wy * wz, wy * wy - wz * wz, wy * wz
    phi[4, 4], phi[4, 5], phi[4, 6] = wx * wz, lx + wy * wz, wz * wz - wx * wx
    phi[4, 7], phi[4, 8], phi[4, 9] = ly, lz - wx * wy, -wx * wz
    phi[5, 4], phi[5, 5], phi[5, 6] = -wx * wy, wx * wx - wy * wy, lx - wy * wz
    phi[5, 7], phi[5, 8], phi[5, 9] = wx * wy, ly + wx * wz, lz
    for r in range(3):                                                  # world axes
        for c in range(10):
            world[r, c] = Q[r, 0] * phi[0, c] + Q[r, 1] * phi[1, c] + Q[r, 2] * phi[2, c]
            world[3 + r, c] = Q[r, 0] * phi[3, c] + Q[r, 1] * phi[4, c] + Q[r, 2] * phi[5, c]
    for j in range(3):
        for c in range(10):
            Y[j, col + c] += (Jv[0, j] * world[0, c] + Jv[1, j] * world[1, c] + Jv[2, j] * world[2, c]
                              + Jw[0, j] * world[3, c] + Jw[1, j] * world[4, c] + Jw[2, j] * world[5, c])


@numba.njit((_M, _M, _M, _V, _M, _M, _V, numba.float64[:, :, ::1]), cache=True, nogil=True)
def body_regressor(q, qd, qdd, geo, e, y, g, Y):
    """The bodies' columns ``Y[:, :, :70]`` (N, 3, 70 of 79) of the regressor at the samples
    ``q, qd, qdd`` (N, 3): added to ``Y`` (zeros there on entry). Returns -1, or the first sample
    whose motion ``_bodies`` refused (``Y`` then incomplete)."""
    Qs, Jvs, Jws = np.empty((7, 3, 3)), np.empty((7, 3, 3)), np.empty((7, 3, 3))
    ams, omegas, alphas = np.empty((7, 3)), np.empty((7, 3)), np.empty((7, 3))
    p, phi, world = np.empty(3), np.empty((6, 10)), np.empty((6, 10))
    for n in range(q.shape[0]):
        if _bodies(q[n], qd[n], geo, e, y, g, Qs, ams, omegas, alphas, Jvs, Jws, p) != OK:
            return n
        for k in range(7):
            _add_body_rows(Y[n], 10 * k, Qs[k], ams[k], omegas[k], alphas[k], Jvs[k], Jws[k], qdd[n], phi, world)
    return -1
