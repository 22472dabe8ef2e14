"""The simulated 3PRRR behind the emulated drives: closed-chain dynamics under six position loops.

Each actuator is driven by a drive-side position controller, PD plus velocity feed-forward,
``F = Kp (q_d - q) + Kd (qd_d - qd)``, clipped to the drive's current limit. The plant moves by
the closed-chain forward dynamics of :class:`ident_hw.model.ThreePRRR` with the *true*
parameters (friction included), integrated by semi-implicit Euler in substeps of at most
``max_substep``. The reduced mass matrix and the velocity terms are evaluated once per period
(the expensive part, one model evaluation); the controller and the friction are re-evaluated
at every substep.

Everything here is SI: rad, m, N·m, N, s; the drive units (counts, rpm, mA) belong to the rig.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from ident_hw.model import InertialParams, ThreePRRR
from ident_hw.model.dynamics import friction, reduced_dynamics


@dataclass(frozen=True)
class TruthSample:
    """One logged plant state at a period start: ``t`` (s), each other field (6,) in SI."""

    t: float
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
        self.robot = robot
        self._base_params = params
        self.params = params
        if Theta0 is None:
            theta, _ = robot.inverse_kinematics(np.zeros((1, 3)), np.zeros((1, 3)))
            Theta0 = np.concatenate([theta[0], np.zeros(3)])
        self.Theta = np.array(Theta0, dtype=float).reshape(6)
        self.Thetad = np.zeros(6)
        self.X = robot.forward_kinematics(self.Theta[None], np.zeros(3))[0]
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
        """Reduced mass matrix (6, 6) and velocity terms without friction (6,) at the current state."""
        motion = self.robot.motion_from_actuated(self.Theta[None], self.Thetad[None], np.zeros((1, 6)), self.X)
        self.X = motion.X[0]
        M, c = reduced_dynamics(self.robot.kinematics, motion, self.params, self.robot.coulomb_width)
        return M[0], c[0] - friction(self.Thetad, self.params, self.robot.coulomb_width)

    def control(self, demand, demand_velocity, enabled, force_limit) -> np.ndarray:
        """Actuator forces (6,) of the position loops at the current state (0 where disabled)."""
        F = self.Kp * (demand - self.Theta) + self.Kd * (demand_velocity - self.Thetad)
        return np.where(enabled, np.clip(F, -force_limit, force_limit), 0.0)

    def step(self, period, demand, demand_velocity, enabled, force_limit) -> None:
        """Advance one period (s). The demand ramps from ``demand`` at ``demand_velocity`` (each (6,)).

        ``enabled`` (6,) bool: axes whose loop is closed (others are free); ``force_limit`` (6,)
        the drive's current limit as a force. The force at the period start is :attr:`force`.
        """
        n_sub = max(1, int(np.ceil(period / self.max_substep - 1e-9)))
        dt = period / n_sub
        M, bias = self._dynamics()
        M_inv = np.linalg.inv(M)
        width = self.robot.coulomb_width
        for k in range(n_sub):
            F = self.control(demand + demand_velocity * (k * dt), demand_velocity, enabled, force_limit)
            acc = M_inv @ (F + self.external_force - bias - friction(self.Thetad, self.params, width))
            if k == 0:
                self.force = F
                self.log.append(TruthSample(self.t, self.Theta.copy(), self.Thetad.copy(), acc, F))
            self.Thetad = self.Thetad + dt * acc
            self.Theta = self.Theta + dt * self.Thetad
        self.t += period

    def truth(self) -> dict[str, np.ndarray]:
        """The logged states as arrays: ``t`` (N,), ``Theta``, ``Thetad``, ``Thetadd``, ``force`` (N, 6)."""
        samples = list(self.log)
        fields = ("t", "Theta", "Thetad", "Thetadd", "force")
        if not samples:
            return {f: np.zeros((0,) if f == "t" else (0, 6)) for f in fields}
        return {f: np.array([getattr(s, f) for s in samples]) for f in fields}
