"""Smooth rest-to-rest timing of piecewise paths.

A path here is a sequence of segments in some coordinate space of dimension ``d`` (the pose and
carriages ``[x, y, alpha, zeta1, zeta2, zeta3]``, or the six actuators ``Theta``). Each segment
goes from ``start`` to ``end`` along

    q(s) = start + (end - start) s + sum_k shape[k] sin((k + 1) pi s),     s in [0, 1]

and ``s(t)`` is the quintic rest-to-rest profile ``s = 10 u^3 - 15 u^4 + 6 u^5``, ``u = t / T``.
Because ``s' = s'' = 0`` at both ends of every segment, position, velocity and acceleration are
continuous everywhere (C2) and every vertex is passed at rest. The optional sine ``shape`` terms
bend a segment away from the straight line without moving its ends (used for carriage schedules).

Durations are chosen from per-actuator speed and acceleration limits by exact time scaling: for
a segment traversed in time ``T``, actuator speeds scale as ``1/T`` and accelerations as
``1/T^2``, so ``T = max(v1 / v_max, sqrt(a1 / a_max))`` with ``v1``, ``a1`` the peaks at ``T = 1``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .motion import SampledMotion

#: ``Map`` from path coordinates ``q, qd, qdd`` (each ``(N, d)``) to the actuators' motion
#: (``Theta, Thetad, Thetadd``, each ``(N, 6)``).
ActuatorMap = Callable[[np.ndarray, np.ndarray, np.ndarray], SampledMotion]

#: Peak of ``ds/du`` of the quintic profile (at ``u = 1/2``).
QUINTIC_PEAK_SPEED = 15.0 / 8.0
#: Peak of ``|d2s/du2|`` of the quintic profile (at ``u = 1/2 -+ sqrt(3)/6``).
QUINTIC_PEAK_ACCEL = 10.0 / np.sqrt(3.0)


def quintic(u: np.ndarray) -> SampledMotion:
    """Quintic rest-to-rest profile and its derivatives with respect to ``u``.

    Args:
        u: normalised time, any shape; clipped to ``[0, 1]``.

    Returns:
        ``s`` (``q``), ``ds/du`` (``qd``), ``d2s/du2`` (``qdd``), each with the shape of ``u``
        (dimensionless).
    """
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    s = u**3 * (10.0 - 15.0 * u + 6.0 * u**2)
    ds = 30.0 * u**2 * (1.0 - u) ** 2
    dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u)
    return SampledMotion(s, ds, dds)


@dataclass(frozen=True)
class Segment:
    """One rest-to-rest segment of a :class:`PiecewisePath`.

    Attributes:
        start: ``(d,)`` coordinates at the start.
        end: ``(d,)`` coordinates at the end.
        duration: ``T`` in s (> 0).
        shape: ``(K, d)`` amplitudes of the ``sin((k + 1) pi s)`` terms, or ``None``.
    """

    start: np.ndarray
    end: np.ndarray
    duration: float
    shape: np.ndarray | None = None

    def geometry(self, s: np.ndarray) -> SampledMotion:
        """Path point and its first two derivatives with respect to ``s`` (not time): each ``(N, d)``."""
        s = np.asarray(s, dtype=float)[:, None]
        delta = np.asarray(self.end, float) - np.asarray(self.start, float)
        q = self.start + delta * s
        dq = np.broadcast_to(delta, q.shape).copy()
        ddq = np.zeros_like(q)
        if self.shape is not None:
            k = np.pi * np.arange(1, len(self.shape) + 1)
            sin, cos = np.sin(s * k), np.cos(s * k)  # (N, K)
            q += sin @ self.shape
            dq += (cos * k) @ self.shape
            ddq -= (sin * k**2) @ self.shape
        return SampledMotion(q, dq, ddq)

    def evaluate(self, tau: np.ndarray) -> SampledMotion:
        """Position, velocity, acceleration (each ``(N, d)``) at times ``tau`` (s) from the segment start."""
        profile = quintic(np.asarray(tau, dtype=float) / self.duration)
        sd, sdd = profile.qd / self.duration, profile.qdd / self.duration**2
        path = self.geometry(profile.q)
        return SampledMotion(path.q, path.qd * sd[:, None], path.qdd * (sd**2)[:, None] + path.qd * sdd[:, None])


class PiecewisePath:
    """A chain of rest-to-rest :class:`Segment` objects, evaluated at any time.

    Args:
        segments: consecutive segments; each must start where the previous one ends.
    """

    def __init__(self, segments: list[Segment]):
        if not segments:
            raise ValueError("a path needs at least one segment")
        for i, (a, b) in enumerate(zip(segments[:-1], segments[1:])):
            if not np.allclose(a.end, b.start, rtol=0.0, atol=1e-12):
                raise ValueError(f"segment {i + 1} starts at {b.start} but segment {i} ends at {a.end}")
        self.segments = list(segments)
        self.boundaries = np.concatenate([[0.0], np.cumsum([seg.duration for seg in segments])])

    @property
    def duration(self) -> float:
        """Total duration in s."""
        return float(self.boundaries[-1])

    def evaluate(self, t: np.ndarray) -> SampledMotion:
        """Position, velocity and acceleration, each ``(N, d)``, at times ``t`` (s), clamped to the path."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        index = np.clip(np.searchsorted(self.boundaries, t, side="right") - 1, 0, len(self.segments) - 1)
        d = len(self.segments[0].start)
        out = [np.empty((len(t), d)) for _ in range(3)]
        for i in np.unique(index):
            mask = index == i
            part = self.segments[i].evaluate(t[mask] - self.boundaries[i])
            for o, v in zip(out, (part.q, part.qd, part.qdd)):
                o[mask] = v
        return SampledMotion(out[0], out[1], out[2])


def time_grid(duration: float, rate: float) -> np.ndarray:
    """Sample times ``0, 1/rate, ...`` up to and including ``duration`` (s); rate in Hz."""
    if rate <= 0:
        raise ValueError(f"sample rate must be positive, got {rate} Hz")
    n = int(np.floor(duration * rate + 1e-9)) + 1
    t = np.arange(n) / rate
    return t if np.isclose(t[-1], duration, atol=1e-12) else np.append(t, duration)


def segment_duration(
    geometry: Callable[[np.ndarray], SampledMotion],
    to_actuators: ActuatorMap,
    max_speed: np.ndarray,
    max_accel: np.ndarray,
    utilisation: float = 0.9,
    samples: int = 201,
    min_duration: float = 0.1,
) -> float:
    """Shortest quintic duration (s) of one segment that keeps every actuator within its limits.

    Args:
        geometry: ``s ->`` the segment's point and its derivatives with respect to ``s`` (see :meth:`Segment.geometry`).
        to_actuators: map from path coordinates to the six actuator coordinates.
        max_speed: ``(6,)`` actuator speed limits (rad/s x3, m/s x3).
        max_accel: ``(6,)`` actuator acceleration limits (rad/s^2 x3, m/s^2 x3).
        utilisation: fraction of the limits aimed at (the peaks are found on a grid).
        samples: grid size in ``u``.
        min_duration: lower bound on the result, s.
    """
    profile = quintic(np.linspace(0.0, 1.0, samples))
    ds, dds = profile.qd, profile.qdd
    path = geometry(profile.q)
    actuators = to_actuators(path.q, path.qd * ds[:, None], path.qdd * (ds**2)[:, None] + path.qd * dds[:, None])
    thd, thdd = actuators.qd, actuators.qdd
    speed = np.max(np.abs(thd) / (utilisation * np.asarray(max_speed)))
    accel = np.max(np.abs(thdd) / (utilisation * np.asarray(max_accel)))
    return float(max(speed, np.sqrt(accel), min_duration))


def rest_to_rest_path(
    waypoints: np.ndarray,
    to_actuators: ActuatorMap,
    max_speed: np.ndarray,
    max_accel: np.ndarray,
    shapes: list[np.ndarray | None] | None = None,
    dwell: float = 0.0,
    utilisation: float = 0.9,
    time_step: float = 0.0,
) -> PiecewisePath:
    """Path through ``waypoints`` (``(M, d)``), at rest at each, timed by the actuator limits.

    Args:
        waypoints: ``(M, d)`` coordinates of the vertices, ``M >= 2``.
        to_actuators: map from path coordinates to actuator coordinates (for the limits).
        max_speed, max_accel: ``(6,)`` actuator limits, SI.
        shapes: optional per-segment sine amplitudes (see :class:`Segment`), ``M - 1`` entries.
        dwell: time (s) held at rest at each vertex, start and end included (0 for none).
        utilisation: fraction of the limits aimed at.
        time_step: if positive, every duration (and the dwell) is rounded up to a multiple of it,
            so that a grid of this step samples every vertex exactly.
    """

    def quantise(duration: float) -> float:
        return float(np.ceil(duration / time_step - 1e-9) * time_step) if time_step > 0 else duration

    dwell = quantise(dwell) if dwell > 0 else 0.0
    waypoints = np.asarray(waypoints, dtype=float)
    if waypoints.ndim != 2 or len(waypoints) < 2:
        raise ValueError(f"waypoints must be (M, d) with M >= 2, got shape {waypoints.shape}")
    shapes = shapes if shapes is not None else [None] * (len(waypoints) - 1)
    segments: list[Segment] = []

    def hold(point: np.ndarray) -> None:
        if dwell > 0:
            segments.append(Segment(point, point, dwell))

    hold(waypoints[0])
    for a, b, shape in zip(waypoints[:-1], waypoints[1:], shapes):
        probe = Segment(a, b, 1.0, shape)
        if np.allclose(a, b) and shape is None:
            continue
        duration = quantise(segment_duration(probe.geometry, to_actuators, max_speed, max_accel, utilisation))
        segments.append(Segment(a, b, duration, shape))
        hold(b)
    return PiecewisePath(segments)
