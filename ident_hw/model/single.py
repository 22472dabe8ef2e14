"""The reduced dynamics of ONE state, for a simulator's inner loop.

:meth:`ident_hw.model.robot.ThreePRRR.reduced_dynamics` is vectorised over N samples: for N = 1 its cost is a few
hundred NumPy calls of a few microseconds each, which a simulated rig pays once per SYNC period.
:class:`SingleState` computes the same quantities (forward kinematics by Newton, passive rates,
body Jacobians, ``M_r`` and the velocity terms) in scalar loops compiled by numba, the equations
term for term those of :mod:`.kinematics` and :mod:`.dynamics` (spec eqs. 1–35). The compiled
functions release the GIL: a simulated rig's plant step runs beside the master's thread.
``tests/test_model_single.py`` holds the two routes equal.

Shapes: ``Theta``, ``Thetad`` (6,) ``[theta1..3 (rad), zeta1..3 (m)]``; pose ``X`` (3,)
``[x, y, alpha]``; ``M`` (6, 6), ``c`` (6,) in N·m for the links and N for the carriages.
"""

from __future__ import annotations

from math import atan2, cos, pi, sin

import numba
import numpy as np

from .errors import KinematicsError, SingularityError
from .interface import PlantState
from .kinematics import PARALLEL_SINGULAR, Kinematics
from .parameters import InertialParams

_TWO_PI = 2.0 * pi

# outcomes of the compiled forward kinematics (what SingleState raises for each)
_OK, _NO_CONVERGENCE, _WORKING_MODE, _SINGULAR, _ASSEMBLY_MODE = range(5)

# argument types of the entry points, given so that numba compiles them at import (or loads them
# from its cache) and refuses other types instead of compiling a new version in a simulator's loop
_V, _M, _F, _I = numba.float64[::1], numba.float64[:, ::1], numba.float64, numba.int64


@numba.njit(cache=True, nogil=True)
def _wrap(angle):
    """``angle`` wrapped into ``(-pi, pi]``, as :func:`.kinematics.wrap`."""
    return pi - (pi - angle) % _TWO_PI


@numba.njit(cache=True, nogil=True)
def _inverse3(m, out):
    """Inverse of the 3x3 ``m`` into ``out`` by the adjugate; returns the determinant (0.0 when
    singular, ``out`` then undefined)."""
    a, b, c = m[0, 0], m[0, 1], m[0, 2]
    d, e, f = m[1, 0], m[1, 1], m[1, 2]
    g, h, i = m[2, 0], m[2, 1], m[2, 2]
    co00, co01, co02 = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * co00 + b * co01 + c * co02
    if det == 0.0 or det != det:
        return 0.0
    r = 1.0 / det
    out[0, 0], out[0, 1], out[0, 2] = co00 * r, (c * h - b * i) * r, (b * f - c * e) * r
    out[1, 0], out[1, 1], out[1, 2] = co01 * r, (a * i - c * g) * r, (c * d - a * f) * r
    out[2, 0], out[2, 1], out[2, 2] = co02 * r, (b * g - a * h) * r, (a * e - b * d) * r
    return det


@numba.njit(cache=True, nogil=True)
def _norm1(m):
    """1-norm of a 3x3 matrix (largest column sum of absolute values)."""
    best = 0.0
    for k in range(3):
        best = max(best, abs(m[0, k]) + abs(m[1, k]) + abs(m[2, k]))
    return best


@numba.njit((_V, _V, _V, _V, _V, _V, _F, _F, _I, _V, _V, _M, _M), cache=True, nogil=True)
def _forward(Theta, X_guess, geo, gamma, modes, beta_ref, assembly_sign, tol, max_iter, X, beta, A, Ainv):
    """Forward kinematics of one ``Theta`` (6,) by Newton from ``X_guess`` (3,).

    ``geo`` = ``[h, l1, l2, s1, s2, a]``; ``gamma``, ``modes``, ``beta_ref`` (3,) each. Fills the
    pose ``X`` (3,), the passive angles ``beta`` (3,), the velocity matrix ``A`` (3, 3) of
    ``A Xd = B Thetad`` and its inverse ``Ainv``. Returns ``(outcome, chain)``: one of the
    ``_OK`` ... ``_ASSEMBLY_MODE`` codes and the 0-based chain of a working-mode change.
    """
    h, l1, a = geo[0], geo[1], geo[5]
    l2sq = geo[2] * geo[2]
    Bx, By = np.empty(3), np.empty(3)
    for i in range(3):
        cg, sg = cos(gamma[i]), sin(gamma[i])
        th, z = Theta[i], Theta[3 + i]
        Bx[i] = z * cg - a * sg + l1 * cos(th)      # B_i = zeta e(g) + a n(g) + l1 e(theta)
        By[i] = z * sg + a * cg + l1 * sin(th)
    x, y, alpha = X_guess[0], X_guess[1], X_guess[2]
    F, J, Jinv = np.empty(3), np.empty((3, 3)), np.empty((3, 3))
    for it in range(max_iter + 1):
        worst = 0.0
        for i in range(3):
            phi = alpha + gamma[i]
            cp, sp = cos(phi), sin(phi)
            dx, dy = x - h * sp - Bx[i], y + h * cp - By[i]    # C_i - B_i, C_i = X + h n(phi)
            F[i] = dx * dx + dy * dy - l2sq
            J[i, 0], J[i, 1], J[i, 2] = 2.0 * dx, 2.0 * dy, -2.0 * h * (dx * cp + dy * sp)
            worst = max(worst, abs(F[i]))
        if worst < tol or it == max_iter:
            break
        if _inverse3(J, Jinv) == 0.0:
            break
        x -= Jinv[0, 0] * F[0] + Jinv[0, 1] * F[1] + Jinv[0, 2] * F[2]
        y -= Jinv[1, 0] * F[0] + Jinv[1, 1] * F[1] + Jinv[1, 2] * F[2]
        alpha -= Jinv[2, 0] * F[0] + Jinv[2, 1] * F[1] + Jinv[2, 2] * F[2]
    if not worst < 1e-12:
        return _NO_CONVERGENCE, -1
    for i in range(3):
        phi = alpha + gamma[i]
        Cx, Cy = x - h * sin(phi), y + h * cos(phi)
        th = Theta[i]
        rx, ry = Cx - (Bx[i] - l1 * cos(th)), Cy - (By[i] - l1 * sin(th))   # C_i - A_i
        if (rx * sin(th) - ry * cos(th)) * modes[i] <= 0:
            return _WORKING_MODE, i
        b = atan2(Cy - By[i], Cx - Bx[i])
        beta[i] = beta_ref[i] + _wrap(b - beta_ref[i])
    alpha = _wrap(alpha)
    X[0], X[1], X[2] = x, y, alpha
    for i in range(3):
        b = beta[i]
        A[i, 0], A[i, 1], A[i, 2] = cos(b), sin(b), h * sin(b - gamma[i] - alpha - 0.5 * pi)
    det = _inverse3(A, Ainv)
    if det == 0.0 or _norm1(A) * _norm1(Ainv) >= PARALLEL_SINGULAR:
        return _SINGULAR, -1
    if det * assembly_sign <= 0:
        return _ASSEMBLY_MODE, -1
    return _OK, -1


@numba.njit(cache=True, nogil=True)
def _add_body(M, c, w, row, acc):
    """``M += w row row^T``, ``c += w acc row``: one Jacobian row (6,) of a body, weighted by
    its mass or inertia, with its acceleration at zero actuated acceleration."""
    for r in range(6):
        wr = w * row[r]
        if wr != 0.0:
            c[r] += wr * acc
            for k in range(6):
                M[r, k] += wr * row[k]


@numba.njit((_V, _V, _V, _V, _V, _V, _V, _F, _V, _M, _V, _V), cache=True, nogil=True)
def _reduced_dynamics(Theta, Thetad, X_guess, geo, gamma, modes, beta_ref, assembly_sign, weights, M, c, X):
    """``M_r`` (6, 6) into ``M``, the velocity terms without friction (6,) into ``c``, the pose into
    ``X`` (3,); ``weights`` = ``[m_c, m_l1, I_l1, m_l2, I_l2, m_ee, I_ee]``, the rest as
    :func:`_forward`, whose ``(outcome, chain)`` it returns (``M``, ``c`` are filled on ``_OK`` only)."""
    beta, A, Ainv = np.empty(3), np.empty((3, 3)), np.empty((3, 3))
    outcome, chain = _forward(Theta, X_guess, geo, gamma, modes, beta_ref, assembly_sign, 1e-14, 50,
                              X, beta, A, Ainv)
    if outcome != _OK:
        return outcome, chain
    h, l1, l2, s1, s2 = geo[0], geo[1], geo[2], geo[3], geo[4]
    alpha = X[2]
    m_c, m_l1, I_l1, m_l2, I_l2, m_ee, I_ee = (weights[0], weights[1], weights[2], weights[3],
                                               weights[4], weights[5], weights[6])
    # J = A^-1 B (3 x 6): column i = Ainv[:, i] l1 sin(beta_i - theta_i), column 3+i = Ainv[:, i] cos(beta_i - gamma_i)
    Jm = np.empty((3, 6))
    for r in range(3):
        for i in range(3):
            Jm[r, i] = Ainv[r, i] * (l1 * sin(beta[i] - Theta[i]))
            Jm[r, 3 + i] = Ainv[r, i] * cos(beta[i] - gamma[i])
    Xd = np.zeros(3)
    for r in range(3):
        for k in range(6):
            Xd[r] += Jm[r, k] * Thetad[k]
    ad = Xd[2]
    # passive rates and the acceleration bias r of A Xdd = B Thetadd + r (Thetadd = 0)
    betad, rr = np.empty(3), np.empty(3)
    for i in range(3):
        b, th, thd, zd = beta[i], Theta[i], Thetad[i], Thetad[3 + i]
        ph = alpha + gamma[i]
        Cdx, Cdy = Xd[0] - h * ad * cos(ph), Xd[1] - h * ad * sin(ph)
        bd = (-sin(b) * Cdx + cos(b) * Cdy - zd * sin(gamma[i] - b) - l1 * thd * cos(b - th)) / l2
        betad[i] = bd
        rr[i] = -l1 * thd * thd * cos(b - th) - l2 * bd * bd + h * ad * ad * sin(b - alpha - gamma[i])
    Xdd = np.zeros(3)
    for r in range(3):
        for i in range(3):
            Xdd[r] += Ainv[r, i] * rr[i]
    add = Xdd[2]
    for r in range(6):
        c[r] = 0.0
        for k in range(6):
            M[r, k] = 0.0
    row, row2 = np.empty(6), np.empty(6)
    dbd = np.empty(6)
    for i in range(3):
        b, t, thd = beta[i], Theta[i], Thetad[i]
        cb, sb, ct, st = cos(b), sin(b), cos(t), sin(t)
        cp, sp = cos(alpha + gamma[i]), sin(alpha + gamma[i])
        egx, egy = cos(gamma[i]), sin(gamma[i])
        # dbetad_i/dThetad (6), from dCd_i/dThetad
        for k in range(6):
            dCx = Jm[0, k] - h * cp * Jm[2, k]
            dCy = Jm[1, k] - h * sp * Jm[2, k]
            dbd[k] = (-sb * dCx + cb * dCy) / l2
        dbd[3 + i] -= sin(gamma[i] - b) / l2
        dbd[i] -= l1 * cos(b - t) / l2
        # carriage: moves along its guide
        for k in range(6):
            row[k], row2[k] = 0.0, 0.0
        row[3 + i], row2[3 + i] = egx, egy
        _add_body(M, c, m_c, row, 0.0)
        _add_body(M, c, m_c, row2, 0.0)
        # link 1: the carriage's motion plus its rotation
        row[i], row2[i] = -s1 * st, s1 * ct
        _add_body(M, c, m_l1, row, -s1 * thd * thd * ct)
        _add_body(M, c, m_l1, row2, -s1 * thd * thd * st)
        for k in range(6):
            row[k] = 0.0
        row[i] = 1.0
        _add_body(M, c, I_l1, row, 0.0)
        # link 2, with betadd at zero actuated acceleration
        Cddx = Xdd[0] - h * add * cp + h * ad * ad * sp
        Cddy = Xdd[1] - h * add * sp - h * ad * ad * cp
        bdd = (-sb * Cddx + cb * Cddy + l1 * thd * thd * sin(t - b)) / l2
        for k in range(6):
            row[k] = -s2 * sb * dbd[k]
            row2[k] = s2 * cb * dbd[k]
        row[i] -= l1 * st
        row2[i] += l1 * ct
        row[3 + i] += egx
        row2[3 + i] += egy
        bd = betad[i]
        _add_body(M, c, m_l2, row, -l1 * thd * thd * ct - s2 * bdd * sb - s2 * bd * bd * cb)
        _add_body(M, c, m_l2, row2, -l1 * thd * thd * st + s2 * bdd * cb - s2 * bd * bd * sb)
        _add_body(M, c, I_l2, dbd, bdd)
    # end-effector
    for k in range(6):
        row[k] = Jm[0, k]
        row2[k] = Jm[1, k]
    _add_body(M, c, m_ee, row, Xdd[0])
    _add_body(M, c, m_ee, row2, Xdd[1])
    for k in range(6):
        row[k] = Jm[2, k]
    _add_body(M, c, I_ee, row, add)
    return _OK, -1


class SingleState:
    """Forward kinematics and reduced dynamics of one state of a 3PRRR.

    Args:
        kinematics: the robot's :class:`~.kinematics.Kinematics` (geometry, working and assembly
            modes, reference angles).
    """

    def __init__(self, kinematics: Kinematics):
        g = kinematics.geometry
        self._geo = np.array([g.h, g.l1, g.l2, g.s1, g.s2, g.a], dtype=float)
        self._gamma = np.array(kinematics.gamma, dtype=float)
        self._modes = np.array(kinematics.modes, dtype=float)
        self._beta_ref = np.array(kinematics._beta_ref, dtype=float)
        self._assembly_sign = float(kinematics._assembly_sign)
        # the inertial weights of the parameters last given (the plant gives the same object every
        # period): built once per parameter set, not every call
        self._weights: tuple[InertialParams, np.ndarray] | None = None

    def _raise(self, outcome: int, chain: int, X) -> None:
        if outcome == _NO_CONVERGENCE:
            raise KinematicsError("forward kinematics did not converge", sample=0)
        if outcome == _WORKING_MODE:
            raise KinematicsError("forward kinematics reached another working mode (give a closer X_guess)",
                                  chain=chain + 1, sample=0)
        if outcome == _SINGULAR:
            x, y, alpha = X
            raise SingularityError(f"parallel (type II) singularity: sample 0 at pose x={x:.6g} m, "
                                   f"y={y:.6g} m, alpha={alpha * 180 / pi:.6g} deg", sample=0)
        raise KinematicsError("forward kinematics reached another assembly mode (across a parallel "
                              "singularity; give a closer X_guess)", sample=0)

    def forward_kinematics(self, Theta, X_guess, tol: float = 1e-14, max_iter: int = 50):
        """Pose ``(x, y, alpha)`` and passive angles ``beta`` (3 each) by Newton from ``X_guess``.

        The checks are those of :meth:`.kinematics.Kinematics.forward_kinematics`; the parallel
        singularity is judged on the 1-norm condition number of ``A`` (within a factor 3 of the
        2-norm one for a 3x3 matrix).

        Raises:
            KinematicsError: no convergence, another working mode, or another assembly mode.
            SingularityError: a parallel (type II) singularity.
        """
        X, beta, A, Ainv = np.empty(3), np.empty(3), np.empty((3, 3)), np.empty((3, 3))
        c = np.ascontiguousarray
        outcome, chain = _forward(c(Theta, dtype=float), c(X_guess, dtype=float), self._geo, self._gamma,
                                  self._modes, self._beta_ref, self._assembly_sign, float(tol), int(max_iter),
                                  X, beta, A, Ainv)
        if outcome != _OK:
            self._raise(outcome, chain, X)
        return X, beta

    def reduced_dynamics(self, Theta, Thetad, params: InertialParams, X_guess) -> PlantState:
        """``M_r`` (6, 6), velocity terms ``c`` (6,) without friction, and the pose ``X`` (3,): a
        :class:`~ident_hw.model.interface.PlantState`.

        The same as :meth:`ident_hw.model.robot.ThreePRRR.reduced_dynamics_of` of a motion with zero actuated
        acceleration, less the friction.
        """
        if self._weights is None or self._weights[0] is not params:
            p = params
            self._weights = (p, np.array([p.m_c, p.m_l1, p.I_l1, p.m_l2, p.I_l2, p.m_ee, p.I_ee], dtype=float))
        weights = self._weights[1]
        M, c, X = np.empty((6, 6)), np.empty(6), np.empty(3)
        contiguous = np.ascontiguousarray
        outcome, chain = _reduced_dynamics(contiguous(Theta, dtype=float), contiguous(Thetad, dtype=float),
                                           contiguous(X_guess, dtype=float), self._geo, self._gamma, self._modes,
                                           self._beta_ref, self._assembly_sign, weights, M, c, X)
        if outcome != _OK:
            self._raise(outcome, chain, X)
        return PlantState(M, c, X)
