"""The public face of the model: :class:`ThreePRRR`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from . import dynamics
from .interface import PRISMATIC, REVOLUTE, PlantState
from .kinematics import Kinematics, Motion, SingularityMargins, batch
from .motion import SampledMotion
from .parameters import ACTUATOR_NAMES, Geometry, InertialParams
from .pseudo_inertia import PhysicalBody


@dataclass(frozen=True)
class Simulation:
    """Result of :meth:`ThreePRRR.simulate`: ``t`` (N,), ``Theta``/``Thetad`` (N, 6), ``X`` (N, 3)."""

    t: np.ndarray
    Theta: np.ndarray
    Thetad: np.ndarray
    X: np.ndarray


class ThreePRRR:
    """Kinematics and dynamics of the 3PRRR, vectorised over N samples.

    Args:
        geometry: the robot's :class:`Geometry`.
        coulomb_width: velocity scale ``w`` (rad/s or m/s) of the smooth Coulomb sign ``tanh(qd / w)``.

    Every method takes batches: poses ``X`` (N, 3) ``[x, y, alpha]`` in m, m, rad; carriages
    ``zeta`` (N, 3) in m; actuated coordinates ``Theta`` (N, 6) ``[theta1..3 (rad), zeta1..3 (m)]``;
    a single sample may be given as a 1-D array. Forces are (N, 6): N·m on the links, N on the
    carriages.
    """

    actuator_names: tuple[str, ...] = ACTUATOR_NAMES
    actuator_kinds: tuple[str, ...] = (REVOLUTE,) * 3 + (PRISMATIC,) * 3
    parameter_names = InertialParams.NAMES
    n_params = len(InertialParams.NAMES)
    pose_size = 3

    def __init__(self, geometry: Geometry, coulomb_width: float = 1e-3):
        if not coulomb_width > 0:
            raise ValueError(f"coulomb_width must be positive, got {coulomb_width}")
        self.geometry = geometry
        self.coulomb_width = coulomb_width
        self.kinematics = Kinematics(geometry)
        self._single: Any = None  # the compiled one-state path (SingleState), made by the plant's first call
        self._plant_params: tuple[np.ndarray, InertialParams] | None = None

    # -- kinematics ---------------------------------------------------------------------------
    def inverse_kinematics(self, X, zeta):
        """``theta``, ``beta`` (N, 3) in rad for poses ``X`` and carriages ``zeta``."""
        return self.kinematics.inverse_kinematics(X, zeta)

    def forward_kinematics(self, Theta, X_guess) -> np.ndarray:
        """Pose ``X`` (N, 3) from ``Theta`` (N, 6); ``X_guess`` (3,) continues along a series, (N, 3) per sample."""
        return self.kinematics.forward_kinematics(Theta, X_guess)

    def jacobian(self, X, zeta) -> np.ndarray:
        """``J`` (N, 3, 6) with ``Xd = J Thetad``."""
        return self.kinematics.jacobian(X, zeta)

    def singularity_margins(self, X, zeta) -> SingularityMargins:
        """Parallel (``cond_A``) and serial (``|sin(beta_i - theta_i)|``) margins."""
        return self.kinematics.singularity_margins(X, zeta)

    def closure_residual(self, X, Theta) -> np.ndarray:
        """Largest closure error (N,) in m of poses ``X`` with actuated coordinates ``Theta``."""
        return self.kinematics.closure_residual(X, Theta)

    def motion(self, X, Xd, Xdd, zeta, zetad, zetadd) -> Motion:
        """Every coordinate of the closed chain with its rates, from the pose and carriage motion."""
        return self.kinematics.motion_from_pose(X, Xd, Xdd, zeta, zetad, zetadd)

    def motion_from_actuated(self, Theta, Thetad, Thetadd, X_guess) -> Motion:
        """Every coordinate with its rates, from measured actuated motion (each (N, 6))."""
        return self.kinematics.motion_from_actuated(Theta, Thetad, Thetadd, X_guess)

    def actuated_motion(self, X, Xd, Xdd, zeta, zetad, zetadd) -> SampledMotion:
        """``Theta`` and its rates (each (N, 6)) of a pose and carriage motion, analytically."""
        m = self.motion(X, Xd, Xdd, zeta, zetad, zetadd)
        return SampledMotion(m.Theta, m.Thetad, m.Thetadd)

    def pose_motion(self, Theta, Thetad, Thetadd, X_guess) -> SampledMotion:
        """The pose ``X`` and its rates (each (N, 3)) of an actuated motion."""
        m = self.motion_from_actuated(Theta, Thetad, Thetadd, X_guess)
        return SampledMotion(m.X, m.Xd, m.Xdd)

    # -- dynamics -------------------------------------------------------------------------------
    def regressor(self, X, Xd, Xdd, zeta, zetad, zetadd) -> np.ndarray:
        """``Y`` (N, 6, 19) with ``tau = Y @ params.as_vector()``."""
        return self.regressor_of(self.motion(X, Xd, Xdd, zeta, zetad, zetadd))

    def regressor_from_actuated(self, Theta, Thetad, Thetadd, X_guess) -> np.ndarray:
        """``Y`` (N, 6, 19) from actuated motion (forward kinematics first)."""
        return self.regressor_of(self.motion_from_actuated(Theta, Thetad, Thetadd, X_guess))

    def regressor_of(self, motion: Motion) -> np.ndarray:
        """``Y`` (N, 6, 19) of an already computed :class:`Motion`."""
        return dynamics.regressor(self.kinematics, motion, self.coulomb_width)

    def inverse_dynamics(self, X, Xd, Xdd, zeta, zetad, zetadd, params: InertialParams) -> np.ndarray:
        """Actuator forces (N, 6) by the Lagrange-multiplier equations (eqs. 31–35), friction included."""
        m = self.motion(X, Xd, Xdd, zeta, zetad, zetadd)
        return dynamics.lagrange_forces(self.kinematics, m, params, self.coulomb_width)

    def kinetic_energy(self, X, Xd, zeta, zetad, params: InertialParams) -> np.ndarray:
        """Kinetic energy ``T`` (N,) in J."""
        return self.energy_regressor(X, Xd, zeta, zetad) @ params.as_vector()[: dynamics.N_INERTIAL]

    def energy_regressor(self, X, Xd, zeta, zetad) -> np.ndarray:
        """``H`` (N, 7) with ``T = H @ params.as_vector()[:7]``."""
        X = batch(X, 3, "X")
        zero = np.zeros_like(X)
        m = self.motion(X, Xd, zero, zeta, zetad, zero)
        return dynamics.energy_regressor(self.kinematics, m)

    def reduced_dynamics(self, Theta, Thetad, params: InertialParams, X_guess):
        """Dynamics in the actuated coordinates: ``M_r(Theta) Thetadd + c(Theta, Thetad) = tau``.

        Returns the mass matrix ``M_r`` (N, 6, 6) (kg, kg·m, kg·m² blocks) and the bias forces ``c``
        (N, 6): velocity terms and friction. ``M_r = sum_b Jac_b^T mu_b Jac_b`` over the bodies.
        """
        Theta = batch(Theta, 6, "Theta")
        return self.reduced_dynamics_of(self.motion_from_actuated(Theta, Thetad, np.zeros_like(Theta), X_guess), params)

    def reduced_dynamics_of(self, motion: Motion, params: InertialParams):
        """``M_r`` (N, 6, 6) and ``c`` (N, 6) of an already computed :class:`Motion` (zero actuated
        acceleration for the velocity terms alone); see :meth:`reduced_dynamics`."""
        return dynamics.reduced_dynamics(self.kinematics, motion, params, self.coulomb_width)

    def friction(self, Thetad, params: InertialParams) -> np.ndarray:
        """Friction forces (N, 6): ``f_v Thetad + f_c tanh(Thetad / coulomb_width)``."""
        return dynamics.friction(batch(Thetad, 6, "Thetad"), params, self.coulomb_width)

    def forward_dynamics(self, Theta, Thetad, tau, params: InertialParams, X_guess) -> np.ndarray:
        """Actuated accelerations ``Thetadd`` (N, 6) under actuator forces ``tau`` (N, 6).

        The closed chain is reduced to the six independent actuated coordinates:
        ``M_r(Theta) Thetadd + c(Theta, Thetad) = tau`` with ``M_r = sum_b Jac_b^T mu_b Jac_b`` and ``c``
        the forces at zero actuated acceleration (velocity terms and friction).
        """
        M, c = self.reduced_dynamics(Theta, Thetad, params, X_guess)
        tau = batch(tau, 6, "tau")
        return np.linalg.solve(M, (tau - c)[..., None])[..., 0]

    # -- the robot interface (ident_hw.model.interface.RobotModel) -------------------------------
    @staticmethod
    def parameter_unit(name: str) -> str:
        """SI unit of a parameter of ``InertialParams.NAMES``: masses, inertias, and the
        friction of a link (``theta``) or a carriage (``zeta``)."""
        if name.startswith("m_"):
            return "kg"
        if name.startswith("I_"):
            return "kg·m²"
        revolute = "theta" in name
        if name.startswith("fv_"):
            return "N·m·s/rad" if revolute else "N·s/m"
        return "N·m" if revolute else "N"

    def readable_base(self) -> None:
        """None: the 3PRRR's base parameters are found by SVD from the data (18 of 19 on a rich
        excitation, ``docs/identification.md``)."""
        return None

    def physical_bodies(self) -> tuple[PhysicalBody, ...]:
        """The four planar bodies of one chain and the platform, each in a frame at its centre of
        mass (the geometry fixes the centres): a carriage is a point mass ``m_c``, links 1 and 2
        ``(m_l*, I_l*)``, the end-effector ``(m_ee, I_ee)``; the chains share their values."""
        at = InertialParams.NAMES.index
        return (PhysicalBody("carriage", (at("m_c"), -1, -1, -1), planar=True),
                PhysicalBody("link1", (at("m_l1"), -1, -1, at("I_l1")), planar=True),
                PhysicalBody("link2", (at("m_l2"), -1, -1, at("I_l2")), planar=True),
                PhysicalBody("end_effector", (at("m_ee"), -1, -1, at("I_ee")), planar=True))

    def pose_series(self, Theta, start) -> np.ndarray:
        """Poses ``X`` (N, 3) of ``Theta`` (N, 6), each Newton start the previous pose."""
        return self.forward_kinematics(Theta, start)

    def identification_regressor(self, Theta, Thetad, Thetadd, guess):
        """``Y`` (N, 6, 19) and ``X`` (N, 3) of a measured actuated motion."""
        motion = self.motion_from_actuated(Theta, Thetad, Thetadd, guess)
        return self.regressor_of(motion), motion.X

    def home_actuated(self) -> np.ndarray:
        """``Theta`` (6,) of the home pose: end-effector at the origin, carriages at mid-stroke."""
        theta, _ = self.inverse_kinematics(np.zeros((1, 3)), np.zeros((1, 3)))
        return np.concatenate([theta[0], np.zeros(3)])

    def pose(self, Theta, guess) -> np.ndarray:
        """The pose ``X`` (3,) of one ``Theta`` (6,), continuing from ``guess`` (3,)."""
        return self.forward_kinematics(np.asarray(Theta, dtype=float)[None], guess)[0]

    def plant_dynamics(self, Theta, Thetad, params: InertialParams, guess) -> PlantState:
        """``M_r`` (6, 6), velocity terms (6,) without friction and ``X`` (3,) of one state (the
        scalar path of :class:`~ident_hw.model.single.SingleState`: what the plant calls every period)."""
        if not isinstance(params, InertialParams):     # the plant's vector: converted once, not every period
            if self._plant_params is None or not np.array_equal(self._plant_params[0], params):
                self._plant_params = (np.array(params, dtype=float), InertialParams.from_vector(params))
            params = self._plant_params[1]
        if self._single is None:
            from .single import SingleState  # compiled code, loaded by the simulated rig only
            self._single = SingleState(self.kinematics)
        return self._single.reduced_dynamics(Theta, Thetad, params, guess)

    def friction_coefficients(self, params: InertialParams):
        """``f_v``, ``f_c`` (6,) each (``params``: :class:`InertialParams` or the vector (19,))."""
        params = _inertial(params)
        return np.asarray(params.f_v, dtype=float), np.asarray(params.f_c, dtype=float)

    def with_payload(self, params, mass: float, inertia: float):
        """The end-effector's ``m_ee``, ``I_ee`` increased by the payload, in ``params``' form
        (:class:`InertialParams` or the vector (19,) of ``parameter_names``)."""
        if isinstance(params, InertialParams):
            return params.replace(m_ee=params.m_ee + mass, I_ee=params.I_ee + inertia)
        vector = np.array(params, dtype=float)
        vector[self.parameter_names.index("m_ee")] += mass
        vector[self.parameter_names.index("I_ee")] += inertia
        return vector

    def simulate(self, t, Theta0, Thetad0, force, params: InertialParams, X0, rtol=1e-10, atol=1e-12) -> Simulation:
        """Integrate the closed-chain dynamics (SciPy ``solve_ivp``, DOP853).

        The state is the actuated coordinates and their rates; the pose is rebuilt by forward
        kinematics at every evaluation, so the closure holds to Newton's tolerance at all times.

        Args:
            t: output times (N,) in s, increasing; integration from ``t[0]``.
            Theta0, Thetad0: initial actuated state (6,).
            force: ``force(t, Theta, Thetad) -> (6,)`` actuator forces in N·m / N.
            params: the plant's parameters.
            X0: initial pose guess (3,).
        """
        last_X = [np.asarray(X0, dtype=float)]

        def rhs(time, y):
            Theta, Thetad = y[:6], y[6:]
            X = self.forward_kinematics(Theta, last_X[0])
            last_X[0] = X[0]
            Thetadd = self.forward_dynamics(Theta, Thetad, force(time, Theta, Thetad), params, X)[0]
            return np.concatenate([Thetad, Thetadd])

        t = np.asarray(t, dtype=float)
        from scipy.integrate import solve_ivp  # here: the integrator is for tests and studies, not every import
        sol = solve_ivp(rhs, (t[0], t[-1]), np.concatenate([Theta0, Thetad0]), method="DOP853",
                        t_eval=t, rtol=rtol, atol=atol)
        if not sol.success:
            raise RuntimeError(f"forward dynamics integration failed: {sol.message}")
        Theta = sol.y[:6].T
        return Simulation(sol.t, Theta, sol.y[6:].T, self.forward_kinematics(Theta, X0))


def _inertial(params) -> InertialParams:
    """``params`` as :class:`InertialParams` (given as such, or as the vector of ``parameter_names``)."""
    return params if isinstance(params, InertialParams) else InertialParams.from_vector(params)
