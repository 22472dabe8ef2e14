"""The simulated robot behind the emulated drives: its dynamics under one position loop per actuator.

Each actuator is driven by a drive-side position controller, PD plus velocity feed-forward,
``F = Kp (q_d - q) + Kd (qd_d - qd)``, clipped to the drive's current limit. Within a period the
demand ``q_d(t)`` is a polynomial handed over by the drive (the set-point interpolation of
:mod:`drivers.sim.drive`, continuous up to its acceleration); since it is continuous with its
first derivative across periods, so is the force, and the force at a period start is the force
of that instant, not a one-sided value. There is no acceleration feed-forward. The plant moves by
the forward dynamics in the actuated coordinates of any
:class:`ident_hw.model.interface.RobotModel` (the 3PRRR's closed chains, the Delta) with the
*true* parameters (friction included). The reduced mass matrix ``M`` and the velocity terms are
evaluated once per period, at its start (the expensive part), and extrapolated linearly over the
period from the previous period's start (held constant, they would make the motion drift from
the model by O(period), a bias of the identified link friction); the controller and the friction are
re-evaluated at every substep of at most ``max_substep``, and
the state advances by Heun's method (second order: the position loops and the smoothed Coulomb
friction are the stiff part, and first-order Euler at 0.5 ms left force errors of a few percent).

The log holds, at each period start, the state, the actuator forces and the *exact*
acceleration ``M^-1 (F - c)`` of that state: the logged forces are the model's inverse dynamics
of the logged motion to rounding, whatever the integration error.

If the commanded motion drives the robot into a parallel (type II) singularity or out of
reach, the forward kinematics has no solution any more: :meth:`Plant.step` raises :class:`PlantJammed` and
the plant stays at its last valid pose, at rest (the rig reports it as a following error).

Everything here is SI: rad, m, N·m, N, s; ``n`` is the robot's number of actuators; the drive units (counts, rpm, mA) belong to the rig.
"""

from __future__ import annotations

from collections import deque

import numba
import numpy as np

from ident_hw.model import KinematicsError
from ident_hw.model.interface import RobotModel


#: s, the plant's integration step unless configured (``sim.max_substep``)
DEFAULT_MAX_SUBSTEP = 5e-4


@numba.njit(cache=True)
def _heun(Theta, Thetad, dt, n_sub, M_inv0, M_slope, bias0, bias_slope, loop_demand, Kp, Kd, low, high,
          f_v, f_c, width):
    """``n_sub`` Heun steps of ``dt`` s (Euler predictor, trapezoid corrector) of
    ``Thetadd = M^-1(t) (F - bias(t) - f_v Thetad - f_c tanh(Thetad / width))`` with the loop force
    ``F = clip(loop_demand[k] - Kp Theta - Kd Thetad, low, high)`` at substep boundary ``k`` and
    ``M^-1``, ``bias`` linear in ``t``. Returns the end state, and the force and acceleration at
    the start. Compiled (numba): it is most of the simulated rig's work per SYNC."""
    n = Theta.shape[0]
    F = np.empty(n)
    u = np.empty(n)

    def acceleration(q, qd, k, out_force):
        t = k * dt
        for j in range(n):
            f = loop_demand[k, j] - Kp[j] * q[j] - Kd[j] * qd[j]
            f = min(max(f, low[j]), high[j])
            out_force[j] = f
            u[j] = f - (bias0[j] + t * bias_slope[j]) - (f_v[j] * qd[j] + f_c[j] * np.tanh(qd[j] / width))
        a = np.empty(n)
        for r in range(n):
            acc = 0.0
            for j in range(n):
                acc += (M_inv0[r, j] + t * M_slope[r, j]) * u[j]
            a[r] = acc
        return a

    force0 = np.empty(n)
    q, qd = Theta.copy(), Thetad.copy()
    a1 = acceleration(q, qd, 0, force0)
    a0 = a1.copy()
    for k in range(n_sub):
        if k:
            a1 = acceleration(q, qd, k, F)
        qd_p = qd + dt * a1
        a2 = acceleration(q + dt * qd, qd_p, k + 1, F)
        q = q + 0.5 * dt * (qd + qd_p)
        qd = qd + 0.5 * dt * (a1 + a2)
    return q, qd, force0, a0


_compiled = False


def _compile_heun() -> None:
    """Compile :func:`_heun` (or load it from numba's cache) now, with the argument types of
    :meth:`Plant.step`, so that a rig's first SYNC does not wait for the compiler (seconds on a
    host, minutes in an emulated guest without a cache)."""
    global _compiled
    if not _compiled:
        z6, z66 = np.zeros(6), np.zeros((6, 6))
        _heun(z6, z6, 1e-3, 1, z66, z66, z6, z6, np.zeros((2, 6)), z6, z6, z6, z6, z6, z6, 1e-3)
        _compiled = True


class PlantJammed(RuntimeError):
    """The mechanism cannot follow: its forward kinematics failed (parallel singularity crossed)."""


class TruthLog:
    """The last ``length`` logged plant states, one row per period start, in numpy chunks.

    Fields (SI): ``t`` (s), ``X`` (pose_size,) pose, ``Theta``, ``Thetad``, ``Thetadd``, ``force``
    (n,) each. No Python object per period: a long run neither grows the garbage collector's work
    (see :mod:`drivers.gc_freeze`) nor keeps more than ``length`` rows.
    """

    CHUNK = 4096  # rows per chunk

    def __init__(self, length: int, n: int, pose_size: int):
        if length < 1:
            raise ValueError(f"log_length must be at least 1, got {length}")
        self.length = length
        self.fields = {"t": 1, "X": pose_size, "Theta": n, "Thetad": n, "Thetadd": n, "force": n}
        self._width = sum(self.fields.values())
        self._chunks: deque[np.ndarray] = deque()
        self._fill = self.CHUNK   # rows used in the last chunk
        self._rows = 0            # rows held (all chunks)

    def append(self, t: float, *fields: np.ndarray) -> None:
        """Log one state: ``t`` and the arrays in the order of :attr:`fields` after ``t``."""
        if self._fill == self.CHUNK:
            self._chunks.append(np.empty((self.CHUNK, self._width)))
            self._fill = 0
        row = self._chunks[-1][self._fill]
        row[0] = t
        np.concatenate(fields, out=row[1:])
        self._fill += 1
        self._rows += 1
        if self._rows - self.CHUNK >= self.length:   # the oldest chunk holds only dropped rows
            self._chunks.popleft()
            self._rows -= self.CHUNK

    def __len__(self) -> int:
        return min(self._rows, self.length)

    def arrays(self) -> dict[str, np.ndarray]:
        """The logged states as arrays: ``t`` (N,), ``X`` (N, pose_size), the others (N, n)."""
        if self._chunks:
            data = np.concatenate(self._chunks)[: self._rows][-self.length:]
        else:
            data = np.zeros((0, self._width))
        out, column = {}, 0
        for name, width in self.fields.items():
            out[name] = data[:, column] if name == "t" else data[:, column: column + width]
            column += width
        return out


class Plant:
    """A robot with its true parameters and ``n`` position-controlled actuators.

    Args:
        robot: the kinematic/dynamic model (:class:`~ident_hw.model.interface.RobotModel`).
        params: the TRUE parameters (what identification should find), as the model takes them.
        Theta0: initial actuated coordinates (n,); default: the robot's home.
        bandwidth_hz, damping: position-loop bandwidth and damping ratio; the gains of axis ``j``
            are ``Kp = M_jj w^2`` and ``Kd = 2 damping M_jj w`` with ``M`` the mass matrix at ``Theta0``.
        gains: explicit ``(Kp, Kd)`` arrays (n,) instead (N/m, N·s/m or N·m/rad, N·m·s/rad).
        max_substep: largest integration step in s.
        log_length: number of periods kept in :attr:`log`.
    """

    def __init__(self, robot: RobotModel, params, Theta0=None, *,
                 bandwidth_hz: float = 20.0, damping: float = 1.0, gains=None,
                 max_substep: float = DEFAULT_MAX_SUBSTEP, log_length: int = 600_000):
        if not max_substep > 0:
            raise ValueError(f"max_substep must be positive, got {max_substep}")
        if gains is None and not (bandwidth_hz > 0 and damping > 0):
            raise ValueError(f"bandwidth_hz and damping must be positive, got {bandwidth_hz}, {damping}")
        self.robot = robot
        self.n = n = len(robot.actuator_names)
        self._base_params = params
        self.params = params
        if Theta0 is None:
            Theta0 = robot.home_actuated()
        self.Theta = np.array(Theta0, dtype=float).reshape(n)
        self.Thetad = np.zeros(n)
        self.X = robot.pose(self.Theta, np.zeros(robot.pose_size))
        self._last_valid = (self.Theta, self.X)
        self.force = np.zeros(n)
        self.external_force = np.zeros(n)
        self.t = 0.0
        self._previous = None   # (period, M^-1, velocity terms) of the last step, at its start
        self.max_substep = max_substep
        if gains is None:
            M, _ = self._dynamics()
            w = 2.0 * np.pi * bandwidth_hz
            diag = np.diag(M)
            gains = (diag * w**2, 2.0 * damping * diag * w)
        self.Kp, self.Kd = (np.array(g, dtype=float).reshape(n) for g in gains)
        self.log = TruthLog(log_length, n, robot.pose_size)
        _compile_heun()

    # -- configuration ---------------------------------------------------------------------------
    def set_payload(self, mass: float, inertia: float = 0.0) -> None:
        """Add a payload (kg, kg·m² about the end-effector point) to the true parameters
        (:meth:`~ident_hw.model.interface.RobotModel.with_payload`).

        Replaces any previous payload; ``set_payload(0)`` removes it.
        """
        if mass < 0 or inertia < 0:
            raise ValueError(f"payload mass and inertia must be non-negative, got {mass}, {inertia}")
        self.params = self.robot.with_payload(self._base_params, mass, inertia)
        self._previous = None   # the dynamics jump: no extrapolation across the change

    # -- dynamics --------------------------------------------------------------------------------
    def _dynamics(self):
        """Mass matrix (n, n) and bias forces without friction (n,) at the current state.

        Raises:
            PlantJammed: no pose closes the chains at ``Theta``; the plant goes back to the last
                pose that closed them, at rest.
        """
        try:  # one forward kinematics: the pose and the dynamics of the same state
            M, c, self.X = self.robot.plant_dynamics(self.Theta, self.Thetad, self.params, self.X)
        except KinematicsError as exc:
            message = f"the simulated robot jammed at Theta = {np.round(self.Theta, 5).tolist()}: {exc}"
            self.Theta, self.X = self._last_valid
            self.Thetad = np.zeros(self.n)
            self._previous = None
            raise PlantJammed(message) from exc
        self._last_valid = (self.Theta, self.X)
        return M, c

    def _loop_force(self, Theta, Thetad, demand, demand_velocity, enabled, force_limit) -> np.ndarray:
        F = self.Kp * (demand - Theta) + self.Kd * (demand_velocity - Thetad)
        return np.where(enabled, np.clip(F, -force_limit, force_limit), 0.0)

    def control(self, demand, demand_velocity, enabled, force_limit) -> np.ndarray:
        """Actuator forces (n,) of the position loops at the current state (0 where disabled)."""
        return self._loop_force(self.Theta, self.Thetad, demand, demand_velocity, enabled, force_limit)

    def step(self, period, demand, enabled, force_limit) -> None:
        """Advance one period (s) under the demand polynomial ``demand`` (k, n).

        ``demand[i]`` is the coefficient of ``t**i`` (``t`` from the period start, s), so that
        ``q_d(t) = sum_i demand[i] t**i``: rows position, velocity, ... (rad, m; per s**i).
        ``enabled`` (n,) bool: axes whose loop is closed (others are free); ``force_limit`` (n,)
        the drive's current limit as a force. The force at the period start is :attr:`force`.

        Raises:
            PlantJammed: the robot cannot move any more (see the module docstring).
        """
        n = self.n
        demand = np.asarray(demand, dtype=float).reshape(-1, n)
        M, bias = self._dynamics()
        n_sub = max(1, int(np.ceil(period / self.max_substep - 1e-9)))
        dt = period / n_sub
        # the demand and its slope at every substep boundary, in one product each: (n_sub + 1, n)
        powers = np.arange(len(demand))
        t_pow = (np.arange(n_sub + 1) * dt)[:, None] ** powers
        q_d = t_pow @ demand
        v_d = t_pow[:, :-1] @ (demand[1:] * powers[1:, None])
        # a disabled loop gives no force: clipped to [0, 0]
        high = np.where(enabled, force_limit, 0.0)
        low = -high
        Kp, Kd = self.Kp, self.Kd
        # M^-1 and the velocity terms: exact at the period start (logged), extrapolated linearly
        # over the period from the previous period's start (second order in the period)
        M_inv0 = np.linalg.inv(M)
        M_slope, bias_slope = np.zeros((n, n)), np.zeros(n)      # per s of the period
        previous, self._previous = self._previous, (period, M_inv0, bias)
        if previous is not None and 0.5 * period <= previous[0] <= 2 * period:   # not after a much shorter step
            M_slope = (M_inv0 - previous[1]) / previous[0]              # previous[0]: its period
            bias_slope = (bias - previous[2]) / previous[0]
        # the hot loop (two evaluations per substep), compiled: the loop's demand part computed
        # once per period, the loop force and the friction as in _loop_force and friction_coefficients
        loop_demand = Kp * q_d + Kd * v_d
        f_v, f_c = self.robot.friction_coefficients(self.params)
        Theta, Thetad, self.force, a0 = _heun(
            self.Theta, self.Thetad, dt, n_sub, M_inv0, M_slope, bias - self.external_force, bias_slope,
            loop_demand, Kp, Kd, low, high, f_v, f_c, float(self.robot.coulomb_width))
        self.log.append(self.t, self.X, self.Theta, self.Thetad, a0, self.force)
        self.Theta, self.Thetad = Theta, Thetad
        self.t += period

    def truth(self) -> dict[str, np.ndarray]:
        """The logged states as arrays: ``t`` (N,), ``X`` (N, pose_size), ``Theta``, ``Thetad``, ``Thetadd``, ``force`` (N, n)."""
        return self.log.arrays()
