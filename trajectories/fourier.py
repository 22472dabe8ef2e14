"""Optimised excitation: finite Fourier series on the pose and the carriages (the SVD-DLS paper, eqs. 84–86).

Each coordinate ``j`` of ``q = [x, y, alpha, zeta1, zeta2, zeta3]`` follows

    f_j(t) = c_j + sum_{k=1..H} a_jk / (k w) sin(k w t) - b_jk / (k w) cos(k w t)        (eq. 84)
    q_j(t) = home_j + e(t) f_j(t)

with ``w = 2 pi f0`` the base frequency, so ``a_jk``, ``b_jk`` are velocity amplitudes (eq. 85).
The envelope ``e(t)`` rises from 0 to 1 over ``ramp`` seconds with the quintic profile and falls back
at the end, so the motion starts and ends at home at rest, C2. Derivatives are analytic.

:func:`optimise_excitation` chooses the coefficients (seeded random start, L-BFGS-B) to minimise
``cond(W)`` — the 2-norm condition number of the stacked base regressor itself, not of ``W^T W``
— where ``W`` stacks the regressor rows of every sample (``N x 6`` rows, SI: N·m and N) restricted
to the base columns and each column divided by its RMS on a fixed rich reference data set
(:func:`base_scaling`), so the criterion does not depend on the parameter units. Reach, stroke, speed, acceleration and singularity-margin
limits enter as quadratic penalties above 90 % of each limit; the result is checked afterwards with
:func:`trajectories.feasibility.check_trajectory`.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg import qr
from scipy.optimize import minimize

from ident_hw.model import KinematicsError

from .feasibility import Limits
from .motion import SampledMotion
from .paths import HOME_POSE
from .timing import quintic, time_grid
from .trajectory import Trajectory

if TYPE_CHECKING:
    from ident_hw.model import ThreePRRR

#: Velocity scale of the optimisation variables per coordinate (m/s, m/s, rad/s, m/s x3).
VELOCITY_SCALE = np.array([0.05, 0.05, 0.3, 0.03, 0.03, 0.03])
#: Fraction of each limit above which the penalty starts.
PENALTY_START = 0.9
PENALTY_WEIGHT = 100.0


@dataclass(frozen=True)
class FourierExcitation:
    """Coefficients of the excitation (see module docstring); SI units.

    Attributes:
        base_frequency: ``f0`` in Hz.
        duration: total time, s (a whole number of base periods is usual).
        ramp: envelope rise and fall time, s.
        offset: ``(6,)`` ``c_j``.
        a, b: ``(6, H)`` velocity amplitudes of the sine and cosine terms of eq. 84.
    """

    base_frequency: float
    duration: float
    ramp: float
    offset: np.ndarray
    a: np.ndarray
    b: np.ndarray

    def __post_init__(self) -> None:
        for key in ("offset", "a", "b"):
            object.__setattr__(self, key, np.asarray(getattr(self, key), dtype=float))
        if self.a.shape != self.b.shape or self.a.ndim != 2 or self.a.shape[0] != 6 or self.offset.shape != (6,):
            raise ValueError(f"offset must be (6,) and a, b (6, H); got {self.offset.shape}, {self.a.shape}, "
                             f"{self.b.shape}")
        if not 0 < 2 * self.ramp <= self.duration:
            raise ValueError(f"ramp {self.ramp} s must be positive and at most half the duration {self.duration} s")

    @property
    def bandwidth(self) -> float:
        """Highest harmonic ``H f0`` in Hz: the bandwidth of the motion (the envelope adds only
        slower content), which sets the identification filter."""
        return self.a.shape[1] * self.base_frequency

    def evaluate(self, t: np.ndarray) -> SampledMotion:
        """The motion (each ``(N, 6)``) at times ``t`` (s); ``q = [x, y, alpha, zeta1..3]``."""
        t = np.asarray(t, dtype=float)[:, None]
        w = 2 * np.pi * self.base_frequency * np.arange(1, self.a.shape[1] + 1)  # (H,)
        sin, cos = np.sin(t * w), np.cos(t * w)  # (N, H)
        f = self.offset + sin @ (self.a / w).T - cos @ (self.b / w).T
        fd = cos @ self.a.T + sin @ self.b.T
        fdd = -sin @ (self.a * w).T + cos @ (self.b * w).T
        rise, fall = quintic(t[:, 0] / self.ramp), quintic((self.duration - t[:, 0]) / self.ramp)
        up, upd, updd = rise.q, rise.qd, rise.qdd
        down, downd, downdd = fall.q, fall.qd, fall.qdd
        e = (up * down)[:, None]
        ed = (upd * down - up * downd)[:, None] / self.ramp
        edd = (updd * down - 2 * upd * downd + up * downdd)[:, None] / self.ramp**2
        home = np.concatenate([HOME_POSE, np.zeros(3)])
        return SampledMotion(home + e * f, ed * f + e * fd, edd * f + 2 * ed * fd + e * fdd)

    def trajectory(self, robot: ThreePRRR, rate: float = 250.0, name: str = "fourier",
                   metadata: dict | None = None) -> Trajectory:
        """Sample at ``rate`` Hz into a :class:`Trajectory`."""
        t = time_grid(self.duration, rate)
        meta = {"generator": "fourier", "coefficients": self.to_dict(), "rate_hz": rate, **(metadata or {})}
        motion = self.evaluate(t)
        return Trajectory.from_pose(robot, name, t, motion.q, motion.qd, motion.qdd, metadata=meta)

    def to_dict(self) -> dict:
        """JSON-serialisable form (lists)."""
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in asdict(self).items()}

    def save(self, path: str | Path, **info) -> None:
        """Write the coefficients (and any ``info``) as JSON."""
        Path(path).write_text(json.dumps({"excitation": self.to_dict(), **info}, indent=1) + "\n", encoding="utf-8")

    @classmethod
    def load(cls, path: str | Path) -> "FourierExcitation":
        """Read coefficients written by :meth:`save`; errors name the file."""
        try:
            data = json.loads(Path(path).read_text(encoding="utf-8"))["excitation"]
            return cls(**data)
        except (OSError, json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{path}: not a Fourier excitation file ({type(exc).__name__}: {exc})") from None


def stacked_regressor(robot: ThreePRRR, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """``(6 N, n_params)`` regressor rows of all samples of ``q = [x, y, alpha, zeta1..3]``."""
    Y = robot.regressor(q[:, :3], qd[:, :3], qdd[:, :3], q[:, 3:], qd[:, 3:], qdd[:, 3:])
    return Y.reshape(-1, Y.shape[-1])


@dataclass(frozen=True)
class BaseScaling:
    """The base columns of the regressor and the fixed column scale of the criterion.

    Attributes:
        columns: indices of a maximal set of structurally independent regressor columns.
        scale: ``(n_params,)`` RMS of each column on the reference data set (SI per unit parameter).
    """

    columns: np.ndarray
    scale: np.ndarray

    def cond(self, W: np.ndarray) -> float:
        """``cond(W[:, columns] / scale)``, 2-norm (``inf`` when rank deficient).

        Computed as ``sqrt`` of the eigenvalue ratio of ``W^T W`` (the same number; a tall QR or
        SVD is 50x slower with a threaded BLAS), accurate to well below 1 % up to ``cond ~ 1e6``;
        ``inf`` beyond ``1e6.5``, where the data set is rank deficient for practical purposes.
        """
        return float(self.conds(W[None])[0])

    def conds(self, W: np.ndarray) -> np.ndarray:
        """:meth:`cond` of each of a stack ``W`` (blocks, rows, n_params), in one call: (blocks,)."""
        Wb = W[:, :, self.columns] / self.scale[self.columns]
        eig = np.linalg.eigvalsh(np.swapaxes(Wb, 1, 2) @ Wb)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(eig[:, 0] > eig[:, -1] * 1e-13, np.sqrt(eig[:, -1] / eig[:, 0]), np.inf)


def base_scaling(robot: ThreePRRR, samples: int = 400, seed: int = 0, tol: float = 1e-9) -> BaseScaling:
    """Base columns and column scale from a rich random data set (reproducible, ``seed``).

    Poses and carriages near home with random rates; QR with column pivoting of the
    column-normalised stacked regressor; a column is dependent when its pivot falls below ``tol``
    times the largest. On a rig with guides exactly 120 deg apart one column drops: the link-2
    mass splits into point masses at its two joints, which group with the link-1, carriage and
    end-effector terms. Scaling each column by its RMS here makes the criterion independent of the
    parameter units while still penalising a trajectory that excites a column less than this
    reference does.
    """
    rng = np.random.default_rng(seed)
    q = rng.uniform(-1, 1, (samples, 6)) * [0.05, 0.05, 0.3, 0.05, 0.05, 0.05]
    W = stacked_regressor(robot, q, rng.normal(size=(samples, 6)) * VELOCITY_SCALE,
                          rng.normal(size=(samples, 6)) * VELOCITY_SCALE * 5)
    scale = np.sqrt(np.mean(W**2, axis=0))
    _, r, pivots = qr(W / scale, mode="economic", pivoting=True)
    diag = np.abs(np.diag(r))
    return BaseScaling(np.sort(pivots[diag > tol * diag[0]]), scale)


def _criterion(robot: ThreePRRR, limits: Limits, base: BaseScaling, q: np.ndarray, qd: np.ndarray,
               qdd: np.ndarray, blocks: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``cond`` of the base regressor (``blocks``,) and the ratio of each limited quantity to its
    limit (``blocks``, 17: six speeds, six accelerations, three strokes, the serial and parallel
    margins) of ``blocks`` excitations whose samples ``q, qd, qdd`` (each (blocks x N, 6)) are
    stacked: one call of the model's vectorised kinematics for all. ``inf`` where a pose is out
    of reach (raises :class:`KinematicsError` for ``blocks`` > 1)."""
    try:
        motion = robot.motion(q[:, :3], qd[:, :3], qdd[:, :3], q[:, 3:], qd[:, 3:], qdd[:, 3:])
        margins = robot.singularity_margins(q[:, :3], q[:, 3:])
    except KinematicsError:
        if blocks > 1:
            raise
        return np.array([np.inf]), np.full((1, 17), np.inf)
    W = robot.regressor_of(motion).reshape(blocks, -1, robot.n_params)
    ratios = np.concatenate([
        np.abs(motion.Thetad).reshape(blocks, -1, 6).max(axis=1) / limits.max_speed,
        np.abs(motion.Thetadd).reshape(blocks, -1, 6).max(axis=1) / limits.max_accel,
        np.abs(motion.zeta).reshape(blocks, -1, 3).max(axis=1) / limits.carriage_stroke,
        limits.min_serial_margin / margins.serial.reshape(blocks, -1).min(axis=1)[:, None],
        margins.cond_A.reshape(blocks, -1).max(axis=1)[:, None] / limits.max_cond_A], axis=1)
    return base.conds(W), ratios


@dataclass(frozen=True)
class ExcitationResult:
    """Outcome of :func:`optimise_excitation`: the excitation and the criterion before and after."""

    excitation: FourierExcitation
    base: BaseScaling
    cond_initial: float
    cond_final: float
    iterations: int


def optimise_excitation(robot: ThreePRRR, limits: Limits, base_frequency: float = 0.2, harmonics: int = 5,
                        duration: float | None = None, ramp: float = 1.5, samples: int = 100, seed: int = 0,
                        max_iter: int = 120, base: BaseScaling | None = None) -> ExcitationResult:
    """Fourier coefficients minimising ``cond(W)`` of the base regressor under the rig's limits.

    Args:
        robot: the model.
        limits: the rig's limits (penalised above 90 %).
        base_frequency: ``f0``, Hz; harmonics: ``H``.
        duration: s, default one base period.
        ramp: envelope rise/fall time, s.
        samples: time samples of the criterion (the regressor of each is stacked).
        seed: seed of the random start (reproducible); the start is shrunk until it is within
            90 % of every limit, so the optimiser starts from a feasible excitation.
        max_iter: L-BFGS-B iteration cap (about 0.2 s each with the defaults).
        base: base columns and column scale of the criterion (default :func:`base_scaling`).
    """
    duration = duration or 1.0 / base_frequency
    problem = _Problem(robot, limits, base or base_scaling(robot), np.linspace(0.0, duration, samples),
                       base_frequency, duration, ramp, harmonics)
    # Seeded random start, shrunk until every limited quantity is within PENALTY_START of its limit.
    v0 = np.concatenate([np.random.default_rng(seed).normal(0.0, 0.5, 12 * harmonics), np.zeros(6)])
    for _ in range(20):
        worst = np.max(problem.evaluate(v0)[1])
        if worst <= PENALTY_START:
            break
        v0 *= 0.5 if not np.isfinite(worst) else min(0.98, PENALTY_START / worst)
    result = minimize(problem.cost, v0, jac=problem.gradient, method="L-BFGS-B", options={"maxiter": max_iter})
    return ExcitationResult(problem.unpack(result.x), problem.base, problem.evaluate(v0)[0],
                            problem.evaluate(result.x)[0], int(result.nit))


def _triple(motion: SampledMotion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q, qd, qdd)`` of ``motion``, for this module's batched arithmetic over the three."""
    return motion.q, motion.qd, motion.qdd


class _Problem:
    """The criterion of :func:`optimise_excitation` on its variables ``v`` (12 H + 6,): the
    velocity amplitudes and offsets scaled by :data:`VELOCITY_SCALE`; the excitation sampled at
    ``t`` (s)."""

    def __init__(self, robot: ThreePRRR, limits: Limits, base: BaseScaling, t: np.ndarray,
                 base_frequency: float, duration: float, ramp: float, harmonics: int) -> None:
        self.robot, self.limits, self.base, self.t = robot, limits, base, t
        self.base_frequency, self.duration, self.ramp, self.harmonics = base_frequency, duration, ramp, harmonics
        # q, qd, qdd are affine in the variables: their response to each unit variable, once
        size = 12 * harmonics + 6
        self.home = _triple(self.unpack(np.zeros(size)).evaluate(t))
        self.unit = [np.stack([_triple(self.unpack(e).evaluate(t))[k] - self.home[k] for e in np.eye(size)])
                     for k in range(3)]

    def unpack(self, v: np.ndarray) -> FourierExcitation:
        shape, h = (6, self.harmonics), self.harmonics
        a = v[:6 * h].reshape(shape) * VELOCITY_SCALE[:, None]
        b = v[6 * h:12 * h].reshape(shape) * VELOCITY_SCALE[:, None]
        offset = v[12 * h:] * VELOCITY_SCALE / (2 * np.pi * self.base_frequency)
        return FourierExcitation(self.base_frequency, self.duration, self.ramp, offset, a, b)

    def evaluate(self, v: np.ndarray) -> tuple[float, np.ndarray]:
        """Criterion and the ratio of each limited quantity to its limit (``inf`` out of reach)."""
        conds, ratios = _criterion(self.robot, self.limits, self.base, *_triple(self.unpack(v).evaluate(self.t)))
        return float(conds[0]), ratios[0]

    @staticmethod
    def cost_of(cond, ratios) -> np.ndarray:
        """The cost of each (batched) criterion and its limit ratios (1e3 out of reach)."""
        penalty = PENALTY_WEIGHT * np.sum(np.maximum(ratios - PENALTY_START, 0.0) ** 2, axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(np.isfinite(cond), np.log(cond) + penalty, 1e3)

    def cost(self, v: np.ndarray) -> float:
        return float(self.cost_of(*self.evaluate(v)))

    def gradient(self, v: np.ndarray) -> np.ndarray:
        """Forward differences of :meth:`cost` (SciPy's '2-point' steps), every perturbed
        excitation evaluated in one batch of samples: SciPy's own differences to ~1e-5 at two
        thirds of the time (one call of the model's vectorised kinematics instead of 67)."""
        step = np.sqrt(np.finfo(float).eps) * np.where(v >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(v))
        step = (v + step) - v
        V = np.vstack([v, v + np.diag(step)])                               # (1 + p, p)
        motions = [self.home[k] + np.einsum("vp,pnj->vnj", V, self.unit[k]) for k in range(3)]
        try:
            q, qd, qdd = (m.reshape(-1, 6) for m in motions)
            costs = self.cost_of(*_criterion(self.robot, self.limits, self.base, q, qd, qdd, len(V)))
        except KinematicsError:                   # some perturbed excitation out of reach: one by one
            costs = np.array([self.cost(x) for x in V])
        return (costs[1:] - costs[0]) / step
