"""Feasibility check run before any trajectory moves hardware.

:func:`check_trajectory` tests every sample of a :class:`~trajectories.trajectory.Trajectory`
against the rig's :class:`Limits`: reach (the inverse kinematics discriminant), consistency of the
actuator columns with the pose, carriage stroke, actuator speed and acceleration (the stored
derivatives and the finite differences of the positions, so that a jump in a hand-edited file is
caught), and the singularity margins. The :class:`Report` names the first violation in time.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ident_hw.model import KinematicsError

from .trajectory import COLUMNS, Trajectory

if TYPE_CHECKING:
    from ident_hw.model import ThreePRRR
    from ident_hw.model.kinematics import SingularityMargins

ACTUATORS = [name for name, _ in COLUMNS["Theta"]]
UNITS = {"Theta": [u for _, u in COLUMNS["Theta"]], "Thetad": [u for _, u in COLUMNS["Thetad"]],
         "Thetadd": [u for _, u in COLUMNS["Thetadd"]]}
#: Largest accepted closure residual (m) of the stored pose and actuator columns.
CONSISTENCY_TOL = 1e-6


class InfeasibleTrajectory(RuntimeError):
    """A trajectory violates a limit of the rig; it must not be sent to the drives."""


@dataclass(frozen=True)
class Limits:
    """Limits of the rig (SI). Defaults are the nominal rig's; the config layer passes the real ones.

    Attributes:
        carriage_stroke: ``|zeta_i|`` allowed, m.
        carriage_speed, carriage_accel: m/s, m/s^2.
        revolute_speed, revolute_accel: rad/s, rad/s^2.
        min_serial_margin: smallest ``|sin(beta_i - theta_i)|`` allowed.
        max_cond_A: largest condition number of ``A`` allowed (parallel singularity).
    """

    carriage_stroke: float = 0.10
    carriage_speed: float = 0.1
    carriage_accel: float = 1.0
    revolute_speed: float = 3.0
    revolute_accel: float = 30.0
    min_serial_margin: float = 0.1
    max_cond_A: float = 50.0

    def __post_init__(self) -> None:
        for key, value in vars(self).items():
            if not value > 0:
                raise ValueError(f"limit {key} must be positive, got {value}")

    @property
    def max_speed(self) -> np.ndarray:
        """``(6,)`` speed limits of ``[theta1..3, zeta1..3]``."""
        return np.array([self.revolute_speed] * 3 + [self.carriage_speed] * 3)

    @property
    def max_accel(self) -> np.ndarray:
        """``(6,)`` acceleration limits of ``[theta1..3, zeta1..3]``."""
        return np.array([self.revolute_accel] * 3 + [self.carriage_accel] * 3)


@dataclass(frozen=True)
class Violation:
    """One limit violated at one sample.

    Attributes:
        time: s; sample: index; chain: 1..3, or ``None`` for the platform (cond(A)).
        quantity: ``"reach"``, ``"consistency"``, ``"stroke"``, ``"position"``, ``"speed"``,
            ``"acceleration"``, ``"serial margin"``, ``"cond(A)"``, or ``"set-point"`` (a set-point
            outside a drive's software position limits, found by the campaign's check).
        name: what was measured (e.g. ``"zeta2d"``); value and limit in ``unit``.
    """

    time: float
    sample: int
    chain: int | None
    quantity: str
    name: str
    value: float
    limit: float
    unit: str = ""

    def __str__(self) -> str:
        where = (f", chain {self.chain}" if self.chain else ", platform" if self.quantity == "cond(A)" else
                 "" if self.quantity == "set-point" else ", all chains")
        if self.quantity == "reach":
            return f"t = {self.time:.4f} s{where}: pose out of reach ({self.name})"
        relation = "below" if self.value < self.limit else "exceeds"    # a margin, a lower bound
        unit = f" {self.unit}" if self.unit else ""
        return (f"t = {self.time:.4f} s{where}: {self.quantity} {self.name} = {self.value:.6g}{unit} "
                f"{relation} limit {self.limit:.6g}{unit}")


@dataclass(frozen=True)
class Report:
    """Result of :func:`check_trajectory`: the earliest violation of each kind, earliest first."""

    trajectory: str
    violations: tuple[Violation, ...] = ()

    @property
    def ok(self) -> bool:
        """True when no limit is violated."""
        return not self.violations

    @property
    def first(self) -> Violation | None:
        """The violation that happens first in time, or ``None``."""
        return self.violations[0] if self.violations else None

    def raise_if_failed(self) -> None:
        """Raise :class:`InfeasibleTrajectory` naming the first violation, if any."""
        if self.violations:
            more = f" (+{len(self.violations) - 1} other violation(s))" if len(self.violations) > 1 else ""
            raise InfeasibleTrajectory(f"trajectory {self.trajectory!r} is infeasible: {self.first}{more}")

    def __str__(self) -> str:
        if self.ok:
            return f"trajectory {self.trajectory!r}: feasible"
        return "\n".join([f"trajectory {self.trajectory!r}: {len(self.violations)} violation(s)"]
                         + [f"  {v}" for v in self.violations])


def _first(found: list[Violation], t: np.ndarray, quantity: str, bad: np.ndarray, value: np.ndarray, limit,
           names, units, chains) -> None:
    """Record in ``found`` the earliest sample where the ``(N, k)`` mask ``bad`` is set (``limit``,
    ``names``, ``units``, ``chains``: per column)."""
    if not bad.any():
        return
    sample, col = np.argwhere(bad)[0]
    found.append(Violation(float(t[sample]), int(sample), chains[col], quantity, names[col],
                           float(value[sample, col]), float(limit[col]), units[col]))


def _rate_violations(found: list[Violation], traj: Trajectory, speed, accel, names, units, chains) -> None:
    """Speed and acceleration limits (per actuator) of the stored rates and of the finite
    differences of the positions and velocities; ``names`` and ``units``: ``(of the speeds, of
    the accelerations)``, each (a,)."""
    dt = np.diff(traj.t)[:, None]
    for quantity, derivative, position, limit, name, unit in (
            ("speed", traj.Thetad, traj.Theta, speed, names[0], units[0]),
            ("acceleration", traj.Thetadd, traj.Thetad, accel, names[1], units[1])):
        value = np.abs(derivative)
        _first(found, traj.t, quantity, value > limit, value, limit, name, unit, chains)
        # Mean rate over each step (finite difference), reported at the step's end: exceeds the
        # limit only if the true rate does within the step, or if the positions jump (hand edit).
        step = np.vstack([np.zeros((1, value.shape[1])), np.abs(np.diff(position, axis=0)) / dt])
        _first(found, traj.t, quantity, step > limit, step, limit, [f"{n} (finite difference)" for n in name],
               unit, chains)


@dataclass(frozen=True)
class ActuatorLimits:
    """Per actuator (a,): ``names``, position range ``low``/``high`` (rad or m), ``speed`` and
    ``accel`` limits (per s, per s²), ``units`` of the positions (``rad``, ``m``)."""

    names: tuple[str, ...]
    low: np.ndarray
    high: np.ndarray
    speed: np.ndarray
    accel: np.ndarray
    units: tuple[str, ...]


def check_actuator_limits(traj: Trajectory, limits: ActuatorLimits) -> Report:
    """Any robot: every actuator within its position range, speed and acceleration limits (the
    stored rates and the finite differences of the positions), the earliest violation of each."""
    found: list[Violation] = []
    chains = list(range(1, len(limits.names) + 1))
    for bad, limit in ((traj.Theta > limits.high, limits.high), (traj.Theta < limits.low, limits.low)):
        _first(found, traj.t, "position", bad, traj.Theta, limit, limits.names, limits.units, chains)
    rates = ([f"{u}/s" for u in limits.units], [f"{u}/s^2" for u in limits.units])
    _rate_violations(found, traj, limits.speed, limits.accel, (limits.names,) * 2, rates, chains)
    found.sort(key=lambda v: v.sample)
    return Report(traj.name, tuple(found))


def check_trajectory(traj: Trajectory, robot: ThreePRRR, limits: Limits) -> Report:
    """Check every sample of ``traj`` against ``limits`` on ``robot``; see the module docstring."""
    found: list[Violation] = []
    t = traj.t

    def first(quantity, bad, value, limit, names, units, chains) -> None:
        _first(found, t, quantity, bad, value, limit, names, units, chains)

    reachable = len(t)
    margins: SingularityMargins | None
    try:
        margins = robot.singularity_margins(traj.X, traj.zeta)
    except KinematicsError as exc:
        reachable, chain = exc.sample or 0, exc.chain
        x, y, alpha = traj.X[reachable]
        zeta = f", zeta{chain}={traj.zeta[reachable, chain - 1]:.4f} m" if chain else ""
        found.append(Violation(float(t[reachable]), reachable, chain, "reach",
                               f"x={x:.4f} m, y={y:.4f} m, alpha={np.degrees(alpha):.2f} deg{zeta}", np.nan, np.nan))
        margins = robot.singularity_margins(traj.X[:reachable], traj.zeta[:reachable]) if reachable else None
    if margins is not None:
        first("serial margin", margins.serial < limits.min_serial_margin, margins.serial,
              np.full(3, limits.min_serial_margin), ["|sin(beta - theta)|"] * 3, [""] * 3, [1, 2, 3])
        cond = margins.cond_A[:, None]
        first("cond(A)", cond > limits.max_cond_A, cond, [limits.max_cond_A], ["cond(A)"], [""], [None])
    residual = robot.closure_residual(traj.X, traj.Theta)[:, None]
    first("consistency", residual > CONSISTENCY_TOL, residual, [CONSISTENCY_TOL],
          ["closure residual of X and Theta"], ["m"], [None])

    stroke = np.abs(traj.zeta)
    first("stroke", stroke > limits.carriage_stroke, stroke, np.full(3, limits.carriage_stroke),
          ACTUATORS[3:], ["m"] * 3, [1, 2, 3])
    _rate_violations(found, traj, limits.max_speed, limits.max_accel,
                     tuple([n for n, _ in COLUMNS[key]] for key in ("Thetad", "Thetadd")),
                     (UNITS["Thetad"], UNITS["Thetadd"]), [1, 2, 3, 1, 2, 3])
    found.sort(key=lambda v: v.sample)
    return Report(traj.name, tuple(found))
