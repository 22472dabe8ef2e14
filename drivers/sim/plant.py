"""The simulated 3PRRR behind the emulated drives: closed-chain dynamics under six position loops.

Each actuator is driven by a drive-side position controller, PD plus velocity feed-forward,
``F = Kp (q_d - q) + Kd (qd_d - qd)``, clipped to the drive's current limit. Within a period the
demand ``q_d(t)`` is a polynomial handed over by the drive (the set-point interpolation of
:mod:`drivers.sim.drive`, continuous up to its acceleration); since it is continuous with its
first derivative across periods, so is the force, and the force at a period start is the force
of that instant, not a one-sided value. There is no acceleration feed-forward. The plant moves by
the closed-chain forward dynamics of :class:`ident_hw.model.ThreePRRR` with the *true*
parameters (friction included). The reduced mass matrix ``M`` and the velocity terms are
evaluated once per period (the expensive part, one model evaluation); within the period the
controller and the friction are re-evaluated at every substep of at most ``max_substep``, and
the state advances by Heun's method (second order: the position loops and the smoothed Coulomb
friction are the stiff part, and first-order Euler at 0.5 ms left force errors of a few percent).

The log holds, at each period start, the state, the actuator forces and the *exact*
acceleration ``M^-1 (F - c)`` of that state: the logged forces are the model's inverse dynamics
of the logged motion to rounding, whatever the integration error.

If the commanded motion drives the robot into a parallel (type II) singularity, the forward
kinematics has no solution any more: :meth:`Plant.step` raises :class:`PlantJammed` and
the plant stays at its last valid pose, at rest (the rig reports it as a following error).

Everything here is SI: rad, m, N·m, N, s; the drive units (counts, rpm, mA) belong to the rig.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from ident_hw.model import InertialParams, KinematicsError, ThreePRRR


class PlantJammed(RuntimeError):
    """The mechanism cannot follow: its forward kinematics failed (parallel singularity crossed)."""


@dataclass(frozen=True)
class TruthSample:
    """One logged plant state at a period start: ``t`` (s), ``X`` (3,) pose, each other field (6,) in SI."""

    t: float
    X: np.ndarray
    Theta: np.ndarray
    Thetad: np.ndarray
    Thetadd: np.ndarray
    force: np.ndarray


class Plant:
    """The 3PRRR with its true parameters and six position-controlled actuators.

    Args:
        robot: the kinematic/dynamic model.
        params: the TRUE parameters (what identification should find).
        Theta0: initial actuated coordinates (6,); default: the home pose (``X = 0``, ``zeta = 0``).
        bandwidth_hz, damping: position-loop bandwidth and damping ratio; the gains of axis ``j``
            are ``Kp = M_jj w^2`` and ``Kd = 2 damping M_jj w`` with ``M`` the mass matrix at ``Theta0``.
        gains: explicit ``(Kp, Kd)`` arrays (6,) instead (N/m, N·s/m or N·m/rad, N·m·s/rad).
        max_substep: largest integration step in s.
        log_length: number of periods kept in :attr:`log`.
    """

    def __init__(self, robot: ThreePRRR, params: InertialParams, Theta0=None, *,
                 bandwidth_hz: float = 20.0, damping: float = 1.0, gains=None,
                 max_substep: float = 5e-4, log_length: int = 600_000):
        if not max_substep > 0:
            raise ValueError(f"max_substep must be positive, got {max_substep}")
        if gains is None and not (bandwidth_hz > 0 and damping > 0):
            raise ValueError(f"bandwidth_hz and damping must be positive, got {bandwidth_hz}, {damping}")
        self.robot = robot
        self._base_params = params
        self.params = params
        if Theta0 is None:
            theta, _ = robot.inverse_kinematics(np.zeros((1, 3)), np.zeros((1, 3)))
            Theta0 = np.concatenate([theta[0], np.zeros(3)])
        self.Theta = np.array(Theta0, dtype=float).reshape(6)
        self.Thetad = np.zeros(6)
        self.X = robot.forward_kinematics(self.Theta[None], np.zeros(3))[0]
        self._last_valid = (self.Theta, self.X)
        self.force = np.zeros(6)
        self.external_force = np.zeros(6)
        self.t = 0.0
        self.max_substep = max_substep
        if gains is None:
            M, _ = self._dynamics()
            w = 2.0 * np.pi * bandwidth_hz
            diag = np.diag(M)
            gains = (diag * w**2, 2.0 * damping * diag * w)
        self.Kp, self.Kd = (np.array(g, dtype=float).reshape(6) for g in gains)
        self.log: deque[TruthSample] = deque(maxlen=log_length)

    # -- configuration ---------------------------------------------------------------------------
    def set_payload(self, mass: float, inertia: float = 0.0) -> None:
        """Add a payload (kg, kg·m² about the end-effector point) to the true ``m_ee``/``I_ee``.

        Replaces any previous payload; ``set_payload(0)`` removes it.
        """
        if mass < 0 or inertia < 0:
            raise ValueError(f"payload mass and inertia must be non-negative, got {mass}, {inertia}")
        p = self._base_params
        self.params = p.replace(m_ee=p.m_ee + mass, I_ee=p.I_ee + inertia)

    # -- dynamics --------------------------------------------------------------------------------
    def _dynamics(self):
        """Reduced mass matrix (6, 6) and velocity terms without friction (6,) at the current state.

        Raises:
            PlantJammed: no pose closes the chains at ``Theta``; the plant goes back to the last
                pose that closed them, at rest.
        """
        robot, Theta = self.robot, self.Theta[None]
        try:  # one forward kinematics per period: the pose and the dynamics from the same Motion
            motion = robot.motion_from_actuated(Theta, self.Thetad[None], np.zeros_like(Theta), self.X)
        except KinematicsError as exc:
            message = f"the simulated robot jammed at Theta = {np.round(self.Theta, 5).tolist()}: {exc}"
            self.Theta, self.X = self._last_valid
            self.Thetad = np.zeros(6)
            raise PlantJammed(message) from exc
        self.X = motion.X[0]
        self._last_valid = (self.Theta, self.X)
        M, c = robot.reduced_dynamics_of(motion, self.params)
        return M[0], c[0] - self._friction(self.Thetad)

    def _friction(self, Thetad) -> np.ndarray:
        return self.robot.friction(Thetad[None], self.params)[0]

    def _loop_force(self, Theta, Thetad, demand, demand_velocity, enabled, force_limit) -> np.ndarray:
        F = self.Kp * (demand - Theta) + self.Kd * (demand_velocity - Thetad)
        return np.where(enabled, np.clip(F, -force_limit, force_limit), 0.0)

    def control(self, demand, demand_velocity, enabled, force_limit) -> np.ndarray:
        """Actuator forces (6,) of the position loops at the current state (0 where disabled)."""
        return self._loop_force(self.Theta, self.Thetad, demand, demand_velocity, enabled, force_limit)

    def step(self, period, demand, enabled, force_limit) -> None:
        """Advance one period (s) under the demand polynomial ``demand`` (k, 6).

        ``demand[i]`` is the coefficient of ``t**i`` (``t`` from the period start, s), so that
        ``q_d(t) = sum_i demand[i] t**i``: rows position, velocity, ... (rad, m; per s**i).
        ``enabled`` (6,) bool: axes whose loop is closed (others are free); ``force_limit`` (6,)
        the drive's current limit as a force. The force at the period start is :attr:`force`.

        Raises:
            PlantJammed: the robot cannot move any more (see the module docstring).
        """
        demand = np.asarray(demand, dtype=float).reshape(-1, 6)
        powers = np.arange(len(demand))
        slope = demand[1:] * powers[1:, None]
        M, bias = self._dynamics()
        Theta0, Thetad0, X0 = self.Theta, self.Thetad, self.X
        M_inv = np.linalg.inv(M)
        external = self.external_force - bias

        def acceleration(Theta, Thetad, t):
            q_d = t ** powers @ demand
            v_d = t ** powers[:-1] @ slope if len(slope) else np.zeros(6)
            F = self._loop_force(Theta, Thetad, q_d, v_d, enabled, force_limit)
            return F, M_inv @ (F + external - self._friction(Thetad))

        self.force, a1 = acceleration(Theta0, Thetad0, 0.0)
        self.log.append(TruthSample(self.t, X0.copy(), Theta0.copy(), Thetad0.copy(), a1, self.force))
        n_sub = max(1, int(np.ceil(period / self.max_substep - 1e-9)))
        dt = period / n_sub
        Theta, Thetad = Theta0, Thetad0
        for k in range(n_sub):                                    # Heun: Euler predictor, trapezoid corrector
            if k:
                a1 = acceleration(Theta, Thetad, k * dt)[1]
            Thetad_p = Thetad + dt * a1
            a2 = acceleration(Theta + dt * Thetad, Thetad_p, (k + 1) * dt)[1]
            Theta = Theta + 0.5 * dt * (Thetad + Thetad_p)
            Thetad = Thetad + 0.5 * dt * (a1 + a2)
        self.Theta, self.Thetad = Theta, Thetad
        self.t += period

    def truth(self) -> dict[str, np.ndarray]:
        """The logged states as arrays: ``t`` (N,), ``X`` (N, 3), ``Theta``, ``Thetad``, ``Thetadd``, ``force`` (N, 6)."""
        samples = list(self.log)
        fields = ("t", "X", "Theta", "Thetad", "Thetadd", "force")
        if not samples:
            return {f: np.zeros((0,) if f == "t" else (0, 3 if f == "X" else 6)) for f in fields}
        return {f: np.array([getattr(s, f) for s in samples]) for f in fields}
