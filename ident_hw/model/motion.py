"""The records of a motion a robot model returns instead of a bare tuple: coordinates sampled with
their first two derivatives (:class:`SampledMotion`, also what the trajectories' generators
return: :mod:`trajectories.motion`), and a described robot's tree at one sample
(:class:`TreeMotion`)."""

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


@dataclass(frozen=True, slots=True)
class TreeMotion:
    """A described robot's kinematic tree at one sample of an actuated motion
    (:meth:`ident_hw.model.described.DescribedRobot.tree_motion`).

    Attributes:
        q: ``(nq,)`` the tree's configuration (rad, m), its loops closed.
        v: ``(nv,)`` its joint rates (rad/s, m/s).
        a: ``(nv,)`` its joint accelerations (rad/s², m/s²).
        W: ``(nv, n)`` the velocity map of the actuated coordinates: ``v = W Thetad``.
    """

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    W: np.ndarray
