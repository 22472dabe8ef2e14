"""The reduced dynamics of ONE state, for a simulator's inner loop.

:meth:`ThreePRRR.reduced_dynamics` is vectorised over N samples: for N = 1 its cost is a few
hundred NumPy calls of a few microseconds each, which a simulated rig pays once per SYNC period.
:class:`SingleState` computes the same quantities (forward kinematics by Newton, passive rates,
body Jacobians, ``M_r`` and the velocity terms) in plain floats, the equations term for term
those of :mod:`.kinematics` and :mod:`.dynamics` (spec eqs. 1–35), with one small matrix product
at the end. ``tests/test_model_single.py`` holds the two routes equal.

Shapes: ``Theta``, ``Thetad`` (6,) ``[theta1..3 (rad), zeta1..3 (m)]``; pose ``X`` (3,)
``[x, y, alpha]``; ``M`` (6, 6), ``c`` (6,) in N·m for the links and N for the carriages.
"""

from __future__ import annotations

from math import atan2, cos, pi, sin

import numpy as np

from .errors import KinematicsError, SingularityError
from .kinematics import PARALLEL_SINGULAR, Kinematics
from .parameters import InertialParams

_TWO_PI = 2.0 * pi


def _wrap(angle: float) -> float:
    """``angle`` wrapped into ``(-pi, pi]``, as :func:`.kinematics.wrap`."""
    return pi - (pi - angle) % _TWO_PI


class SingleState:
    """Forward kinematics and reduced dynamics of one state of a 3PRRR.

    Args:
        kinematics: the robot's :class:`~.kinematics.Kinematics` (geometry, working and assembly
            modes, reference angles).
    """

    def __init__(self, kinematics: Kinematics):
        g = kinematics.geometry
        self._g = g
        self._gamma = [float(v) for v in kinematics.gamma]
        self._cg = [cos(v) for v in self._gamma]
        self._sg = [sin(v) for v in self._gamma]
        self._modes = [float(v) for v in kinematics.modes]
        self._beta_ref = [float(v) for v in kinematics._beta_ref]
        self._assembly_sign = float(kinematics._assembly_sign)

    def forward_kinematics(self, Theta, X_guess, tol: float = 1e-14, max_iter: int = 50):
        """Pose ``(x, y, alpha)`` and passive angles ``beta`` (3 floats each) by Newton from ``X_guess``.

        The checks are those of :meth:`.kinematics.Kinematics.forward_kinematics`; the parallel
        singularity is judged on the 1-norm condition number of ``A`` (within a factor 3 of the
        2-norm one for a 3x3 matrix).

        Raises:
            KinematicsError: no convergence, another working mode, or another assembly mode.
            SingularityError: a parallel (type II) singularity.
        """
        g = self._g
        h, l1, l2sq = g.h, g.l1, g.l2 * g.l2
        cg, sg = self._cg, self._sg
        Bx, By = [], []
        for i in range(3):
            th, z = Theta[i], Theta[3 + i]
            Bx.append(z * cg[i] - g.a * sg[i] + l1 * cos(th))     # B_i = zeta e(g) + a n(g) + l1 e(theta)
            By.append(z * sg[i] + g.a * cg[i] + l1 * sin(th))
        x, y, alpha = (float(v) for v in X_guess)
        for _ in range(max_iter + 1):
            F, J = [], []
            for i in range(3):
                phi = alpha + self._gamma[i]
                cp, sp = cos(phi), sin(phi)
                dx, dy = x - h * sp - Bx[i], y + h * cp - By[i]    # C_i - B_i, C_i = X + h n(phi)
                F.append(dx * dx + dy * dy - l2sq)
                J.append((2.0 * dx, 2.0 * dy, -2.0 * h * (dx * cp + dy * sp)))
            if max(abs(f) for f in F) < tol:
                break
            if _ == max_iter:
                break
            step = _solve3(J, F)
            if step is None:
                break
            x, y, alpha = x - step[0], y - step[1], alpha - step[2]
        if not max(abs(f) for f in F) < 1e-12:
            raise KinematicsError("forward kinematics did not converge", sample=0)
        beta = []
        for i in range(3):
            phi = alpha + self._gamma[i]
            Cx, Cy = x - h * sin(phi), y + h * cos(phi)
            rx, ry = Cx - (Bx[i] - l1 * cos(Theta[i])), Cy - (By[i] - l1 * sin(Theta[i]))   # C_i - A_i
            th = Theta[i]
            if (rx * sin(th) - ry * cos(th)) * self._modes[i] <= 0:
                raise KinematicsError("forward kinematics reached another working mode (give a closer X_guess)",
                                      chain=i + 1, sample=0)
            b = atan2(Cy - By[i], Cx - Bx[i])
            beta.append(self._beta_ref[i] + _wrap(b - self._beta_ref[i]))
        alpha = _wrap(alpha)
        A = [(cos(b), sin(b), h * sin(b - gam - alpha - 0.5 * pi)) for b, gam in zip(beta, self._gamma)]
        Ainv, det = _inverse3(A)
        if Ainv is None or _cond1(A, Ainv) >= PARALLEL_SINGULAR:
            raise SingularityError(f"parallel (type II) singularity: sample 0 at pose x={x:.6g} m, "
                                   f"y={y:.6g} m, alpha={alpha * 180 / pi:.6g} deg", sample=0)
        if det * self._assembly_sign <= 0:
            raise KinematicsError("forward kinematics reached another assembly mode (across a parallel "
                                  "singularity; give a closer X_guess)", sample=0)
        self._A, self._Ainv = A, Ainv
        return (x, y, alpha), beta

    def reduced_dynamics(self, Theta, Thetad, params: InertialParams, X_guess):
        """``M_r`` (6, 6), velocity terms ``c`` (6,) without friction, and the pose ``X`` (3,).

        The same as :meth:`ThreePRRR.reduced_dynamics_of` of a motion with zero actuated
        acceleration, less the friction.
        """
        g = self._g
        h, l1, l2, s1, s2 = g.h, g.l1, g.l2, g.s1, g.s2
        Theta = [float(v) for v in Theta]
        Thetad = [float(v) for v in Thetad]
        (x, y, alpha), beta = self.forward_kinematics(Theta, X_guess)
        th, thd, zd = Theta[:3], Thetad[:3], Thetad[3:]
        gam = self._gamma
        # velocity matrices A (3x3, with its inverse from the forward kinematics) and B (its
        # diagonal blocks) of A Xd = B Thetad
        Ainv = self._Ainv
        Bt, Bz, ph = [], [], []
        for i in range(3):
            b = beta[i]
            Bt.append(l1 * sin(b - th[i]))
            Bz.append(cos(b - gam[i]))
            ph.append(alpha + gam[i])
        # J = A^-1 B (3 x 6): column i = Ainv[:, i] Bt_i, column 3+i = Ainv[:, i] Bz_i
        Jm = [[0.0] * 6 for _ in range(3)]
        for r in range(3):
            for i in range(3):
                Jm[r][i] = Ainv[r][i] * Bt[i]
                Jm[r][3 + i] = Ainv[r][i] * Bz[i]
        Xd = [sum(Jm[r][k] * Thetad[k] for k in range(6)) for r in range(3)]
        ad = Xd[2]
        # passive rates and the acceleration bias r of A Xdd = B Thetadd + r (Thetadd = 0)
        betad, rr = [], []
        for i in range(3):
            b = beta[i]
            nbx, nby = -sin(b), cos(b)
            cp, sp = cos(ph[i]), sin(ph[i])
            Cdx, Cdy = Xd[0] - h * ad * cp, Xd[1] - h * ad * sp
            bd = (nbx * Cdx + nby * Cdy - zd[i] * sin(gam[i] - b) - l1 * thd[i] * cos(b - th[i])) / l2
            betad.append(bd)
            rr.append(-l1 * thd[i] ** 2 * cos(b - th[i]) - l2 * bd * bd + h * ad * ad * sin(b - alpha - gam[i]))
        Xdd = [sum(Ainv[r][i] * rr[i] for i in range(3)) for r in range(3)]
        add = Xdd[2]
        # body Jacobian rows (6 each) and their accelerations, weighted by their parameter
        p = params
        rows, acc, weight = [], [], []

        def body(w, jac_rows, accelerations):
            rows.extend(jac_rows)
            acc.extend(accelerations)
            weight.extend([w] * len(jac_rows))

        for i in range(3):
            b, t = beta[i], th[i]
            cb, sb, ct, st = cos(b), sin(b), cos(t), sin(t)
            cp, sp = cos(ph[i]), sin(ph[i])
            # dCd_i/dThetad (2 x 6) and dbetad_i/dThetad (6)
            dCx = [Jm[0][k] - h * cp * Jm[2][k] for k in range(6)]
            dCy = [Jm[1][k] - h * sp * Jm[2][k] for k in range(6)]
            dbd = [(-sb * dCx[k] + cb * dCy[k]) / l2 for k in range(6)]
            dbd[3 + i] -= sin(gam[i] - b) / l2
            dbd[i] -= l1 * cos(b - t) / l2
            egx, egy = self._cg[i], self._sg[i]
            carriage_x = [0.0] * 6
            carriage_y = [0.0] * 6
            carriage_x[3 + i], carriage_y[3 + i] = egx, egy
            body(p.m_c, [carriage_x, carriage_y], [0.0, 0.0])
            l1x, l1y = list(carriage_x), list(carriage_y)
            l1x[i], l1y[i] = -s1 * st, s1 * ct
            body(p.m_l1, [l1x, l1y], [-s1 * thd[i] ** 2 * ct, -s1 * thd[i] ** 2 * st])
            rot1 = [0.0] * 6
            rot1[i] = 1.0
            body(p.I_l1, [rot1], [0.0])
            # betadd with zero actuated acceleration
            Cddx = Xdd[0] - h * add * cp + h * ad * ad * sp
            Cddy = Xdd[1] - h * add * sp - h * ad * ad * cp
            bdd = (-sb * Cddx + cb * Cddy + l1 * thd[i] ** 2 * sin(t - b)) / l2
            l2x = [-s2 * sb * dbd[k] for k in range(6)]
            l2y = [s2 * cb * dbd[k] for k in range(6)]
            l2x[i] -= l1 * st
            l2y[i] += l1 * ct
            l2x[3 + i] += egx
            l2y[3 + i] += egy
            bd = betad[i]
            body(p.m_l2, [l2x, l2y], [-l1 * thd[i] ** 2 * ct - s2 * bdd * sb - s2 * bd * bd * cb,
                                       -l1 * thd[i] ** 2 * st + s2 * bdd * cb - s2 * bd * bd * sb])
            body(p.I_l2, [dbd], [bdd])
        body(p.m_ee, [Jm[0], Jm[1]], [Xdd[0], Xdd[1]])
        body(p.I_ee, [Jm[2]], [add])
        W = np.array(rows)
        w = np.array(weight)
        M = W.T @ (w[:, None] * W)
        c = W.T @ (w * np.array(acc))
        return M, c, np.array((x, y, alpha))


def _solve3(J, F):
    """``J^-1 F`` for a 3x3 ``J`` (rows) by the adjugate; ``None`` when singular."""
    inv, det = _inverse3(J)
    if inv is None:
        return None
    return [inv[r][0] * F[0] + inv[r][1] * F[1] + inv[r][2] * F[2] for r in range(3)]


def _inverse3(m):
    """Inverse of a 3x3 matrix (rows) and its determinant; ``(None, 0.0)`` when singular."""
    (a, b, c), (d, e, f), (g, h, i) = m
    co00, co01, co02 = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * co00 + b * co01 + c * co02
    if det == 0.0 or det != det:
        return None, 0.0
    r = 1.0 / det
    return ((co00 * r, (c * h - b * i) * r, (b * f - c * e) * r),
            (co01 * r, (a * i - c * g) * r, (c * d - a * f) * r),
            (co02 * r, (b * g - a * h) * r, (a * e - b * d) * r)), det


def _cond1(m, inv) -> float:
    """Condition number of a 3x3 matrix in the 1-norm (largest column sum of absolute values)."""
    def norm1(x):
        return max(abs(x[0][k]) + abs(x[1][k]) + abs(x[2][k]) for k in range(3))
    return norm1(m) * norm1(inv)
