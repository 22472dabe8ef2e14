"""Which values of a parameter vector a physical body can have: the bodies of a model, their
pseudo-inertia matrices.

A rigid body of mass ``m``, first moment ``h = m c`` (kg·m) and inertia ``I`` about a frame's
origin (kg·m²) is physically consistent (some non-negative mass density realises it) exactly when
its pseudo-inertia

    J = [[Σ, h], [hᵀ, m]],   Σ = ½ tr(I) 1 − I   (the second moments ∫ r rᵀ dm),

is positive semidefinite (Wensing, Kim, Slotine, "Linear Matrix Inequalities for Physically
Consistent Inertial Parameter Identification", 2017): the condition is linear in the parameters
(a linear matrix inequality) and implies the positive mass, the positive-definite inertia and its
triangle inequalities. A body that moves in a plane (the 3PRRR's) shows only ``m``, ``h_x``,
``h_y`` and ``I_zz``: it is realisable when some in-plane second moments ``Σ`` (2×2) with
``tr Σ = I_zz`` make ``[[Σ, h], [hᵀ, m]]`` (3×3) positive semidefinite.

A model says where its bodies sit in its parameter vector (:class:`PhysicalBody`); everything
else the model names as a drive term (friction, rotor inertia) must be non-negative.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: the values of a spatial body, in pinocchio's dynamic-parameter order
SPATIAL = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
#: the values of a planar body (motion in the x-y plane)
PLANAR = ("m", "mx", "my", "Izz")


@dataclass(frozen=True)
class PhysicalBody:
    """One body of a model: where its values sit in the model's parameter vector.

    ``planar`` False: ``indices`` (10,) of :data:`SPATIAL`; True: (4,) of :data:`PLANAR`. An
    index of -1 is a value the model fixes at 0 (a body whose centre of mass is its frame's
    origin, a point mass without inertia).
    """

    name: str
    indices: tuple[int, ...]
    planar: bool = False

    def __post_init__(self) -> None:
        size = len(PLANAR) if self.planar else len(SPATIAL)
        if len(self.indices) != size:
            raise ValueError(f"body {self.name!r}: {len(self.indices)} indices, a "
                             f"{'planar' if self.planar else 'spatial'} body has {size}")

    def values(self, params: np.ndarray) -> np.ndarray:
        """The body's values (10,) or (4,) of a parameter vector (0 where the model fixes them)."""
        params = np.asarray(params, dtype=float)
        return np.array([params[i] if i >= 0 else 0.0 for i in self.indices])


def pseudo_inertia(values) -> np.ndarray:
    """``J`` (4, 4) of a spatial body's values (10,) in :data:`SPATIAL` order."""
    m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz = np.asarray(values, dtype=float)
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    J = np.empty((4, 4))
    J[:3, :3] = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    J[:3, 3] = J[3, :3] = hx, hy, hz
    J[3, 3] = m
    return J


def planar_pseudo_inertia(values) -> np.ndarray:
    """``J`` (3, 3) of a planar body's values (4,) in :data:`PLANAR` order, with the in-plane
    second moments split evenly about the centre of mass: ``Σ = h hᵀ / m + ½ I_c 1`` with
    ``I_c = I_zz − |h|² / m`` the inertia about the centre of mass. ``J ⪰ 0`` exactly when some
    split is (``m ≥ 0`` and ``I_c ≥ 0``), so its smallest eigenvalue is the body's margin."""
    m, hx, hy, izz = np.asarray(values, dtype=float)
    h = np.array([hx, hy])
    if m > 0:
        sigma = np.outer(h, h) / m + 0.5 * (izz - h @ h / m) * np.eye(2)
    else:                       # no mass: consistent only with no first moment and no inertia
        sigma = 0.5 * izz * np.eye(2)
    J = np.empty((3, 3))
    J[:2, :2] = sigma
    J[:2, 2] = J[2, :2] = h
    J[2, 2] = m
    return J


def body_pseudo_inertia(body: PhysicalBody, params) -> np.ndarray:
    """The body's pseudo-inertia in ``params``: (4, 4), or (3, 3) for a planar body."""
    values = body.values(params)
    return planar_pseudo_inertia(values) if body.planar else pseudo_inertia(values)


def margin(body: PhysicalBody, params) -> float:
    """Smallest eigenvalue of the body's pseudo-inertia in ``params``: ≥ 0 when consistent."""
    return float(np.linalg.eigvalsh(body_pseudo_inertia(body, params))[0])
