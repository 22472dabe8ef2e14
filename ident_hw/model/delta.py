"""The 3-DOF Delta robot of the SVD-DLS paper: kinematics and virtual-work dynamics in regressor
form (``docs/delta-model.md`` restates the equations with the paper's typos fixed).

Conventions: world ``z`` up, gravity ``[0, 0, -g]``, base plane ``z = 0`` with the platform below
it; arm angle ``q_i`` below the horizontal (0 = horizontal), limb ``i`` at azimuth ``psi_i``;
``tau_i`` the torque on arm ``i`` about its motor axis ``y_i``. Every function takes a batch:
positions ``(N, 3)`` (or one sample ``(3,)``, returned without the batch axis).

Parameters ``pi`` (79,): seven bodies ``arm1..3, rod1..3, plat``, each
``[m, mx, my, mz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` (kg, kg·m, kg·m²: first moment ``m c`` and the
inertia about the body frame's origin, in body axes), then the drive terms
``fv_1..3`` (N·m·s/rad), ``fc_1..3`` (N·m), ``Jm_1..3`` (kg·m², reflected rotor inertia).
``tau = Y(q, qd, qdd) @ pi`` with ``Y`` of shape (N, 3, 79).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from types import ModuleType

import numpy as np

from .base_basis import BaseBasis
from .dynamics import smooth_sign
from .interface import REVOLUTE, PlantState
from .pseudo_inertia import SPATIAL, PhysicalBody
from .errors import KinematicsError, SingularityError

GRAVITY = 9.81  # m/s²
#: the seven bodies, in the order of the parameter vector
BODIES = ("arm1", "arm2", "arm3", "rod1", "rod2", "rod3", "plat")
BODY_PARAMS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")
DRIVE_PARAMS = tuple(f"{kind}_{i}" for kind in ("fv", "fc", "Jm") for i in (1, 2, 3))
#: the 79 parameters: ten per body (:data:`BODIES`), then ``fv_i``, ``fc_i``, ``Jm_i`` of each drive
PARAM_NAMES = tuple(f"{b}.{p}" for b in BODIES for p in BODY_PARAMS) + DRIVE_PARAMS
N_BODY_PARAMS = 10 * len(BODIES)           # 70
N_PARAMS = len(PARAM_NAMES)                # 79
ACTUATOR_NAMES = ("q1", "q2", "q3")

_EZ = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class DeltaGeometry:
    """Lengths in m, azimuths in rad (the paper's Table 1; ``r`` and ``psi`` chosen)."""

    L1: float = 0.309                                   # upper arm, actuated joint to elbow
    L2: float = 0.595                                   # parallelogram, elbow to platform joint
    R: float = 0.140                                    # radius of the actuated joints
    r: float = 0.035                                    # radius of the platform joints
    psi: tuple[float, float, float] = (0.0, 2 * math.pi / 3, 4 * math.pi / 3)


def body_parameters(mass: float, com, inertia_about_origin) -> np.ndarray:
    """One body's 10 parameters from its mass (kg), centre of mass ``com`` (3,) in body axes (m)
    and inertia about the frame origin ``[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` (kg·m²)."""
    return np.concatenate([[mass], mass * np.asarray(com, float), np.asarray(inertia_about_origin, float)])


def inertia_about_origin(mass: float, com, inertia_about_com) -> np.ndarray:
    """Parallel axis: ``I_O = I_G + m (|c|² 1 - c cᵀ)`` as ``[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]``."""
    c = np.asarray(com, float)
    Ig = _sym(np.asarray(inertia_about_com, float))
    Io = Ig + mass * (c @ c * np.eye(3) - np.outer(c, c))
    return Io[[0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]


def nominal_parameters(geometry: DeltaGeometry = DeltaGeometry()) -> np.ndarray:
    """(79,) the paper's Table 1 robot as the spec reads it: arm and rod centres of mass at half
    their length, the tabulated inertias about the frame origin, no drive terms."""
    arm = body_parameters(0.781, (geometry.L1 / 2, 0, 0), (3.0e-3, 8.8e-4, 2.0e-3, 2.5e-2, 4.0e-3, 2.7e-2))
    rod = body_parameters(1.666, (geometry.L2 / 2, 0, 0), (5.2e-2, 2.0e-2, 2.8e-2, 2.6e-1, 1.2e-2, 2.2e-1))
    plat = body_parameters(0.637, (0, 0, 0), (0,) * 6)
    return np.concatenate([arm, arm, arm, rod, rod, rod, plat, np.zeros(9)])


def physical_parameters(geometry: DeltaGeometry = DeltaGeometry()) -> np.ndarray:
    """(79,) the robot of :func:`nominal_parameters` made physical: read as printed, Table 1's
    products of inertia make the arm and the rod unrealisable (their pseudo-inertias have a
    negative eigenvalue, ``docs/delta-model.md``), so no physically consistent parameter set can
    reproduce their base parameters. Here the arm's products are a fifth of the table's and the
    rod's ``Ixy`` 0.016 with ``Ixz`` negative (the signs are lost in the table): the masses,
    centres of mass and diagonal inertias are the table's. The configs' Delta (CAD and
    simulated truth) is this one."""
    arm = body_parameters(0.781, (geometry.L1 / 2, 0, 0), (3.0e-3, 1.76e-4, 4.0e-4, 2.5e-2, 8.0e-4, 2.7e-2))
    rod = body_parameters(1.666, (geometry.L2 / 2, 0, 0), (5.2e-2, 1.6e-2, -2.8e-2, 2.6e-1, 1.2e-2, 2.2e-1))
    plat = body_parameters(0.637, (0, 0, 0), (0,) * 6)
    return np.concatenate([arm, arm, arm, rod, rod, rod, plat, np.zeros(9)])


def closed_form_base(geometry: DeltaGeometry = DeltaGeometry(), drive_terms: bool = True) -> BaseBasis:
    """34 base parameters of the bodies (one common, eleven per limb), plus ``fv_i``, ``fc_i``
    with the drive terms (40; ``Jm_i`` joins ``arm_i.Iyy``)."""
    L1, L2 = geometry.L1, geometry.L2
    index = {name: k for k, name in enumerate(PARAM_NAMES)}
    rows: list[tuple[str, dict[str, float]]] = [
        ("plat.m", {"plat.m": 1.0, **{f"rod{i}.m": 1.0 for i in (1, 2, 3)},
                    **{f"rod{i}.mx": -1.0 / L2 for i in (1, 2, 3)}})]
    for i in (1, 2, 3):
        arm, rod = f"arm{i}.", f"rod{i}."
        rows.append((arm + "mx", {arm + "mx": 1.0, rod + "mx": L1 / L2}))
        rows.append((arm + "mz", {arm + "mz": 1.0}))
        rows.append((arm + "Iyy", {arm + "Iyy": 1.0, rod + "mx": L1**2 / L2,
                                   **({f"Jm_{i}": 1.0} if drive_terms else {})}))
        rows += [(rod + p, {rod + p: 1.0}) for p in ("my", "mz", "Ixx", "Ixy", "Ixz", "Iyz")]
        rows.append((rod + "Iyy", {rod + "Iyy": 1.0, rod + "mx": -L2}))
        rows.append((rod + "Izz", {rod + "Izz": 1.0, rod + "mx": -L2}))
    if drive_terms:
        rows += [(f"{kind}_{i}", {f"{kind}_{i}": 1.0}) for i in (1, 2, 3) for kind in ("fv", "fc")]
    H = np.zeros((len(rows), N_PARAMS))
    for r, (_, terms) in enumerate(rows):
        for name, coef in terms.items():
            H[r, index[name]] = coef
    return BaseBasis(PARAM_NAMES, tuple(k for k, _ in rows), H)


@dataclass(frozen=True)
class Bodies:
    """The seven bodies' motion along a batch (N samples), in the order of :data:`BODIES`.

    ``origin`` (7, N, 3) m; ``Q`` (7, N, 3, 3) body axes in world; ``v``, ``a`` (7, N, 3) velocity
    and acceleration of the origin; ``omega``, ``alpha`` (7, N, 3) rad/s, rad/s²; ``J`` (7, N, 6, 3):
    ``[v; omega] = J @ qd``.
    """

    origin: np.ndarray
    Q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    J: np.ndarray


class Delta:
    """The Delta's kinematics, Jacobians, singularity measures, regressor and dynamics.

    Args:
        geometry: lengths and azimuths.
        coulomb_width: velocity scale (rad/s) of the smooth Coulomb sign ``tanh(qd / w)``.
        gravity: m/s², acting along ``-z``.
    """

    actuator_names: tuple[str, ...] = ACTUATOR_NAMES
    actuator_kinds: tuple[str, ...] = (REVOLUTE,) * 3
    parameter_names = PARAM_NAMES
    pose_size = 3

    def __init__(self, geometry: DeltaGeometry = DeltaGeometry(), coulomb_width: float = 0.01,
                 gravity: float = GRAVITY) -> None:
        self.geometry = geometry
        self.coulomb_width = coulomb_width
        self.g = np.array([0.0, 0.0, -gravity])
        psi = np.asarray(geometry.psi, float)
        self._e = np.stack([np.cos(psi), np.sin(psi), np.zeros(3)], axis=1)     # (3 limbs, 3) radial
        self._y = np.stack([-np.sin(psi), np.cos(psi), np.zeros(3)], axis=1)    # motor axes
        self._R = np.stack([self._e, self._y, np.tile(_EZ, (3, 1))], axis=2)   # (3, 3, 3): columns e, y, z
        self._A = geometry.R * self._e
        self._single_geo = np.array([geometry.L1, geometry.L2, geometry.R, geometry.r], dtype=float)

    # ------------------------------------------------------------------ kinematics
    def ik(self, p) -> np.ndarray:
        """Arm angles (N, 3) rad of platform positions ``p`` (N, 3) m, elbow-out branch.

        Raises:
            KinematicsError: a position out of reach, naming the limb and the position.
        """
        p, single = _batch(p)
        L1, L2 = self.geometry.L1, self.geometry.L2
        v = np.einsum("lka,nlk->nla", self._R, p[:, None, :] + self.geometry.r * self._e - self._A)
        K = (np.sum(v**2, axis=2) + L1**2 - L2**2) / (2 * L1)
        rho = np.hypot(v[..., 0], v[..., 2])
        bad = ~(np.abs(K) <= rho)
        if bad.any():
            n, limb = map(int, np.argwhere(bad)[0])
            raise KinematicsError(f"platform position {p[n].tolist()} m out of reach of limb {limb + 1} "
                                  f"(sample {n})", chain=limb + 1, sample=n)
        q = np.arctan2(-v[..., 2], v[..., 0]) - np.arccos(K / rho)
        return q[0] if single else q

    def elbows(self, q: np.ndarray) -> np.ndarray:
        """Elbow positions ``B_i`` (N, 3 limbs, 3) m."""
        cq, sq = np.cos(q)[..., None], np.sin(q)[..., None]
        return self._A + self.geometry.L1 * (cq * self._e - sq * _EZ)

    def fk(self, q) -> np.ndarray:
        """Platform positions (N, 3) m of arm angles ``q`` (N, 3) rad: the three-sphere
        intersection below the base.

        Raises:
            KinematicsError: no assembly (the spheres do not meet) or collinear sphere centres.
        """
        q, single = _batch(q)
        C = self.elbows(q) - self.geometry.r * self._e
        c1, c2, c3 = C[:, 0], C[:, 1], C[:, 2]
        dc = np.linalg.norm(c2 - c1, axis=1)
        fx = (c2 - c1) / dc[:, None]
        i = np.sum(fx * (c3 - c1), axis=1)
        rest = c3 - c1 - i[:, None] * fx
        j = np.linalg.norm(rest, axis=1)
        if np.any(j <= 1e-12 * self.geometry.L2):
            n = int(np.argmax(j <= 1e-12 * self.geometry.L2))
            raise SingularityError(f"sphere centres collinear at q = {q[n].tolist()} rad (sample {n})", sample=n)
        fy = rest / j[:, None]
        fz = np.cross(fx, fy)
        x0 = dc / 2
        y0 = (i**2 + j**2 - 2 * i * x0) / (2 * j)
        z2 = self.geometry.L2**2 - x0**2 - y0**2
        if np.any(z2 < 0):
            n = int(np.argmax(z2 < 0))
            raise KinematicsError(f"no assembly at q = {q[n].tolist()} rad (sample {n}): the rods cannot "
                                  "reach a common platform position", sample=n)
        base = c1 + x0[:, None] * fx + y0[:, None] * fy
        up, down = base + np.sqrt(z2)[:, None] * fz, base - np.sqrt(z2)[:, None] * fz
        p = np.where((up[:, 2] < down[:, 2])[:, None], up, down)
        return p[0] if single else p

    def rod_angles(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Rod angles ``b``, ``c`` (N, 3) rad of arm angles ``q``."""
        q, single = _batch(q)
        w = self._rod_axes(q, self.fk(q))
        b, c = np.arctan2(-w[..., 2], w[..., 0]), np.arcsin(np.clip(w[..., 1], -1, 1))
        return (b[0], c[0]) if single else (b, c)

    def jacobian(self, q) -> np.ndarray:
        """``J`` (N, 3, 3): platform velocity ``pd = J @ qd`` (m/s per rad/s)."""
        q, single = _batch(q)
        D, E = self._D_E(q, self.fk(q))
        J = np.linalg.solve(D, E)
        return J[0] if single else J

    def singularity(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Singularity measures: serial ``|d_i . t_i| / (L1 L2)`` (N, 3), 0 where limb ``i``'s IK
        branches meet; parallel ``cond(D / L2)`` (N,), infinite where the FK roots meet."""
        q, single = _batch(q)
        D, E = self._D_E(q, self.fk(q))
        serial = np.abs(np.diagonal(E, axis1=1, axis2=2)) / (self.geometry.L1 * self.geometry.L2)
        parallel = np.linalg.cond(D / self.geometry.L2)
        return (serial[0], parallel[0]) if single else (serial, parallel)

    def _rod_axes(self, q, p) -> np.ndarray:
        """``w_i = R_iᵀ u_i`` (N, 3, 3): rod axis from platform joint to elbow, limb coordinates."""
        u = -(p[:, None, :] + self.geometry.r * self._e - self.elbows(q)) / self.geometry.L2
        return np.einsum("lka,nlk->nla", self._R, u)

    def _D_E(self, q, p):
        d = p[:, None, :] + self.geometry.r * self._e - self.elbows(q)
        t = self._arm_tangents(q)
        return d, _diag(np.sum(d * t, axis=2))

    def _arm_tangents(self, q) -> np.ndarray:
        """``t_i = dB_i/dq_i`` (N, 3, 3)."""
        cq, sq = np.cos(q)[..., None], np.sin(q)[..., None]
        return -self.geometry.L1 * (sq * self._e + cq * _EZ)

    def bodies(self, q, qd, qdd) -> Bodies:
        """Poses, velocities, accelerations and Jacobians of the seven bodies."""
        q, qd, qdd = (np.atleast_2d(np.asarray(x, float)) for x in (q, qd, qdd))
        n = len(q)
        p, pd, pdd, J, t, d, Bdd = self._platform_motion(q, qd, qdd)
        b, c, nvec, omega_rod, alpha_rod = self._rod_motion(qd, t, d, pd, pdd, Bdd)
        beta, gamma = self._rod_rate_rows(J, t, b, c)
        zeros = np.zeros((n, 3))
        parts = []                          # per body: origin, Q, v, a, omega, alpha, J
        for i in range(3):                                              # arms
            Jk = np.zeros((n, 6, 3))
            Jk[:, 3:, i] = self._y[i]
            parts.append((np.broadcast_to(self._A[i], (n, 3)), self._R[i] @ _rot_y(q[:, i]), zeros, zeros,
                          qd[:, i, None] * self._y[i], qdd[:, i, None] * self._y[i], Jk))
        for i in range(3):                                              # rods
            Jk = np.zeros((n, 6, 3))
            Jk[:, :3] = J
            Jk[:, 3:] = self._y[i][:, None] * beta[:, i, None, :] + nvec[:, i, :, None] * gamma[:, i, None, :]
            parts.append((p + self.geometry.r * self._e[i],
                          self._R[i] @ _rot_y(b[:, i]) @ _rot_z(c[:, i]) @ _rot_x(np.full(n, -math.pi / 2)),
                          pd, pdd, omega_rod[:, i], alpha_rod[:, i], Jk))
        Jk = np.zeros((n, 6, 3))                                        # platform
        Jk[:, :3] = J
        parts.append((p, np.broadcast_to(np.eye(3), (n, 3, 3)), pd, pdd, zeros, zeros, Jk))
        return Bodies(*(np.stack(x) for x in zip(*parts)))

    def _platform_motion(self, q, qd, qdd):
        """The platform's position ``p``, velocity ``pd`` and acceleration ``pdd`` (N, 3) and its
        Jacobian ``J`` (N, 3, 3), ``pd = J @ qd``, from the batch ``q, qd, qdd`` (N, 3); with the
        arm tangents ``t``, the elbow-to-platform-joint vectors ``d`` and the elbows' accelerations
        ``Bdd`` (N, 3 limbs, 3) that the rods' motion needs."""
        p = self.fk(q)
        B = self.elbows(q)
        t = self._arm_tangents(q)
        d = p[:, None, :] + self.geometry.r * self._e - B
        D = d
        dt = np.sum(d * t, axis=2)                                       # (N, 3)
        J = np.linalg.solve(D, _diag(dt))
        pd = np.einsum("nij,nj->ni", J, qd)
        BA = B - self._A
        Bdd = t * qdd[..., None] - (qd**2)[..., None] * BA
        ddot = pd[:, None, :] - t * qd[..., None]
        kappa = -(qd**2) * np.sum(d * BA, axis=2) - np.sum(ddot**2, axis=2)
        pdd = np.linalg.solve(D, (dt * qdd + kappa)[..., None])[..., 0]
        return p, pd, pdd, J, t, d, Bdd

    def _rod_motion(self, qd, t, d, pd, pdd, Bdd):
        """The rods' U-joint angles ``b``, ``c`` (N, 3 limbs), second U-joint axes ``nvec`` and
        angular velocities and accelerations (N, 3 limbs, 3), from the platform's and the elbows'
        motion (:meth:`_platform_motion`). Raises :class:`SingularityError` where a U-joint is at
        its limit (``cos c = 0``)."""
        L2 = self.geometry.L2
        n = len(qd)
        RT = lambda vec: np.einsum("lka,nlk->nla", self._R, vec)       # noqa: E731  world -> limb
        w = RT(-d / L2)
        wd = RT((t * qd[..., None] - pd[:, None, :]) / L2)
        wdd = RT((Bdd - pdd[:, None, :]) / L2)
        c = np.arcsin(np.clip(w[..., 1], -1, 1))
        b = np.arctan2(-w[..., 2], w[..., 0])
        cc, sc, cb, sb = np.cos(c), np.sin(c), np.cos(b), np.sin(b)
        if np.any(np.abs(cc) < 1e-9):
            k, limb = map(int, np.argwhere(np.abs(cc) < 1e-9)[0])
            raise SingularityError(f"U-joint of limb {limb + 1} at its limit (cos c = 0), sample {k}",
                                   chain=limb + 1, sample=k)
        cd = wd[..., 1] / cc
        bd = -(sb * wd[..., 0] + cb * wd[..., 2]) / cc
        cdd = (wdd[..., 1] + sc * cd**2) / cc
        bdd = (sc * bd * cd - sb * wdd[..., 0] - cb * wdd[..., 2] - bd * (cb * wd[..., 0] - sb * wd[..., 2])) / cc
        nvec = sb[..., None] * self._e + cb[..., None] * _EZ             # (N, 3, 3) second U-joint axes
        y = np.broadcast_to(self._y, (n, 3, 3))
        omega_rod = bd[..., None] * y + cd[..., None] * nvec
        alpha_rod = bdd[..., None] * y + cdd[..., None] * nvec + (bd * cd)[..., None] * np.cross(y, nvec)
        return b, c, nvec, omega_rod, alpha_rod

    def _rod_rate_rows(self, J, t, b, c):
        """The rows ``beta``, ``gamma`` (N, 3 limbs, 3) with ``bd = beta_i . qd``, ``cd = gamma_i .
        qd``: the rods' angular-velocity Jacobians, from the platform's Jacobian ``J`` (N, 3, 3),
        the arm tangents ``t`` and the U-joint angles ``b``, ``c`` (N, 3 limbs)."""
        cc, cb, sb = np.cos(c), np.cos(b), np.sin(b)
        # W_i = R_iᵀ (t_i eps_iᵀ - J) / L2 and its rows -> bd = beta_i . qd, cd = gamma_i . qd
        M = np.repeat(-J[:, None], 3, axis=1)                            # (N, limb, 3, 3)
        for i in range(3):
            M[:, i, :, i] += t[:, i]
        W = np.einsum("lka,nlkj->nlaj", self._R, M) / self.geometry.L2
        beta = -(sb[..., None] * W[:, :, 0] + cb[..., None] * W[:, :, 2]) / cc[..., None]
        gamma = W[:, :, 1] / cc[..., None]
        return beta, gamma

    # ------------------------------------------------------------------ dynamics
    def regressor(self, q, qd, qdd) -> np.ndarray:
        """``Y`` (N, 3, 79): ``tau = Y @ pi`` (virtual work of the seven bodies, then the drive terms).

        The bodies' columns by the compiled sample loop (:func:`.delta_single.body_regressor`,
        held equal to :meth:`vectorised_regressor`); where a sample's motion fails there (no
        assembly, a singularity), the whole batch goes the vectorised way, which raises the error."""
        q = np.asarray(q, float)
        single = q.ndim == 1
        c = np.ascontiguousarray
        q, qd, qdd = (c(np.atleast_2d(np.asarray(x, float))) for x in (q, qd, qdd))
        if not q.shape == qd.shape == qdd.shape or q.shape[1] != 3:
            raise ValueError(f"q, qd, qdd must each be (N, 3), got {q.shape}, {qd.shape}, {qdd.shape}")
        Y = np.zeros((len(q), 3, N_PARAMS))
        if _compiled().body_regressor(q, qd, qdd, self._single_geo, self._e, self._y, self.g, Y) >= 0:
            Y = self.vectorised_regressor(q, qd, qdd)
        else:
            self._drive_columns(Y, qd, qdd)
        return Y[0] if single else Y

    def _drive_columns(self, Y, qd, qdd) -> None:
        """The drive terms' columns of ``Y`` (N, 3, 79): viscous and Coulomb friction, rotor inertia."""
        idx = np.arange(3)
        Y[:, idx, N_BODY_PARAMS + idx] = qd
        Y[:, idx, N_BODY_PARAMS + 3 + idx] = smooth_sign(qd, self.coulomb_width)
        Y[:, idx, N_BODY_PARAMS + 6 + idx] = qdd

    def vectorised_regressor(self, q, qd, qdd) -> np.ndarray:
        """:meth:`regressor` in NumPy over the batch (the reference of the compiled path)."""
        q = np.asarray(q, float)
        single = q.ndim == 1
        q, qd, qdd = (np.atleast_2d(np.asarray(x, float)) for x in (q, qd, qdd))
        bodies = self.bodies(q, qd, qdd)
        n = len(q)
        Y = np.zeros((n, 3, N_PARAMS))
        for k in range(len(BODIES)):
            QT = np.swapaxes(bodies.Q[k], 1, 2)
            abar = np.einsum("nij,nj->ni", QT, bodies.a[k] - self.g)
            wbar = np.einsum("nij,nj->ni", QT, bodies.omega[k])
            albar = np.einsum("nij,nj->ni", QT, bodies.alpha[k])
            Sw = _skew(wbar)
            Lw = _inertia_map(wbar)
            phi = np.zeros((n, 6, 10))
            phi[:, :3, 0] = abar
            phi[:, :3, 1:4] = _skew(albar) + Sw @ Sw
            phi[:, 3:, 1:4] = -_skew(abar)
            phi[:, 3:, 4:] = _inertia_map(albar) + Sw @ Lw
            world = np.concatenate([bodies.Q[k] @ phi[:, :3], bodies.Q[k] @ phi[:, 3:]], axis=1)
            Y[:, :, 10 * k:10 * k + 10] = np.swapaxes(bodies.J[k], 1, 2) @ world
        self._drive_columns(Y, qd, qdd)
        return Y[0] if single else Y

    def inverse_dynamics(self, q, qd, qdd, pi) -> np.ndarray:
        """Arm torques (N, 3) N·m."""
        return self.regressor(q, qd, qdd) @ np.asarray(pi, float)

    def mass_matrix(self, q, pi) -> np.ndarray:
        """``M(q)`` (N, 3, 3) kg·m²: column ``j`` is ``tau(q, 0, e_j) - tau(q, 0, 0)``."""
        q, single = _batch(q)
        n = len(q)
        zero = np.zeros((n, 3))
        pi = np.asarray(pi, float)
        static = self.regressor(q, zero, zero) @ pi
        cols = [self.regressor(q, zero, np.tile(np.eye(3)[j], (n, 1))) @ pi - static for j in range(3)]
        M = np.stack(cols, axis=2)
        return M[0] if single else M

    def forward_dynamics(self, q, qd, tau, pi) -> np.ndarray:
        """Arm accelerations (N, 3) rad/s² under torques ``tau`` (N, 3) N·m:
        ``M(q) qdd = tau - tau(q, qd, 0)``."""
        q, single = _batch(q)
        qd, tau = np.atleast_2d(np.asarray(qd, float)), np.atleast_2d(np.asarray(tau, float))
        bias = self.regressor(q, qd, np.zeros_like(qd)) @ np.asarray(pi, float)
        qdd = np.linalg.solve(self.mass_matrix(q, pi), (tau - bias)[..., None])[..., 0]
        return qdd[0] if single else qdd


    # ------------------------------------------------------------------ the robot interface
    # (ident_hw.model.interface.RobotModel)
    @staticmethod
    def parameter_unit(name: str) -> str:
        """SI unit of a parameter of :data:`PARAM_NAMES`."""
        kind = name.split(".")[-1].split("_")[0]
        return {"m": "kg", "mx": "kg·m", "my": "kg·m", "mz": "kg·m", "fv": "N·m·s/rad", "fc": "N·m",
                "Jm": "kg·m²"}.get(kind, "kg·m²")

    def readable_base(self) -> BaseBasis:
        """The spec's 40 readable base parameters with the drive terms (:func:`closed_form_base`)."""
        return closed_form_base(self.geometry, drive_terms=True)

    def physical_bodies(self) -> tuple[PhysicalBody, ...]:
        """The seven bodies (arms, rods, platform), each in its own frame."""
        return tuple(PhysicalBody(b, tuple(PARAM_NAMES.index(f"{b}.{p}") for p in SPATIAL)) for b in BODIES)

    def pose_series(self, Theta, start=None) -> np.ndarray:
        """Platform positions (N, 3) m: closed form, no series needed."""
        return self.fk(Theta)

    def identification_regressor(self, Theta, Thetad, Thetadd, guess=None):
        """``Y`` (N, 3, 79) and the platform positions (N, 3)."""
        return self.regressor(Theta, Thetad, Thetadd), self.fk(Theta)

    def home_actuated(self) -> np.ndarray:
        """Arms horizontal, ``q = 0`` (3,): the centre of the paper's paths."""
        return np.zeros(3)

    def pose(self, Theta, guess=None) -> np.ndarray:
        """Platform position (3,) m: the closed-form forward kinematics needs no guess."""
        return self.fk(np.asarray(Theta, float))

    def plant_dynamics(self, Theta, Thetad, params, guess=None) -> PlantState:
        """``M`` (3, 3) kg·m², bias torques (3,) N·m (gravity and velocity terms, no friction) and
        the platform position (3,) m (a :class:`~ident_hw.model.interface.PlantState`), by the
        compiled one-state path (:mod:`.delta_single`).
        Where that path fails (no assembly, a singularity) the regressor path raises the error."""
        c = np.ascontiguousarray
        pi = c(params, dtype=float)
        M, bias, p = np.empty((3, 3)), np.empty(3), np.empty(3)
        compiled = _compiled()
        outcome = compiled.one_state(c(Theta, dtype=float), c(Thetad, dtype=float), pi, pi[N_BODY_PARAMS + 6:],
                                     self._single_geo, self._e, self._y, self.g, M, bias, p)
        if outcome != compiled.OK:
            return self._plant_dynamics_regressor(Theta, Thetad, params)
        return PlantState(M, bias, p)

    def _plant_dynamics_regressor(self, Theta, Thetad, params) -> PlantState:
        """:meth:`plant_dynamics` from one regressor evaluation of five stacked samples."""
        q, qd = np.asarray(Theta, float), np.asarray(Thetad, float)
        pi = np.array(params, float)
        pi[N_BODY_PARAMS:N_BODY_PARAMS + 6] = 0.0            # fv, fc: the plant adds the friction
        zero = np.zeros(3)
        qdd = np.vstack([zero, np.eye(3), zero])
        tau = self.regressor(np.tile(q, (5, 1)), np.vstack([np.zeros((4, 3)), qd]), qdd) @ pi
        M = (tau[1:4] - tau[0]).T
        return PlantState(M, tau[4], self.pose(q))

    def friction_coefficients(self, params):
        """``fv_1..3`` (N·m·s/rad) and ``fc_1..3`` (N·m) from the parameter vector."""
        pi = np.asarray(params, float)
        return pi[N_BODY_PARAMS:N_BODY_PARAMS + 3].copy(), pi[N_BODY_PARAMS + 3:N_BODY_PARAMS + 6].copy()

    def with_payload(self, params, mass: float, inertia: float = 0.0) -> np.ndarray:
        """``pi`` with a point-like payload at the platform's origin: ``mass`` kg added to the
        platform's mass, ``inertia`` kg·m² to its ``Izz`` (first moments unchanged)."""
        pi = np.array(params, float)
        plat = 10 * BODIES.index("plat")
        pi[plat + BODY_PARAMS.index("m")] += mass
        pi[plat + BODY_PARAMS.index("Izz")] += inertia
        return pi

# ---------------------------------------------------------------------- helpers
@functools.cache
def _compiled() -> ModuleType:
    """The compiled code of one state and of a sample loop (:mod:`.delta_single`, numba: compiled
    or read from its cache when first imported), imported on first use and kept: an import
    statement in :meth:`Delta.plant_dynamics`, called every SYNC period, costs more than the
    record it returns."""
    from . import delta_single
    return delta_single


def _batch(x) -> tuple[np.ndarray, bool]:
    x = np.asarray(x, float)
    return np.atleast_2d(x), x.ndim == 1


def _sym(six: np.ndarray) -> np.ndarray:
    xx, xy, xz, yy, yz, zz = six
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def _diag(v: np.ndarray) -> np.ndarray:
    out = np.zeros(v.shape + (v.shape[-1],))
    idx = np.arange(v.shape[-1])
    out[..., idx, idx] = v
    return out


def _skew(v: np.ndarray) -> np.ndarray:
    """(N, 3, 3) cross-product matrices: ``_skew(v) @ x = v × x``."""
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def _inertia_map(w: np.ndarray) -> np.ndarray:
    """(N, 3, 6) ``L(w)`` with ``I w = L(w) [Ixx, Ixy, Ixz, Iyy, Iyz, Izz]``."""
    L = np.zeros(w.shape[:-1] + (3, 6))
    wx, wy, wz = w[..., 0], w[..., 1], w[..., 2]
    L[..., 0, 0], L[..., 0, 1], L[..., 0, 2] = wx, wy, wz
    L[..., 1, 1], L[..., 1, 3], L[..., 1, 4] = wx, wy, wz
    L[..., 2, 2], L[..., 2, 4], L[..., 2, 5] = wx, wy, wz
    return L


def _rot_x(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def _rot_y(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def _rot_z(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)
