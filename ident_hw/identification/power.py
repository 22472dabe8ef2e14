"""Power and energy models (the power-model paper): identification without accelerations.

Actuated power equals the rate of change of the kinetic energy plus the friction losses:

    Thetadᵀ tau = dT/dt + sum_j (f_vj qd_j² + f_cj qd_j tanh(qd_j / w)),   T = h(q, qd) pi[:7]

Power model: one scalar row per sample, ``dh/dt`` by fourth-order central differences
(:func:`ident_hw.signal.central_derivatives`; the two samples at each end, where only second
order is available, give no row). Energy model: the same integrated between sample times
``t_a = t_i``, ``t_b = t_{i+window}`` (cumulative Simpson rule, error O(h⁴)):
``∫ Pdt = h(t_b) − h(t_a) + friction work``.

Why fourth order: one scalar equation per sample makes the fit of the 18 base parameters
ill-conditioned, and it amplifies the differentiation or integration error of ``h`` by
thousands: second-order differences or the trapezoid rule leave base parameters tens of
percent off on exact model data, fourth order a fraction of a percent
(``tests/test_ident_power.py`` holds the fits to that).

Inputs are sampled (N,) time-major: ``t`` (N,), energy regressor ``H`` (N, 7) from
``robot.energy_regressor``, ``Thetad`` (N, 6), ``tau`` (N, 6). The parameter vector is
``[inertial (7), f_v (6), f_c (6)]``, the order of ``robot.parameter_names``. The rows
are a regressor with one output: ``identify_base(W[:, None], y[:, None], names)`` fits them.
"""

from __future__ import annotations

import numpy as np
from scipy import integrate

from ident_hw.signal import central_derivatives



def _friction_power(Thetad: np.ndarray, coulomb_width: float) -> np.ndarray:
    """Friction power regressor (N, 12): ``[qd², qd tanh(qd / w)]``."""
    return np.concatenate([Thetad**2, Thetad * np.tanh(Thetad / coulomb_width)], axis=1)


def _check(t, H, Thetad, tau):
    t, H, Thetad, tau = (np.asarray(a, dtype=float) for a in (t, H, Thetad, tau))
    if t.ndim != 1 or H.shape[0] != t.size or Thetad.shape != tau.shape or Thetad.shape[0] != t.size:
        raise ValueError(f"expected t (N,), H (N, p), Thetad and tau (N, k); got {t.shape}, {H.shape}, "
                         f"{Thetad.shape}, {tau.shape}")
    return t, H, Thetad, tau


def power_rows(t, H, Thetad, tau, coulomb_width: float) -> tuple[np.ndarray, np.ndarray]:
    """Power-model equations: ``W`` (N − 4, p + 2k) and ``y`` (N − 4,) = actuated power, W,
    of the samples 2 .. N − 3 (fourth-order ``dh/dt``; ``t`` uniform)."""
    t, H, Thetad, tau = _check(t, H, Thetad, tau)
    if t.size < 5:
        raise ValueError(f"the power model needs at least 5 samples, got {t.size}")
    dH, _ = central_derivatives(H, t)
    inner = slice(2, t.size - 2)
    W = np.concatenate([dH, _friction_power(Thetad, coulomb_width)], axis=1)
    return W[inner], np.sum(Thetad * tau, axis=1)[inner]


def energy_rows(t, H, Thetad, tau, coulomb_width: float, window: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Energy-model equations over consecutive windows of ``window`` samples.

    Returns ``W`` (M, p + 2k) and ``y`` (M,) = work of the actuators over each window, J.
    """
    t, H, Thetad, tau = _check(t, H, Thetad, tau)
    if window < 1 or window >= t.size:
        raise ValueError(f"window must lie in [1, {t.size - 1}] samples, got {window}")
    cum_power = integrate.cumulative_simpson(np.sum(Thetad * tau, axis=1), x=t, initial=0.0)
    cum_friction = integrate.cumulative_simpson(_friction_power(Thetad, coulomb_width), x=t, axis=0, initial=0.0)
    ends = np.arange(0, t.size, window)
    a, b = ends[:-1], ends[1:]
    W = np.concatenate([H[b] - H[a], cum_friction[b] - cum_friction[a]], axis=1)
    return W, cum_power[b] - cum_power[a]
