"""The paper's experiments (the 3PRRR paper; docs/3prrr-model.md, "The paper's experiments"), on any geometry.

Every trajectory starts and ends at home (pose 0, carriages 0), at rest.

- :func:`carriage_sweep`: revolute actuators held at home, each carriage in turn
  ``0 -> -A -> +A -> 0`` (identifies ``m_c`` and the carriage friction), then the three together
  (rotates the platform: more excitation of the platform terms at the same carriage motion).
- :func:`five_squares`: carriages blocked at 0, squares of the same side centred at the origin,
  the i-th rotated by ``(i - 1) * step``, orientation held at 0.
- :func:`validation_triangle`: vertices (0, 0.12), (-0.1039, -0.06), (0.1039, -0.06) m at
  orientation -20 deg, all six actuators moving (carriage schedule optimised for margins).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .feasibility import Limits
from .paths import HOME_POSE, actuator_trajectory, home_actuators, pose_trajectory
from .trajectory import Trajectory

if TYPE_CHECKING:
    from ident_hw.model import ThreePRRR

TRIANGLE_CIRCUMRADIUS = 0.12
TRIANGLE_ALPHA = np.radians(-20.0)


def triangle_vertices(circumradius: float = TRIANGLE_CIRCUMRADIUS) -> np.ndarray:
    """``(3, 2)`` vertices (m) of the equilateral triangle centred at the origin, first vertex on +y.

    With the paper's circumradius 0.12 m: (0, 0.12), (-0.1039, -0.06), (0.1039, -0.06).
    """
    angles = np.radians([90.0, 210.0, 330.0])
    return circumradius * np.column_stack([np.cos(angles), np.sin(angles)])


def carriage_sweep(robot: ThreePRRR, limits: Limits, amplitude: float = 0.06, rate: float = 250.0,
                   dwell: float = 0.0) -> Trajectory:
    """Carriage sweep: chains 1, 2, 3 one at a time, then all three together (``amplitude`` in m)."""
    home = home_actuators(robot)
    waypoints = [home]
    for carriages in ([0], [1], [2], [0, 1, 2]):
        for value in (-amplitude, amplitude, 0.0):
            point = home.copy()
            point[[3 + c for c in carriages]] = value
            waypoints.append(point)
    meta = {"experiment": "carriage sweep", "amplitude_m": amplitude}
    return actuator_trajectory(robot, "carriage-sweep", np.array(waypoints), limits, rate, dwell, meta)


def square_vertices(side: float, angle: float) -> np.ndarray:
    """``(4, 2)`` corners (m) of a square of ``side`` centred at the origin, rotated by ``angle`` (rad).

    Unrotated, the corners are ``(+s/2, +s/2), (-s/2, +s/2), (-s/2, -s/2), (+s/2, -s/2)``.
    """
    corners = side / 2 * np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    c, s = np.cos(angle), np.sin(angle)
    return corners @ np.array([[c, s], [-s, c]])


def square(robot: ThreePRRR, limits: Limits, angle: float, side: float = 0.12, rate: float = 250.0,
           dwell: float = 0.0, name: str = "square") -> Trajectory:
    """Home -> the four corners (the first twice, to close the square) -> home; carriages blocked."""
    corners = square_vertices(side, angle)
    xy = np.vstack([HOME_POSE[:2], corners, corners[:1], HOME_POSE[:2]])
    poses = np.column_stack([xy, np.zeros(len(xy))])
    meta = {"experiment": "square", "side_m": side, "angle_deg": float(np.degrees(angle))}
    return pose_trajectory(robot, name, poses, limits, rate, "blocked", dwell, meta)


def five_squares(robot: ThreePRRR, limits: Limits, side: float = 0.12, step: float = np.radians(10.0),
                 rate: float = 250.0, dwell: float = 0.0) -> list[Trajectory]:
    """The five squares, the i-th (``i = 1..5``) rotated by ``(i - 1) * step`` (rad)."""
    return [square(robot, limits, i * step, side, rate, dwell, name=f"square-{i + 1}") for i in range(5)]


def validation_triangle(robot: ThreePRRR, limits: Limits, rate: float = 250.0, dwell: float = 0.0,
                        carriages: np.ndarray | str = "optimise", circumradius: float = TRIANGLE_CIRCUMRADIUS,
                        orientation: float = TRIANGLE_ALPHA) -> Trajectory:
    """Home -> the triangle (closed) -> home at ``orientation`` (rad, -20 deg), carriages as ``carriages``.

    ``carriages`` is ``"optimise"`` (default: schedule maximising the singularity margins) or a
    user-given ``(6, 3)`` array at the waypoints home, v1, v2, v3, v1, home.
    """
    vertices = triangle_vertices(circumradius)
    xy = np.vstack([HOME_POSE[:2], vertices, vertices[:1], HOME_POSE[:2]])
    alpha = np.r_[0.0, np.full(4, orientation), 0.0]
    poses = np.column_stack([xy, alpha])
    meta = {"experiment": "validation triangle", "circumradius_m": circumradius,
            "orientation_deg": float(np.degrees(orientation))}
    return pose_trajectory(robot, "triangle", poses, limits, rate, carriages, dwell, meta)
