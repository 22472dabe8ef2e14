"""The physical size of each parameter and of each base combination: the scale against which a
base parameter's σ says whether it is well identified.

A base parameter is well identified when its σ is at most ``threshold`` % (10 %) of its size.
The relative σ alone (``σ / |estimate|``) cannot judge a parameter whose value is 0 or nearly:
a product of inertia of a symmetric body, the first moment of a body whose centre of mass is on
its joint's axis, a combination whose terms cancel (57 of the Stewart platform's 118 base
parameters are 0 in its description file): however small its σ, it is "poorly identified". The
size used instead is the one the robot's own bodies give that parameter:

* a body of CAD mass ``m`` whose mass lies at an r.m.s. distance ``l`` from its frame's origin
  (its radius of gyration about that point, ``l² = tr Σ / m`` with ``Σ = ½ tr(I) 1 − I`` the
  second moments about the origin; a planar body's ``tr Σ`` is its ``I_zz``) gives its mass the
  size ``m``, each first moment ``m l`` and each inertia value ``m l²``: a first moment known to
  10 % of ``m l`` places the centre of mass within a tenth of the body's own extent, a product
  of inertia known to 10 % of ``m l²`` is a tenth of the body's inertia;
* a parameter outside the bodies (a drive term: friction, rotor inertia) has its CAD magnitude;
* a body without mass in the description gives its values no size (0);
* a base combination ``β_j = Σ_i H_ji π_i`` has the size ``sqrt(Σ_i (H_ji s_i)²)`` (the r.m.s.
  of what its terms contribute at their own sizes, the coefficients' units included).

The size of a combination is taken with its estimate's magnitude: ``max(|β̂_j|, S_j)``, so a
parameter whose %σ is within the threshold stays well identified (the size only adds the ones
the relative σ cannot judge). The sizes come from the CAD values, never from the data, and the
threshold is the configuration's ``identification.rel_sigma_threshold``. SI units.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ident_hw.model.pseudo_inertia import PLANAR, SPATIAL, PhysicalBody

#: the kind of size (0 mass, 1 first moment, 2 inertia) of each value of a spatial and a planar body
_SPATIAL_POWER = tuple(0 if v == "m" else 1 if v in ("mx", "my", "mz") else 2 for v in SPATIAL)
_PLANAR_POWER = tuple(0 if v == "m" else 1 if v in ("mx", "my") else 2 for v in PLANAR)


def radius_of_gyration(body: PhysicalBody, values: np.ndarray) -> float:
    """The r.m.s. distance (m) of a body's mass from its frame's origin, ``sqrt(tr Σ / m)``, from
    a parameter vector ``values`` (0 for a body without mass or second moments)."""
    v = body.values(values)
    m = v[0]
    if body.planar:
        second = v[3]                                   # I_zz = tr of the in-plane second moments
    else:
        second = 0.5 * (v[4] + v[6] + v[9])             # tr Σ = ½ tr I
    return float(np.sqrt(second / m)) if m > 0 and second > 0 else 0.0


def parameter_sizes(bodies: Sequence[PhysicalBody], cad: np.ndarray) -> np.ndarray:
    """(n,) the physical size of every parameter of a model whose bodies are ``bodies`` and
    whose CAD values are ``cad`` (n,) (module docstring): ``m``, ``m l``, ``m l²`` for a body's
    mass, first moments and inertia values; ``|cad|`` for a parameter no body holds."""
    cad = np.asarray(cad, dtype=float)
    sizes = np.abs(cad)
    for body in bodies:
        m = max(float(body.values(cad)[0]), 0.0)
        l = radius_of_gyration(body, cad)
        for index, power in zip(body.indices, _PLANAR_POWER if body.planar else _SPATIAL_POWER):
            if index >= 0:
                sizes[index] = m * l**power
    return sizes


def combination_sizes(H: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """(r,) the size ``sqrt(Σ_i (H_ji s_i)²)`` of each base combination (the rows of ``H`` (r, n))
    of parameters of sizes ``sizes`` (n,)."""
    return np.sqrt(((np.asarray(H, dtype=float) * np.asarray(sizes, dtype=float)) ** 2).sum(axis=1))


def well_identified(coef: np.ndarray, sigma: np.ndarray, size: np.ndarray | None, threshold: float) -> np.ndarray:
    """(r,) bool: ``100 sigma / max(|coef|, size) <= threshold`` (``size`` None: ``|coef|``
    alone, the relative σ, %σ); False where that is not finite."""
    coef, sigma = np.asarray(coef, dtype=float), np.asarray(sigma, dtype=float)
    scale = np.abs(coef) if size is None else np.maximum(np.abs(coef), np.nan_to_num(np.asarray(size, dtype=float)))
    with np.errstate(divide="ignore", invalid="ignore"):
        return 100.0 * sigma / scale <= threshold
