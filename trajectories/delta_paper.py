"""The Delta paths of the SVD-DLS paper, in arm angles (rad), exact with their rates.

- :func:`verification_path` (eq. 60): one harmonic per arm, ``q = (0.5 sin(3π t/4),
  0.4 sin(6π t/5), 0.3 sin(5π t/3))``; the paper's test path.
- :func:`training_path` (eq. 84, Table 2): seven harmonics per arm at the tabulated angular
  frequencies, amplitudes ``a_ik = 0.05 w_ik`` (not printed in the paper: chosen), so that
  ``q_i = sum_k 0.05 sin(w_ik t)``.
- :func:`held_arm_path`: eq. 60 with arm 3 held at 0, the insufficient excitation on which the
  online estimators are compared (the paper's eq. 60 itself is rank-complete).

Each returns ``(q, qd, qdd)``, arrays (N, 3) in rad, rad/s, rad/s² at the times ``t`` (N,) s.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ident_hw.model import KinematicsError

from .feasibility import ActuatorLimits, Report, Violation, _first, check_actuator_limits
from .motion import SampledMotion
from .trajectory import Trajectory

#: eq. 60: amplitudes (rad) and angular frequencies (rad/s) of the verification path
VERIFICATION_AMPLITUDES = np.array([0.5, 0.4, 0.3])
VERIFICATION_FREQUENCIES = np.array([3 * np.pi / 4, 6 * np.pi / 5, 5 * np.pi / 3])
#: Table 2: the training path's angular frequencies (rad/s), one row per arm
TRAINING_FREQUENCIES = np.array([
    [1.3205, 3.6285, 4.9051, 0.6095, 0.3655, 0.0523, 2.8992],
    [2.7838, 0.8777, 9.5607, 0.4818, 2.7921, 5.6926, 4.3036],
    [7.2655, 5.3827, 2.4944, 3.6024, 3.2002, 3.8935, 4.4653],
])
#: chosen amplitude law of the training path: ``a_ik = TRAINING_GAIN w_ik`` (rad/s), b = 0, q0 = 0
TRAINING_GAIN = 0.05


def _harmonics(t: np.ndarray, amplitude: np.ndarray, w: np.ndarray) -> SampledMotion:
    """``q_i = sum_k amplitude_ik sin(w_ik t)`` (amplitude, w: (3, K)) and its rates."""
    t = np.asarray(t, dtype=float)
    arg = w[None] * t[:, None, None]
    q = np.sum(amplitude * np.sin(arg), axis=2)
    qd = np.sum(amplitude * w * np.cos(arg), axis=2)
    qdd = -np.sum(amplitude * w**2 * np.sin(arg), axis=2)
    return SampledMotion(q, qd, qdd)


def verification_path(t: np.ndarray) -> SampledMotion:
    """Eq. 60 (rad), with its exact rates."""
    return _harmonics(t, VERIFICATION_AMPLITUDES[:, None], VERIFICATION_FREQUENCIES[:, None])


def held_arm_path(t: np.ndarray) -> SampledMotion:
    """Eq. 60 with arm 3 held at ``q3 = 0``: two excited arms, a rank-deficient regressor."""
    amplitude = VERIFICATION_AMPLITUDES.copy()
    amplitude[2] = 0.0
    return _harmonics(t, amplitude[:, None], VERIFICATION_FREQUENCIES[:, None])


def training_path(t: np.ndarray) -> SampledMotion:
    """Eq. 84 with Table 2's frequencies and the chosen amplitudes ``a = 0.05 w``, ``b = 0``."""
    return _harmonics(t, np.full_like(TRAINING_FREQUENCIES, TRAINING_GAIN), TRAINING_FREQUENCIES)


# ----------------------------------------------------------------------------- campaign trajectories
#: the paths of the campaign by trajectory kind (``trajectories[].kind`` of a Delta config)
PATHS = {"delta_verification": verification_path, "delta_training": training_path, "delta_held_arm": held_arm_path}


def _smoothstep(u: np.ndarray):
    """Quintic ``s(u) = u³ (10 − 15u + 6u²)`` on [0, 1] (0 → 1 at rest, zero acceleration at both
    ends) with its first and second derivatives."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10 - 15 * u + 6 * u**2), 30 * u**2 * (1 - u) ** 2, 60 * u * (1 - u) * (1 - 2 * u)


def faded(path: Callable[[np.ndarray], SampledMotion], t: np.ndarray, fade: float) -> SampledMotion:
    """``path(t)`` (q, qd, qdd, each (N, n), rad|m and per s, s²) multiplied by a window that rises over the first
    ``fade`` s and falls over the last: the arms leave ``q = 0`` at rest and come back to it at
    rest (the paper's paths start moving). Exact rates by the product rule."""
    t = np.asarray(t, dtype=float)
    motion = path(t)
    if fade <= 0:
        return motion
    q, qd, qdd = motion.q, motion.qd, motion.qdd
    end = t[-1]
    rise, rise_d, rise_dd = _smoothstep((t - t[0]) / fade)
    fall, fall_d, fall_dd = _smoothstep((end - t) / fade)
    w = rise * fall
    wd = (rise_d * fall - rise * fall_d) / fade
    wdd = (rise_dd * fall - 2 * rise_d * fall_d + rise * fall_dd) / fade**2
    w, wd, wdd = w[:, None], wd[:, None], wdd[:, None]
    return SampledMotion(w * q, wd * q + w * qd, wdd * q + 2 * wd * qd + w * qdd)


def delta_trajectory(robot, kind: str, duration: float, rate: float, fade: float = 1.0, name: str | None = None,
                     amplitude=1.0):
    """The campaign trajectory ``kind`` (a key of :data:`PATHS`) of ``duration`` s sampled at
    ``rate`` Hz, its angles scaled by ``amplitude`` (a factor, or (3,): one per arm), faded in and
    out (:func:`faded`), as a :class:`~trajectories.Trajectory` whose pose is the platform position (``robot.fk``; its rates by the Jacobian, its acceleration by
    central differences: the pose is for plots, the drives follow ``Theta``).

    Raises:
        ValueError: an unknown kind, or a duration shorter than the two fades.
    """
    if kind not in PATHS:
        raise ValueError(f"unknown Delta path {kind!r}; known: {', '.join(PATHS)}")
    if not duration > 2 * fade:
        raise ValueError(f"duration {duration} s must exceed the fade in and out, 2 x {fade} s")
    t = np.arange(int(np.floor(duration * rate + 1e-9)) + 1) / rate
    scale = np.asarray(amplitude, dtype=float)
    motion = faded(PATHS[kind], t, fade)
    q, qd, qdd = scale * motion.q, scale * motion.qd, scale * motion.qdd
    X = robot.fk(q)
    Xd = np.einsum("nij,nj->ni", robot.jacobian(q), qd)
    Xdd = np.gradient(Xd, t, axis=0)
    return Trajectory(name or kind, t, X, Xd, Xdd, q, qd, qdd,
                      metadata={"generator": kind, "duration_s": duration, "fade_s": fade, "rate_hz": rate,
                                "amplitude": scale.tolist()})


def check_delta_trajectory(traj: Trajectory, robot, limits: ActuatorLimits, min_serial: float,
                           max_parallel: float) -> Report:
    """The feasibility report of a Delta trajectory: the actuator limits
    (:func:`trajectories.feasibility.check_actuator_limits`), reach (the forward kinematics) and
    the singularity measures of :meth:`ident_hw.model.Delta.singularity` (serial at least
    ``min_serial``, parallel condition at most ``max_parallel``)."""
    report = check_actuator_limits(traj, limits)
    found = list(report.violations)
    try:
        serial, parallel = robot.singularity(traj.Theta)
    except KinematicsError as exc:
        k = exc.sample or 0
        found.append(Violation(float(traj.t[k]), k, None, "reach", f"q = {np.round(traj.Theta[k], 4).tolist()} rad",
                               np.nan, np.nan))
    else:
        measure = "Delta singularity measure"
        _first(found, traj.t, "serial margin", serial < min_serial, serial, [min_serial] * 3, [measure] * 3,
               [""] * 3, [1, 2, 3])
        cond = parallel[:, None]
        _first(found, traj.t, "cond(A)", cond > max_parallel, cond, [max_parallel], [measure], [""], [None])
    found.sort(key=lambda v: v.sample)
    return Report(report.trajectory, tuple(found))
