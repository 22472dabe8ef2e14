"""Closed-form kinematics of the 3PRRR (spec eqs. 1–14), vectorised over N samples.

Conventions (``docs/3prrr-model.md``): ``e(phi) = [cos, sin]``, ``n(phi) = [-sin, cos]``,

    A_i = zeta_i e(gamma_i) + a n(gamma_i)
    B_i = A_i + l1 e(theta_i)
    C_i = B_i + l2 e(beta_i) = [x, y] + h n(alpha + gamma_i)

Shapes: ``X`` (N, 3) = ``[x, y, alpha]`` (m, m, rad); ``zeta`` (N, 3) m; ``theta``, ``beta``
(N, 3) rad; ``Theta`` (N, 6) = ``[theta1..3, zeta1..3]``. Passive rates and accelerations come
from differentiating the closure analytically.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import KinematicsError, SingularityError, raise_at_first
from .parameters import Geometry

#: Below this ``|sin(beta_i - theta_i)|`` a chain is treated as singular (stretched or folded).
SERIAL_SINGULAR = 1e-9
#: Above this condition number of ``A`` the platform is treated as in a parallel singularity.
PARALLEL_SINGULAR = 1e9
#: Relative rounding allowed on the IK cosine before a pose counts as out of reach.
REACH_ROUNDING = 1e-12
#: Samples per block when forward kinematics continues a time series from one guess.
FK_BLOCK = 32


def e(phi: np.ndarray) -> np.ndarray:
    """Unit vectors ``[cos phi, sin phi]``, shape ``phi.shape + (2,)``."""
    out = np.empty(np.shape(phi) + (2,))
    np.cos(phi, out=out[..., 0])
    np.sin(phi, out=out[..., 1])
    return out


def n(phi: np.ndarray) -> np.ndarray:
    """Unit normals ``[-sin phi, cos phi]``, shape ``phi.shape + (2,)``."""
    out = np.empty(np.shape(phi) + (2,))
    np.sin(phi, out=out[..., 0])
    np.negative(out[..., 0], out=out[..., 0])
    np.cos(phi, out=out[..., 1])
    return out


def dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Dot product over the last axis."""
    return np.einsum("...k,...k->...", u, v)


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angle wrapped into ``(-pi, pi]``."""
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


def batch(array, width: int, name: str) -> np.ndarray:
    """``array`` as float (N, width); a single row of shape (width,) becomes (1, width)."""
    a = np.asarray(array, dtype=float)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != width:
        raise ValueError(f"{name} must have shape (N, {width}) or ({width},), got {np.shape(array)}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or inf (first at sample {int(np.argmax(~np.isfinite(a).all(1)))})")
    return a


@dataclass(frozen=True)
class Motion:
    """Every coordinate of the closed chain with its first two time derivatives.

    Pose ``X`` (N, 3); carriages ``zeta`` (N, 3); link angles ``theta``, ``beta`` (N, 3); each with
    ``d`` (velocity) and ``dd`` (acceleration) companions. ``A`` (N, 3, 3) and ``B`` (N, 3, 6) are
    the velocity matrices of ``A Xd = B Thetad``; ``J = A^-1 B`` (N, 3, 6).
    """

    X: np.ndarray
    Xd: np.ndarray
    Xdd: np.ndarray
    zeta: np.ndarray
    zetad: np.ndarray
    zetadd: np.ndarray
    theta: np.ndarray
    thetad: np.ndarray
    thetadd: np.ndarray
    beta: np.ndarray
    betad: np.ndarray
    betadd: np.ndarray
    A: np.ndarray
    B: np.ndarray
    J: np.ndarray

    @property
    def Theta(self) -> np.ndarray:
        return np.concatenate([self.theta, self.zeta], axis=1)

    @property
    def Thetad(self) -> np.ndarray:
        return np.concatenate([self.thetad, self.zetad], axis=1)

    @property
    def Thetadd(self) -> np.ndarray:
        return np.concatenate([self.thetadd, self.zetadd], axis=1)


@dataclass(frozen=True)
class SingularityMargins:
    """Distance to singularities, per sample.

    ``cond_A`` (N,): condition number of ``A`` (parallel, type II); ``cond_A_normalised`` (N,):
    the same with the third column divided by ``h`` (unitless); ``serial`` (N, 3):
    ``|sin(beta_i - theta_i)|`` (0 when chain ``i`` is stretched or folded).
    """

    cond_A: np.ndarray
    cond_A_normalised: np.ndarray
    serial: np.ndarray


class Kinematics:
    """Kinematics of one 3PRRR geometry."""

    def __init__(self, geometry: Geometry):
        self.geometry = geometry
        g = geometry
        self.gamma = np.array(g.gamma)
        self.modes = np.array(g.modes, dtype=float)
        self._eg = e(self.gamma)  # (3, 2) guide directions
        self._ng = n(self.gamma)
        # Reference angles at home (X = 0, zeta = 0): outputs are continuous within pi of them.
        self._theta_ref = np.zeros(3)
        self._beta_ref = np.zeros(3)
        theta, beta = self._raw_ik(np.zeros((1, 3)), np.zeros((1, 3)))
        self._theta_ref, self._beta_ref = theta[0], beta[0]
        A_home, _ = self.velocity_matrices(np.zeros((1, 3)), theta, beta)
        self._assembly_sign = np.sign(np.linalg.det(A_home[0]))

    # -- points -------------------------------------------------------------------------------
    def base_points(self, zeta: np.ndarray) -> np.ndarray:
        """``A_i`` (N, 3, 2) for carriages ``zeta`` (N, 3)."""
        return zeta[..., None] * self._eg + self.geometry.a * self._ng

    def elbow_points(self, theta: np.ndarray, zeta: np.ndarray) -> np.ndarray:
        """``B_i`` (N, 3, 2)."""
        return self.base_points(zeta) + self.geometry.l1 * e(theta)

    def platform_points(self, X: np.ndarray) -> np.ndarray:
        """``C_i`` (N, 3, 2) for poses ``X`` (N, 3)."""
        return X[:, None, :2] + self.geometry.h * n(X[:, 2:3] + self.gamma)

    def closure_residual(self, X, Theta) -> np.ndarray:
        """Largest closure error ``|g_i|`` over the chains, (N,) in m, given ``X`` and ``Theta``."""
        X, Theta = batch(X, 3, "X"), batch(Theta, 6, "Theta")
        theta, zeta = Theta[:, :3], Theta[:, 3:]
        C = self.platform_points(X)
        B = self.elbow_points(theta, zeta)
        # beta is passive: the residual of chain i is the error of |C_i - B_i| = l2.
        return np.abs(np.linalg.norm(C - B, axis=-1) - self.geometry.l2).max(axis=1)

    # -- inverse kinematics (eqs. 1–7) ----------------------------------------------------------
    def _raw_ik(self, X: np.ndarray, zeta: np.ndarray):
        g = self.geometry
        rho = self.platform_points(X) - self.base_points(zeta)
        r = np.linalg.norm(rho, axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            cos_arg = (r**2 + g.l1**2 - g.l2**2) / (2.0 * g.l1 * r)
        # a chain exactly stretched or folded may round past 1: that is a singularity, not out of reach
        out_of_reach = ~(np.abs(cos_arg) <= 1.0 + REACH_ROUNDING)
        raise_at_first(out_of_reach, KinematicsError, "pose out of reach (IK discriminant negative)", X)
        psi = np.arctan2(rho[..., 1], rho[..., 0])
        theta = psi + self.modes * np.arccos(np.clip(cos_arg, -1.0, 1.0))
        theta = self._theta_ref + wrap(theta - self._theta_ref)
        d = rho - g.l1 * e(theta)
        beta = np.arctan2(d[..., 1], d[..., 0])
        beta = self._beta_ref + wrap(beta - self._beta_ref)
        return theta, beta

    def inverse_kinematics(self, X, zeta):
        """Link angles ``theta``, ``beta`` (N, 3) for poses ``X`` (N, 3) and carriages ``zeta`` (N, 3).

        Raises :class:`KinematicsError` for a pose out of reach and :class:`SingularityError` for a
        chain stretched or folded, naming the chain and the sample.
        """
        X, zeta = batch(X, 3, "X"), batch(zeta, 3, "zeta")
        theta, beta = self._raw_ik(X, zeta)
        raise_at_first(np.abs(np.sin(beta - theta)) < SERIAL_SINGULAR, SingularityError,
                       "serial singularity (chain stretched or folded)", X)
        return theta, beta

    # -- velocity relation (eqs. 10–14) ---------------------------------------------------------
    def velocity_matrices(self, X, theta, beta):
        """``A`` (N, 3, 3) and ``B`` (N, 3, 6) of ``A Xd = B Thetad``."""
        g = self.geometry
        N = X.shape[0]
        A = np.empty((N, 3, 3))
        A[..., 0] = np.cos(beta)
        A[..., 1] = np.sin(beta)
        A[..., 2] = g.h * np.sin(beta - self.gamma - X[:, 2:3] - np.pi / 2)
        B = np.zeros((N, 3, 6))
        idx = np.arange(3)
        B[:, idx, idx] = g.l1 * np.sin(beta - theta)
        B[:, idx, idx + 3] = np.cos(beta - self.gamma)
        return A, B

    def _jacobian_from(self, X, A, B):
        s = np.linalg.svd(A, compute_uv=False)
        with np.errstate(divide="ignore"):
            cond = s[:, 0] / s[:, -1]
        raise_at_first(~(cond < PARALLEL_SINGULAR), SingularityError, "parallel (type II) singularity", X)
        return np.linalg.solve(A, B)

    def jacobian(self, X, zeta) -> np.ndarray:
        """``J = A^-1 B`` (N, 3, 6) with ``Xd = J Thetad``."""
        X, zeta = batch(X, 3, "X"), batch(zeta, 3, "zeta")
        theta, beta = self.inverse_kinematics(X, zeta)
        A, B = self.velocity_matrices(X, theta, beta)
        return self._jacobian_from(X, A, B)

    def singularity_margins(self, X, zeta) -> SingularityMargins:
        """Parallel and serial singularity margins (see :class:`SingularityMargins`)."""
        X, zeta = batch(X, 3, "X"), batch(zeta, 3, "zeta")
        theta, beta = self._raw_ik(X, zeta)
        A, _ = self.velocity_matrices(X, theta, beta)
        An = A.copy()
        An[..., 2] /= self.geometry.h
        with np.errstate(divide="ignore"):
            cond = np.linalg.cond(A)
            cond_n = np.linalg.cond(An)
        return SingularityMargins(cond, cond_n, np.abs(np.sin(beta - theta)))

    # -- full motion ---------------------------------------------------------------------------
    def motion_from_pose(self, X, Xd, Xdd, zeta, zetad, zetadd) -> Motion:
        """All coordinates and rates from the pose and carriage motion (each (N, 3))."""
        X, Xd, Xdd = (batch(v, 3, name) for v, name in ((X, "X"), (Xd, "Xd"), (Xdd, "Xdd")))
        zeta, zetad, zetadd = (batch(v, 3, name) for v, name in ((zeta, "zeta"), (zetad, "zetad"), (zetadd, "zetadd")))
        theta, beta = self.inverse_kinematics(X, zeta)
        A, B = self.velocity_matrices(X, theta, beta)
        J = self._jacobian_from(X, A, B)
        l1_sin = B[:, [0, 1, 2], [0, 1, 2]]
        cos_bg = B[:, [0, 1, 2], [3, 4, 5]]
        thetad = (np.einsum("nij,nj->ni", A, Xd) - cos_bg * zetad) / l1_sin
        betad = self._betad(X, Xd, zetad, theta, thetad, beta)
        r = self._acceleration_bias(X, Xd, theta, thetad, beta, betad)
        thetadd = (np.einsum("nij,nj->ni", A, Xdd) - r - cos_bg * zetadd) / l1_sin
        betadd = self._betadd(X, Xd, Xdd, zetadd, theta, thetad, thetadd, beta, betad)
        return Motion(X, Xd, Xdd, zeta, zetad, zetadd, theta, thetad, thetadd, beta, betad, betadd, A, B, J)

    def motion_from_actuated(self, Theta, Thetad, Thetadd, X_guess) -> Motion:
        """All coordinates and rates from the actuated motion (each (N, 6)); pose by forward kinematics."""
        Theta, Thetad, Thetadd = (batch(v, 6, name) for v, name in
                                  ((Theta, "Theta"), (Thetad, "Thetad"), (Thetadd, "Thetadd")))
        X, beta = self._forward_kinematics(Theta, X_guess)
        theta, zeta = Theta[:, :3], Theta[:, 3:]
        thetad, zetad = Thetad[:, :3], Thetad[:, 3:]
        A, B = self.velocity_matrices(X, theta, beta)
        J = self._jacobian_from(X, A, B)
        Xd = np.einsum("nij,nj->ni", J, Thetad)
        betad = self._betad(X, Xd, zetad, theta, thetad, beta)
        r = self._acceleration_bias(X, Xd, theta, thetad, beta, betad)
        Xdd = np.linalg.solve(A, (np.einsum("nij,nj->ni", B, Thetadd) + r)[..., None])[..., 0]
        thetadd = Thetadd[:, :3]
        betadd = self._betadd(X, Xd, Xdd, Thetadd[:, 3:], theta, thetad, thetadd, beta, betad)
        return Motion(X, Xd, Xdd, zeta, zetad, Thetadd[:, 3:], theta, thetad, thetadd, beta, betad, betadd, A, B, J)

    def _platform_velocity(self, X, Xd):
        """``Cd_i`` (N, 3, 2)."""
        phi = X[:, 2:3] + self.gamma
        return Xd[:, None, :2] - self.geometry.h * Xd[:, 2:3, None] * e(phi)

    def _platform_acceleration(self, X, Xd, Xdd):
        """``Cdd_i`` (N, 3, 2)."""
        phi = X[:, 2:3] + self.gamma
        h = self.geometry.h
        return Xdd[:, None, :2] - h * Xdd[:, 2:3, None] * e(phi) - h * (Xd[:, 2:3, None] ** 2) * n(phi)

    def _betad(self, X, Xd, zetad, theta, thetad, beta):
        g = self.geometry
        nb = n(beta)
        Cd = self._platform_velocity(X, Xd)
        return (dot(nb, Cd) - zetad * np.sin(self.gamma - beta) - g.l1 * thetad * np.cos(beta - theta)) / g.l2

    def _acceleration_bias(self, X, Xd, theta, thetad, beta, betad):
        """``r`` (N, 3) of ``A Xdd = B Thetadd + r``."""
        g = self.geometry
        return (-g.l1 * thetad**2 * np.cos(beta - theta) - g.l2 * betad**2
                + g.h * Xd[:, 2:3] ** 2 * np.sin(beta - X[:, 2:3] - self.gamma))

    def _betadd(self, X, Xd, Xdd, zetadd, theta, thetad, thetadd, beta, betad):
        g = self.geometry
        Cdd = self._platform_acceleration(X, Xd, Xdd)
        return (dot(n(beta), Cdd) - zetadd * np.sin(self.gamma - beta) - g.l1 * thetadd * np.cos(beta - theta)
                + g.l1 * thetad**2 * np.sin(theta - beta)) / g.l2

    # -- forward kinematics ---------------------------------------------------------------------
    def _newton(self, X, theta, zeta, tol=1e-14, max_iter=50):
        """Newton on ``|C_i(X) - B_i|^2 = l2^2``; returns X and a per-sample convergence mask."""
        g = self.geometry
        B = self.elbow_points(theta, zeta)
        X = X.copy()
        for _ in range(max_iter):
            d = self.platform_points(X) - B  # (N, 3, 2)
            F = dot(d, d) - g.l2**2
            if np.all(np.abs(F) < tol):
                break
            Jac = np.empty(X.shape[:1] + (3, 3))
            Jac[..., :2] = 2.0 * d
            Jac[..., 2] = -2.0 * g.h * dot(d, e(X[:, 2:3] + self.gamma))
            with np.errstate(all="ignore"):
                step = np.linalg.solve(Jac, F[..., None])[..., 0]
            X -= np.where(np.isfinite(step), step, 0.0)
        d = self.platform_points(X) - B
        return X, np.abs(dot(d, d) - g.l2**2).max(axis=1) < 1e-12

    def forward_kinematics(self, Theta, X_guess) -> np.ndarray:
        """Pose ``X`` (N, 3) for actuated coordinates ``Theta`` (N, 6), by Newton's method.

        ``X_guess`` (N, 3) gives a start per sample; a single (3,) guess starts a continuation
        along the series (blocks of :data:`FK_BLOCK` samples, each started from the previous
        block's last pose), which suits a time series. The result is checked to lie in the
        configured working modes; otherwise :class:`KinematicsError` names the sample.
        """
        return self._forward_kinematics(batch(Theta, 6, "Theta"), X_guess)[0]

    def _forward_kinematics(self, Theta, X_guess):
        """Pose ``X`` (N, 3) and passive angles ``beta`` (N, 3) of a batch ``Theta``."""
        theta, zeta = Theta[:, :3], Theta[:, 3:]
        guess = np.asarray(X_guess, dtype=float)
        if guess.ndim == 2:
            X, ok = self._newton(batch(guess, 3, "X_guess"), theta, zeta)
        else:
            start = batch(guess, 3, "X_guess")[0]
            X = np.empty((len(Theta), 3))
            ok = np.empty(len(Theta), dtype=bool)
            for b in range(0, len(Theta), FK_BLOCK):
                sl = slice(b, b + FK_BLOCK)
                X[sl], ok[sl] = self._newton(np.repeat(start[None], len(Theta[sl]), 0), theta[sl], zeta[sl])
                start = X[sl][-1] if ok[sl][-1] else start
        raise_at_first(~ok, KinematicsError, "forward kinematics did not converge")
        # Working mode m_i of eq. 6: theta_i = psi_i + m_i acos(...), so sin(theta_i - psi_i) has the sign m_i.
        rho = self.platform_points(X) - self.base_points(zeta)
        side = rho[..., 0] * np.sin(theta) - rho[..., 1] * np.cos(theta)
        raise_at_first(side * self.modes <= 0, KinematicsError,
                       "forward kinematics reached another working mode (give a closer X_guess)", X)
        d = rho - self.geometry.l1 * e(theta)
        beta = self._beta_ref + wrap(np.arctan2(d[..., 1], d[..., 0]) - self._beta_ref)
        X[:, 2] = wrap(X[:, 2])
        # Assembly mode of the platform: det(A) changes sign only across a parallel singularity.
        A, _ = self.velocity_matrices(X, theta, beta)
        raise_at_first(np.linalg.det(A) * self._assembly_sign <= 0, KinematicsError,
                       "forward kinematics reached another assembly mode (across a parallel singularity; "
                       "give a closer X_guess)", X)
        return X, beta
