"""The :class:`SampledMotion` record: coordinates sampled with their first two derivatives, what
the trajectories' generators (paths, sines, the quintic timing law) return instead of a bare
``(q, qd, qdd)`` triple."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SampledMotion:
    """Coordinates and their first two derivatives at the same samples.

    The derivatives are with respect to time (s) unless the function that returns the record
    says otherwise (:func:`trajectories.timing.quintic`: the normalised time ``u``;
    :meth:`trajectories.timing.Segment.geometry`: the path parameter ``s``). The units are the
    coordinates' (rad or m for actuators, the pose's for a pose) and per s, per s².

    Attributes:
        q: ``(N, d)`` coordinates (or the shape of the argument sampled, e.g. ``(N,)``).
        qd: first derivatives, the shape of ``q``.
        qdd: second derivatives, the shape of ``q``.
    """

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
