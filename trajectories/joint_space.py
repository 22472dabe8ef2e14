"""Excitation of any robot in its actuated coordinates: sums of sines about home, within limits.

For a robot known only from its description file there are no task-space paths to follow; what
identification needs is every actuator moving over much of its range at several frequencies at
once, so that the regressor's columns separate. :func:`joint_excitation` gives actuator ``j``

    Theta_j(t) = home_j + s_j e(t) sum_k sin(w_jk t + phi_jk) / w_jk

with ``K`` angular frequencies ``w_jk`` spread over ``[bandwidth / 8, bandwidth]`` (Hz × 2π)
and phases ``phi_jk`` drawn from ``seed`` (the same trajectory on every host), the velocity
amplitudes equal (``1 / w``), ``e(t)`` the fade window of :func:`trajectories.delta_paper.faded`
(from and back to home at rest) and ``s_j`` the largest scale that keeps the motion within
``fraction`` of the actuator's position room about home, its speed and its acceleration limits.
Exact rates by the product rule. The frequencies, phases and relative weights of the sines
(:class:`JointHarmonics`) are drawn from ``seed``, or read from a file written by the
optimisation of :mod:`trajectories.joint_optimisation` (weights ``c_jk`` then multiply each sine).

:func:`check_described_trajectory` is the feasibility check of such a robot: the actuator limits,
reach (the loops close at every sample) and the distance to a parallel singularity (the
condition number of the passive joints' closure Jacobian).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any
from pathlib import Path

import numpy as np

from ident_hw.model import KinematicsError

from .delta_paper import faded
from .motion import SampledMotion
from .feasibility import ActuatorLimits, Report, Violation, _first, check_actuator_limits
from .trajectory import Trajectory


#: m or rad: a trajectory's pose closes the loops when every closure residual is below this
CLOSED = 1e-9


@dataclass(frozen=True)
class OptimisedFor:
    """What an optimised joint excitation was optimised for (:mod:`trajectories.joint_optimisation`),
    the arguments a config must repeat to get the same trajectory: its ``duration_s`` (s),
    ``bandwidth_hz`` (Hz), ``harmonics`` per actuator, the limits' ``fraction``, ``fade_s`` (s), the
    draw's ``seed``, the relative ``amplitude`` per actuator, the closure's ``max_condition`` (None:
    none), the criterion's ``samples``, and the optimiser's ``iterations`` done. Stored in the
    excitation's JSON file under these names."""

    duration_s: float
    bandwidth_hz: float
    harmonics: int
    fraction: float
    fade_s: float
    seed: int
    amplitude: tuple[float, ...]
    max_condition: float | None
    samples: int
    iterations: int

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> OptimisedFor:
        """The record of its JSON form (:meth:`JointHarmonics.save`)."""
        return cls(**{**doc, "amplitude": tuple(doc["amplitude"])})


@dataclass(frozen=True)
class JointHarmonics:
    """The sines of a joint excitation, per actuator and harmonic (n, K) each: angular
    ``frequencies`` (rad/s), ``phases`` (rad) and relative velocity ``weights`` (1: the drawn
    excitation; the scale that fits the limits is applied afterwards). An optimised set also
    carries the scaled condition number of the base regressor before and after the
    optimisation (:mod:`trajectories.joint_optimisation`), and what it was optimised for."""

    frequencies: np.ndarray
    phases: np.ndarray
    weights: np.ndarray
    cond_initial: float | None = None
    cond_final: float | None = None
    optimised_for: OptimisedFor | None = None

    @classmethod
    def drawn(cls, n: int, bandwidth: float, harmonics: int, seed: int) -> "JointHarmonics":
        """``harmonics`` frequencies per actuator in ``[bandwidth / 8, bandwidth]`` (Hz) and phases
        drawn from ``seed`` (the same on every host), weights 1."""
        rng = np.random.default_rng(seed)
        w = 2 * np.pi * bandwidth * np.sort(rng.uniform(1 / 8, 1.0, (n, harmonics)), axis=1)
        phi = rng.uniform(0, 2 * np.pi, (n, harmonics))
        return cls(w, phi, np.ones_like(w))

    def motion(self, t: np.ndarray) -> SampledMotion:
        """``sum_k c_k sin(w_k t + phi_k) / w_k`` per actuator and its two rates, (N, n) each, at
        times ``t`` (N,) s (relative: the scale that fits the limits is applied afterwards)."""
        w, c = self.frequencies, self.weights
        arg = w[None] * t[:, None, None] + self.phases[None]
        s, co = np.sin(arg), np.cos(arg)
        if np.all(c == 1.0):                  # the drawn excitation: the same bits as ever
            return SampledMotion(np.sum(s / w, axis=2), np.sum(co, axis=2), -np.sum(w * s, axis=2))
        return SampledMotion(np.sum(c * s / w, axis=2), np.sum(c * co, axis=2), -np.sum(c * w * s, axis=2))

    def save(self, path: str | Path) -> Path:
        """Write the set as JSON (numbers written in full: the same trajectory when read back)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        doc = {"kind": "joint_harmonics", "frequencies_rad_s": self.frequencies.tolist(),
               "phases_rad": self.phases.tolist(), "weights": self.weights.tolist(),
               "cond_initial": self.cond_initial, "cond_final": self.cond_final,
               "optimised_for": dataclasses.asdict(self.optimised_for) if self.optimised_for else None}
        path.write_text(json.dumps(doc, indent=1) + "\n")
        return path

    @classmethod
    def load(cls, path: str | Path, actuators: int | None = None) -> "JointHarmonics":
        """Read a set written by :meth:`save`.

        Raises:
            ValueError: not such a file, or (``actuators`` given) not one row per actuator,
                naming the file.
        """
        try:
            doc = json.loads(Path(path).read_text())
            if doc.get("kind") != "joint_harmonics":
                raise ValueError(f"kind {doc.get('kind')!r}, expected 'joint_harmonics'")
            arrays = [np.array(doc[k], dtype=float) for k in ("frequencies_rad_s", "phases_rad", "weights")]
        except (OSError, json.JSONDecodeError, KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ValueError(f"{path}: not a joint excitation file ({type(exc).__name__}: {exc})") from None
        if arrays[0].ndim != 2 or any(a.shape != arrays[0].shape for a in arrays) or not np.all(arrays[0] > 0):
            raise ValueError(f"{path}: frequencies, phases and weights must be (actuators, harmonics) arrays "
                             "of the same shape, the frequencies positive")
        if actuators is not None and len(arrays[0]) != actuators:
            raise ValueError(f"{path}: {len(arrays[0])} rows of sines, the robot has {actuators} actuators")
        frequencies, phases, weights = arrays
        try:
            optimised_for = OptimisedFor.from_json(doc["optimised_for"]) if doc.get("optimised_for") else None
        except (KeyError, TypeError) as exc:
            raise ValueError(f"{path}: optimised_for is not what the optimiser writes ({type(exc).__name__}: {exc})") from None
        return cls(frequencies, phases, weights, doc.get("cond_initial"), doc.get("cond_final"), optimised_for)


def fitted_scale(home: np.ndarray, limits: ActuatorLimits, motion: SampledMotion, fraction: float) -> np.ndarray:
    """The largest factor per actuator (n,) that keeps the motion ``home + s q`` (``motion``, (N, n)
    each) within ``fraction`` of its position room about home, its speed and its acceleration limits.

    Raises:
        ValueError: a home not inside its actuator's limits, naming the actuator."""
    room = np.minimum(home - limits.low, limits.high - home)
    if np.any(room <= 0):
        j = int(np.argmin(room))
        raise ValueError(f"actuator {limits.names[j]}: home {home[j]:.6g} {limits.units[j]} is not inside its "
                         f"limits [{limits.low[j]:.6g}, {limits.high[j]:.6g}]")
    peak = [np.max(np.abs(x), axis=0) for x in (motion.q, motion.qd, motion.qdd)]
    return fraction * np.min([room / peak[0], limits.speed / peak[1], limits.accel / peak[2]], axis=0)


def joint_excitation(robot, limits: ActuatorLimits, duration: float, rate: float, bandwidth: float,
                     harmonics: int = 5, fraction: float = 0.8, fade: float = 1.0, seed: int = 0,
                     name: str = "excitation", amplitude=1.0, sines: JointHarmonics | None = None) -> Trajectory:
    """The excitation of the module docstring, ``duration`` s at ``rate`` Hz, as a
    :class:`~trajectories.Trajectory` whose pose is the robot's (``robot.pose_series``; its
    rates by central differences: the pose is for plots and the assembly mode, the drives follow
    ``Theta``). ``amplitude`` (a factor, or one per actuator) scales the motion after it has
    been fitted to the limits (at most 1 keeps it within them). ``sines``: the frequencies,
    phases and weights (default: drawn from ``seed``, ``harmonics`` per actuator up to
    ``bandwidth``).

    Raises:
        ValueError: a duration shorter than the two fades, a bandwidth the rate cannot carry.
        KinematicsError: a sample at which the loops do not close.
    """
    if not duration > 2 * fade:
        raise ValueError(f"duration {duration} s must exceed the fade in and out, 2 x {fade} s")
    if not 0 < bandwidth < rate / 4:
        raise ValueError(f"bandwidth {bandwidth} Hz must be positive and below a quarter of the rate {rate} Hz")
    home = robot.home_actuated()
    n = len(home)
    sines = JointHarmonics.drawn(n, bandwidth, harmonics, seed) if sines is None else sines
    t = np.arange(int(np.floor(duration * rate + 1e-9)) + 1) / rate
    motion = faded(sines.motion, t, fade)
    q, qd, qdd = motion.q, motion.qd, motion.qdd
    scale = fitted_scale(home, limits, motion, fraction) * np.asarray(amplitude, dtype=float)
    Theta, Thetad, Thetadd = home + scale * q, scale * qd, scale * qdd
    X = robot.pose_series(Theta, robot.pose(home, None))
    Xd = np.gradient(X, t, axis=0)
    Xdd = np.gradient(Xd, t, axis=0)
    return Trajectory(name, t, X, Xd, Xdd, Theta, Thetad, Thetadd,
                      metadata={"generator": "joint_excitation", "duration_s": duration, "rate_hz": rate,
                                "bandwidth_hz": bandwidth, "harmonics": sines.frequencies.shape[1], "fraction": fraction,
                                "fade_s": fade, "seed": seed, "scale": scale.tolist(),
                                **({} if sines.cond_final is None else
                                   {"optimised": {"cond_initial": sines.cond_initial, "cond_final": sines.cond_final}})})


def check_described_trajectory(traj: Trajectory, robot, limits: ActuatorLimits, max_condition: float) -> Report:
    """The feasibility report of a trajectory of a described robot: the actuator limits
    (:func:`trajectories.feasibility.check_actuator_limits`), reach (the loops close at every
    sample: the trajectory's own poses where they are closed tree configurations at its
    actuated coordinates, else solved from the first sample on) and the condition number of the passive joints'
    closure Jacobian at most ``max_condition`` (a parallel singularity is infinite)."""
    report = check_actuator_limits(traj, limits)
    found = list(report.violations)
    cond = None
    if traj.X.shape[1] == robot.pose_size and np.array_equal(traj.X[:, robot.actuated_q], traj.Theta):
        # the trajectory's own poses (the excitation's): closed at every sample, or solved again
        residual, cond = robot.closed_conditions(traj.X)
        if np.max(residual) > CLOSED:
            cond = None
    if cond is None:
        try:
            cond = robot.conditions(robot.pose_series(traj.Theta, robot.pose(traj.Theta[0], None)))
        except KinematicsError as exc:
            k = exc.sample or 0
            found.append(Violation(float(traj.t[k]), k, None, "reach",
                                   f"Theta = {np.round(traj.Theta[k], 4).tolist()}", np.nan, np.nan))
    if cond is not None:
        _first(found, traj.t, "closure condition", cond[:, None] > max_condition, cond[:, None], [max_condition],
               ["passive joints' closure Jacobian"], [""], [None])
    found.sort(key=lambda v: v.sample)
    return Report(report.trajectory, tuple(found))
