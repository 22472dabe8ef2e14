"""The simulated robot behind the emulated drives: its dynamics under one position loop per actuator.

:class:`Plant` moves any :class:`ident_hw.model.interface.RobotModel` by its forward dynamics in
the actuated coordinates, with the *true* parameters (friction included), each actuator under a
drive-side PD loop with velocity feed-forward on the demand polynomial the drive hands over
(:mod:`drivers.sim.drive`). Per period the mass matrix and velocity terms are evaluated at the
start and extrapolated over it; the state advances by classical Runge-Kutta substeps of at most
``max_substep``, the loop and friction re-evaluated at each. The log holds, at each period start,
the state, the actuator forces and the exact acceleration of that state. A motion into a type II
singularity or out of reach raises :class:`PlantJammed`. Why the integration is this accurate,
and what the identification needs of it: ``docs/simulated-rig.md``.

Everything here is SI: rad, m, N·m, N, s; ``n`` is the robot's number of actuators; the drive
units (counts, rpm, mA) belong to the rig.
"""

from __future__ import annotations

from collections import deque

import numba
import numpy as np

from ident_hw.model import KinematicsError
from ident_hw.model.described import DescribedData, DescribedRobot
from ident_hw.model.interface import RobotModel


#: s, the plant's integration step unless configured (``sim.max_substep``)
DEFAULT_MAX_SUBSTEP = 5e-4


@numba.njit(cache=True, nogil=True)
def _rk4(Theta, Thetad, dt, n_sub, M_inv0, M_lin, M_quad, bias0, bias_lin, bias_quad, loop_demand, Kp, Kd, low,
         high, f_v, f_c, width):
    """``n_sub`` classical Runge-Kutta steps of ``dt`` s of
    ``Thetadd = M^-1(t) (F - bias(t) - f_v Thetad - f_c tanh(Thetad / width))`` with the loop force
    ``F = clip(loop_demand[i] - Kp Theta - Kd Thetad, low, high)`` at half-substep ``i`` and
    ``M^-1(t) = M_inv0 + t M_lin + t^2 M_quad``, ``bias(t)`` likewise. Returns the end state, and
    the force and acceleration at the start."""
    n = Theta.shape[0]
    F = np.empty(n)
    u = np.empty(n)

    def acceleration(q, qd, i, out_force):
        t = 0.5 * i * dt
        for j in range(n):
            f = loop_demand[i, j] - Kp[j] * q[j] - Kd[j] * qd[j]
            f = min(max(f, low[j]), high[j])
            out_force[j] = f
            b = bias0[j] + t * (bias_lin[j] + t * bias_quad[j])
            u[j] = f - b - (f_v[j] * qd[j] + f_c[j] * np.tanh(qd[j] / width))
        a = np.empty(n)
        for r in range(n):
            acc = 0.0
            for j in range(n):
                acc += (M_inv0[r, j] + t * (M_lin[r, j] + t * M_quad[r, j])) * u[j]
            a[r] = acc
        return a

    force0 = np.empty(n)
    q, qd = Theta.copy(), Thetad.copy()
    a1 = acceleration(q, qd, 0, force0)
    a0 = a1.copy()
    for k in range(n_sub):
        if k:
            a1 = acceleration(q, qd, 2 * k, F)
        v2 = qd + 0.5 * dt * a1
        a2 = acceleration(q + 0.5 * dt * qd, v2, 2 * k + 1, F)
        v3 = qd + 0.5 * dt * a2
        a3 = acceleration(q + 0.5 * dt * v2, v3, 2 * k + 1, F)
        v4 = qd + dt * a3
        a4 = acceleration(q + dt * v3, v4, 2 * k + 2, F)
        q += dt / 6.0 * (qd + 2.0 * v2 + 2.0 * v3 + v4)
        qd += dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return q, qd, force0, a0


@numba.njit(cache=True, nogil=True)
def _extrapolation(f0, f1, f2, h1, h2, quadratic, lin, quad):
    """Into ``lin``, ``quad`` (each like ``f0``, 1-D): ``f(t) = f0 + t lin + t^2 quad`` through
    ``f0`` at ``t = 0``, ``f1`` at ``-h1`` and, if ``quadratic``, ``f2`` at ``-h1 - h2``, element by
    element (Newton's form: ``f0 + t f[0, -h1] + t (t + h1) f[0, -h1, -h1 - h2]``)."""
    for r in range(f0.shape[0]):
        d1 = (f0[r] - f1[r]) / h1
        d2 = ((d1 - (f1[r] - f2[r]) / h2) / (h1 + h2)) if quadratic else 0.0
        lin[r], quad[r] = d1 + h1 * d2, d2


_V, _M = numba.float64[::1], numba.float64[:, ::1]


# the argument types given: a call with other types (e.g. a non-contiguous array) is refused
# instead of compiling a new version while a rig waits for its SYNC
@numba.njit((_V, _V, numba.float64, numba.int64, _M, _V, _V, numba.float64, _M, _V, numba.float64, _M, _V,
             _M, _V, _V, numba.boolean[::1], _V, _V, _V, numba.float64), cache=True, nogil=True)
def _period(Theta, Thetad, period, n_sub, M, bias, external, h1, M_inv1, bias1, h2, M_inv2, bias2,
            demand, Kp, Kd, enabled, force_limit, f_v, f_c, width):
    """One period of :meth:`Plant.step`, compiled and without the GIL (most of the simulated
    rig's work per SYNC; the master's thread runs meanwhile).

    ``M`` (n, n), ``bias`` (n,): the dynamics at the period start (``external`` (n,): a force on
    the actuators, held over the period, subtracted from ``bias``); ``M_inv1``, ``bias1``: those
    of the previous period's start, ``h1`` s earlier, and ``M_inv2``, ``bias2`` of the one before,
    ``h2`` s before that (0: none). ``M^-1`` and ``bias`` are extrapolated over the period by the
    polynomial through these points (quadratic with two, linear with one; a previous step outside
    half to twice the period is not used). ``demand`` (k, n): the demand polynomial's
    coefficients. Returns the end state ``Theta``, ``Thetad``, the force and the acceleration at
    the start, and ``M^-1`` (for the next periods).
    """
    n = Theta.shape[0]
    dt = period / n_sub
    M_inv0 = np.ascontiguousarray(np.linalg.inv(M))    # C order, as the next period's argument type
    M_lin, M_quad, bias_lin, bias_quad = np.zeros((n, n)), np.zeros((n, n)), np.zeros(n), np.zeros(n)
    if 0.5 * period <= h1 <= 2.0 * period:
        quadratic = 0.5 * period <= h2 <= 2.0 * period
        _extrapolation(bias, bias1, bias2, h1, h2, quadratic, bias_lin, bias_quad)
        _extrapolation(M_inv0.reshape(-1), M_inv1.reshape(-1), M_inv2.reshape(-1), h1, h2, quadratic,
                       M_lin.reshape(-1), M_quad.reshape(-1))
    # the loop's demand part at every half substep: Kp q_d(t_i) + Kd qd_d(t_i)
    loop_demand = np.empty((2 * n_sub + 1, n))
    for i in range(2 * n_sub + 1):
        t = 0.5 * i * dt
        for j in range(n):
            q_d, v_d, t_i = 0.0, 0.0, 1.0
            for c in range(demand.shape[0]):
                q_d += demand[c, j] * t_i
                if c + 1 < demand.shape[0]:
                    v_d += (c + 1) * demand[c + 1, j] * t_i
                t_i *= t
            loop_demand[i, j] = Kp[j] * q_d + Kd[j] * v_d
    # a disabled loop gives no force: clipped to [0, 0]
    low, high, bias0 = np.empty(n), np.empty(n), np.empty(n)
    for j in range(n):
        high[j] = force_limit[j] if enabled[j] else 0.0
        low[j] = -high[j]
        bias0[j] = bias[j] - external[j]
    q, qd, force0, a0 = _rk4(Theta, Thetad, dt, n_sub, M_inv0, M_lin, M_quad, bias0, bias_lin, bias_quad,
                             loop_demand, Kp, Kd, low, high, f_v, f_c, width)
    return q, qd, force0, a0, M_inv0


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
        """Log one state: ``t`` and the arrays in the order of ``fields`` after ``t``."""
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
        log_length: number of periods kept in ``log``.
    """

    def __init__(self, robot: RobotModel, params, Theta0=None, *,
                 bandwidth_hz: float = 20.0, damping: float = 1.0, gains=None,
                 max_substep: float = DEFAULT_MAX_SUBSTEP, log_length: int = 600_000):
        if not max_substep > 0:
            raise ValueError(f"max_substep must be positive, got {max_substep}")
        if gains is None and not (bandwidth_hz > 0 and damping > 0):
            raise ValueError(f"bandwidth_hz and damping must be positive, got {bandwidth_hz}, {damping}")
        self.robot = robot
        # a described robot's data of the plant's own (the closure state its periods carry, the
        # warm start of the next): the identification of the same robot in this process keeps its own
        self._data: DescribedData | None = robot.create_data() if isinstance(robot, DescribedRobot) else None
        start = np.zeros(robot.pose_size)
        self.n = n = len(robot.actuator_names)
        self._base_params = params
        self.params = params
        if Theta0 is None:
            Theta0 = robot.home_actuated()
        self.Theta = np.array(Theta0, dtype=float).reshape(n)
        self.Thetad = np.zeros(n)
        if isinstance(robot, DescribedRobot):
            self.X = robot.pose(self.Theta, start, data=self._data)
        else:
            self.X = robot.pose(self.Theta, start)
        self._last_valid = (self.Theta, self.X)
        self.force = np.zeros(n)
        self.external_force = np.zeros(n)
        self.t = 0.0
        # (period, M^-1, velocity terms) at the start of the last two steps, the latest first
        self._previous: deque = deque(maxlen=2)
        self._friction = (None, None, None)   # (params, f_v, f_c) of the last step
        self.max_substep = max_substep
        M, _ = self._dynamics()     # also compiles the robot's plant dynamics now, not at the first SYNC
        if gains is None:
            w = 2.0 * np.pi * bandwidth_hz
            diag = np.diag(M)
            gains = (diag * w**2, 2.0 * damping * diag * w)
        self.Kp, self.Kd = (np.array(g, dtype=float).reshape(n) for g in gains)
        self.log = TruthLog(log_length, n, robot.pose_size)

    # -- configuration ---------------------------------------------------------------------------
    def set_payload(self, mass: float, inertia: float = 0.0) -> None:
        """Add a payload (kg, kg·m² about the end-effector point) to the true parameters
        (:meth:`~ident_hw.model.interface.RobotModel.with_payload`).

        Replaces any previous payload; ``set_payload(0)`` removes it.
        """
        if mass < 0 or inertia < 0:
            raise ValueError(f"payload mass and inertia must be non-negative, got {mass}, {inertia}")
        self.params = self.robot.with_payload(self._base_params, mass, inertia)
        self._previous.clear()   # the dynamics jump: no extrapolation across the change

    # -- dynamics --------------------------------------------------------------------------------
    def _dynamics(self):
        """Mass matrix (n, n) and bias forces without friction (n,) at the current state.

        Raises:
            PlantJammed: no pose closes the chains at ``Theta``; the plant goes back to the last
                pose that closed them, at rest.
        """
        try:  # one forward kinematics: the pose and the dynamics of the same state
            robot = self.robot
            if isinstance(robot, DescribedRobot):
                state = robot.plant_dynamics(self.Theta, self.Thetad, self.params, self.X, data=self._data)
            else:
                state = robot.plant_dynamics(self.Theta, self.Thetad, self.params, self.X)
            M, c, self.X = state.M, state.bias, state.pose
        except KinematicsError as exc:
            message = f"the simulated robot jammed at Theta = {np.round(self.Theta, 5).tolist()}: {exc}"
            self.Theta, self.X = self._last_valid
            self.Thetad = np.zeros(self.n)
            self._previous.clear()
            raise PlantJammed(message) from exc
        self._last_valid = (self.Theta, self.X)
        return M, c

    def _loop_force(self, Theta, Thetad, demand, demand_velocity, enabled, force_limit) -> np.ndarray:
        F = self.Kp * (demand - Theta) + self.Kd * (demand_velocity - Thetad)
        return np.where(enabled, np.clip(F, -force_limit, force_limit), 0.0)

    def control(self, demand, demand_velocity, enabled, force_limit) -> np.ndarray:
        """Actuator forces (n,) of the position loops at the current state (0 where disabled)."""
        return self._loop_force(self.Theta, self.Thetad, demand, demand_velocity, enabled, force_limit)

    def step(self, period, demand, enabled, force_limit, remember: bool = True) -> None:
        """Advance one period (s) under the demand polynomial ``demand`` (k, n).

        ``demand[i]`` is the coefficient of ``t**i`` (``t`` from the period start, s), so that
        ``q_d(t) = sum_i demand[i] t**i``: rows position, velocity, ... (rad, m; per s**i).
        ``enabled`` (n,) bool: axes whose loop is closed (others are free); ``force_limit`` (n,)
        the drive's current limit as a force. The force at the period start is ``force``.
        ``remember``: keep this period's dynamics for extrapolating the next periods'; False
        for a step whose length the host's clock chose (the rig's idle steps), which must not
        reach the motion of the SYNC-driven steps after it.

        Raises:
            PlantJammed: the robot cannot move any more (see the module docstring).
        """
        n = self.n
        demand = np.asarray(demand, dtype=float).reshape(-1, n)
        M, bias = self._dynamics()
        n_sub = max(1, int(np.ceil(period / self.max_substep - 1e-9)))
        (h1, M_inv1, bias1), (h2, M_inv2, bias2) = (list(self._previous) + [(0.0, M, bias)] * 2)[:2]
        if self._friction[0] is not self.params:
            self._friction = (self.params, *(np.ascontiguousarray(v, dtype=float)
                                             for v in self.robot.friction_coefficients(self.params)))
        _, f_v, f_c = self._friction
        c = np.ascontiguousarray
        Theta, Thetad, self.force, a0, M_inv0 = _period(
            c(self.Theta), c(self.Thetad), float(period), n_sub, c(M), c(bias), c(self.external_force),
            float(h1), c(M_inv1), c(bias1), float(h2), c(M_inv2), c(bias2), c(demand), c(self.Kp), c(self.Kd),
            c(enabled, dtype=bool), c(force_limit, dtype=float), f_v, f_c, float(self.robot.coulomb_width))
        # M^-1 and the velocity terms: exact at the period start (logged), extrapolated over the
        # period through the two previous periods' starts (third order in the period)
        if remember:
            self._previous.appendleft((period, M_inv0, bias))
        else:
            self._previous.clear()
        self.log.append(self.t, self.X, self.Theta, self.Thetad, a0, self.force)
        self.Theta, self.Thetad = Theta, Thetad
        self.t += period

    def truth(self) -> dict[str, np.ndarray]:
        """The logged states as arrays: ``t`` (N,), ``X`` (N, pose_size), ``Theta``, ``Thetad``, ``Thetadd``, ``force`` (N, n)."""
        return self.log.arrays()
