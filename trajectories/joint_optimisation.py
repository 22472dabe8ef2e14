"""Optimised excitation of any robot in its actuated coordinates (issue 48 item 3).

The joint excitation of :mod:`trajectories.joint_space` moves each actuator by a sum of sines
whose frequencies and phases are drawn from a seed. :func:`optimise_joint_excitation` keeps the
frequencies and chooses the phases and the relative weights of the sines (``2 n K`` variables)
to minimise the log of the **scaled condition number of the numerical base regressor** over the
motion: the regressor of the robot's base parameters (the columns
:func:`ident_hw.model.described.numerical_base` keeps), stacked over ``samples`` instants of the
trajectory, each column scaled to unit RMS (as the identification's step condition,
:func:`ident_hw.identification.base_params.scaled_condition`, is). Every candidate is fitted to
``fraction`` of the joint, speed and acceleration limits the same way as the drawn excitation
(:func:`trajectories.joint_space.fitted_scale`), so those hold by construction; the assembly
limit (the closure Jacobian's condition below ``max_condition``) enters as a quadratic penalty
above :data:`PENALTY_START` of it, and a candidate that leaves the workspace (the loops do not
close, a singularity) costs :data:`OUT_OF_REACH`. L-BFGS-B with forward differences, from the
drawn excitation: deterministic for a host, but its last bits may differ between hosts, so the
result is written to a file (:meth:`~trajectories.joint_space.JointHarmonics.save`) that a
config's ``joint_excitation`` reads (``path``): the same trajectory on every host.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from ident_hw.model import KinematicsError

from .delta_paper import faded
from .feasibility import ActuatorLimits
from .joint_space import JointHarmonics, OptimisedFor, fitted_scale

#: fraction of ``max_condition`` above which the assembly penalty starts
PENALTY_START = 0.9
PENALTY_WEIGHT = 100.0
#: cost of a candidate that leaves the workspace (log of the condition is some 5-10)
OUT_OF_REACH = 1e3
#: bounds of the relative weight of a sine (the drawn excitation: 1)
WEIGHT_BOUNDS = (0.1, 2.0)


def base_columns(robot) -> np.ndarray:
    """The regressor columns of the robot's numerical base parameters (the parameters each base
    combination is named after): a maximal independent set."""
    kept = robot.readable_base().kept
    names = list(robot.parameter_names)
    return np.array(sorted(names.index(k) for k in kept))


def scaled_condition(Y: np.ndarray, columns: np.ndarray) -> float:
    """2-norm condition number of the stacked regressor ``Y`` (N, n, P) restricted to ``columns``,
    each scaled to unit RMS (``inf`` where a column is zero or the set is rank deficient beyond
    1e6.5): from the eigenvalues of ``W^T W``, the same number as the SVD's to well below 1 %."""
    W = Y.reshape(-1, Y.shape[-1])[:, columns]
    rms = np.sqrt(np.mean(W**2, axis=0))
    if not np.all(rms > 0):
        return float("inf")
    W = W / rms
    eig = np.linalg.eigvalsh(W.T @ W)
    return float(np.sqrt(eig[-1] / eig[0])) if eig[0] > eig[-1] * 1e-13 else float("inf")


class _Problem:
    """The criterion on the variables ``v`` = (phases (n K), weights (n K))."""

    def __init__(self, robot, limits: ActuatorLimits, drawn: JointHarmonics, duration: float, fade: float,
                 fraction: float, amplitude, max_condition: float, samples: int, peak_rate: float) -> None:
        self.robot, self.limits, self.drawn = robot, limits, drawn
        self.fade, self.fraction, self.max_condition = fade, fraction, max_condition
        self.amplitude = np.asarray(amplitude, dtype=float)
        self.home = robot.home_actuated()
        self.start = robot.pose(self.home, None)
        self.columns = base_columns(robot)
        # the limits are fitted on a grid dense enough for the peaks (peak_rate Hz), the criterion
        # on ``samples`` instants of the same grid's span (both include the two ends at rest)
        self.t_peak = np.linspace(0.0, duration, int(np.ceil(duration * peak_rate)) + 1)
        self.t = np.linspace(0.0, duration, samples)
        self.shape = drawn.frequencies.shape

    def sines(self, v: np.ndarray) -> JointHarmonics:
        size = int(np.prod(self.shape))
        return JointHarmonics(self.drawn.frequencies, v[:size].reshape(self.shape), v[size:].reshape(self.shape))

    def evaluate(self, v: np.ndarray) -> tuple[float, float]:
        """The scaled condition (``inf`` out of reach) and the largest closure condition over its
        limit."""
        sines = self.sines(v)
        scale = fitted_scale(self.home, self.limits, faded(sines.motion, self.t_peak, self.fade), self.fraction)
        motion = faded(sines.motion, self.t, self.fade)
        q, qd, qdd = motion.q, motion.qd, motion.qdd
        scale = scale * self.amplitude
        try:
            Y, poses = self.robot.identification_regressor(self.home + scale * q, scale * qd, scale * qdd, self.start)
            closure = float(np.max(self.robot.conditions(poses)))
        except KinematicsError:
            return float("inf"), float("inf")
        return scaled_condition(Y, self.columns), closure / self.max_condition

    def cost(self, v: np.ndarray) -> float:
        cond, ratio = self.evaluate(v)
        if not (np.isfinite(cond) and np.isfinite(ratio)):
            return OUT_OF_REACH
        return float(np.log(cond) + PENALTY_WEIGHT * max(ratio - PENALTY_START, 0.0) ** 2)

    def gradient(self, v: np.ndarray) -> np.ndarray:
        """Forward differences of :meth:`cost` (SciPy's '2-point' steps)."""
        step = np.sqrt(np.finfo(float).eps) * np.where(v >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(v))
        step = (v + step) - v
        c0 = self.cost(v)
        return np.array([(self.cost(v + step[i] * e) - c0) / step[i] for i, e in enumerate(np.eye(len(v)))])


def optimise_joint_excitation(robot, limits: ActuatorLimits, duration: float, bandwidth: float,
                              harmonics: int = 5, fraction: float = 0.8, fade: float = 1.0, seed: int = 0,
                              amplitude=1.0, max_condition: float = np.inf, samples: int = 150,
                              max_iter: int = 30, peak_rate: float | None = None) -> JointHarmonics:
    """The sines of a joint excitation (``duration`` s, ``harmonics`` per actuator up to
    ``bandwidth`` Hz, drawn from ``seed``) with their phases and weights optimised for the
    scaled condition of the numerical base regressor (module docstring), within ``fraction`` of
    the actuator limits scaled by ``amplitude`` and the closure condition ``max_condition``.
    The result carries the condition before (the drawn excitation) and after, and what it was
    optimised for (``optimised_for``: the arguments a config must repeat to get the same
    trajectory).

    ``samples``: instants of the criterion (the regressor of each is stacked); ``max_iter``:
    L-BFGS-B iterations (each some ``2 n K + 1`` regressor evaluations of ``samples`` rows);
    ``peak_rate``: Hz of the grid the limits are fitted on (default 10 x ``bandwidth``).

    Raises:
        KinematicsError: the drawn excitation itself leaves the workspace (lower ``amplitude``).
    """
    home = robot.home_actuated()
    drawn = JointHarmonics.drawn(len(home), bandwidth, harmonics, seed)
    problem = _Problem(robot, limits, drawn, duration, fade, fraction, amplitude, max_condition, samples,
                       peak_rate or 10.0 * bandwidth)
    v0 = np.concatenate([drawn.phases.ravel(), drawn.weights.ravel()])
    cond0, ratio0 = problem.evaluate(v0)
    if not np.isfinite(cond0) or not np.isfinite(ratio0):
        raise KinematicsError(f"the drawn excitation (seed {seed}) leaves the workspace: lower its amplitude")
    size = drawn.phases.size
    bounds = [(None, None)] * size + [WEIGHT_BOUNDS] * size
    result = minimize(problem.cost, v0, jac=problem.gradient, method="L-BFGS-B", bounds=bounds,
                      options={"maxiter": max_iter})
    best = result.x if problem.cost(result.x) <= problem.cost(v0) else v0
    cond1, _ = problem.evaluate(best)
    sines = problem.sines(best)
    amplitudes = tuple(float(a) for a in np.broadcast_to(problem.amplitude, home.shape))
    return JointHarmonics(sines.frequencies, sines.phases, sines.weights, cond0, cond1,
                          OptimisedFor(duration, bandwidth, harmonics, fraction, fade, seed, amplitudes,
                                       max_condition if np.isfinite(max_condition) else None, samples,
                                       int(result.nit)))
