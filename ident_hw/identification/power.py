"""Power and energy models (the power-model paper): identification without accelerations.

Actuated power equals the rate of change of the kinetic energy plus the friction losses:

    Thetadᵀ tau = dT/dt + sum_j (f_vj qd_j² + f_cj qd_j tanh(qd_j / w)),   T = h(q, qd) pi[:7]

Power model: one scalar row per sample, ``dh/dt`` by fourth-order central differences
(:func:`ident_hw.filtering.central_derivatives`; the two samples at each end, where only second
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

Any other parameter layout (:func:`power_rows_in_layout`, :func:`energy_rows_in_layout`): ``H``
(N, P) covers the whole parameter vector of the robot (its friction columns zero, as
``DescribedRobot.energy_regressor`` gives it: kinetic and potential energy of the bodies, the
rotors' ``Jm qd² / 2``), and the friction power columns go to the model's own ``f_v``, ``f_c``
positions (:class:`FrictionLayout`, read from ``robot.friction_coefficients``), so that the rows
multiply the same parameter vector as the dynamic model's ``Y``. A potential energy term (gravity)
enters through ``ΔH`` like the kinetic one: ``Thetadᵀ tau = dE/dt + friction power`` with ``E``
the total energy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import integrate

from ident_hw.filtering import central_derivatives


@dataclass(frozen=True)
class FrictionLayout:
    """Where a robot's friction coefficients sit in its parameter vector of ``n_params``
    entries: ``fv`` and ``fc`` (k,) column indices, one per actuator in actuator order (the
    friction force of actuator j is ``f_v[j] qd_j + f_c[j] tanh(qd_j / w)``)."""

    n_params: int
    fv: tuple[int, ...]
    fc: tuple[int, ...]

    def __post_init__(self) -> None:
        cols = self.fv + self.fc
        if len(self.fv) != len(self.fc) or len(set(cols)) != len(cols) or not all(0 <= c < self.n_params for c in cols):
            raise ValueError(f"friction columns must be distinct indices below {self.n_params}, one f_v and one "
                             f"f_c per actuator; got fv {self.fv}, fc {self.fc}")

    @classmethod
    def of(cls, robot) -> "FrictionLayout":
        """The layout of a robot model whose ``friction_coefficients`` reads the parameter
        vector (the described robots, the Delta): asked with the vector of the column indices,
        it answers with the indices of ``f_v`` and ``f_c``.

        Raises:
            ValueError: the model's friction coefficients are not entries of its vector (e.g.
                the 3PRRR's, which reads an ``InertialParams``).
        """
        n = len(robot.parameter_names)
        try:
            fv, fc = robot.friction_coefficients(np.arange(n, dtype=float))
        except (AttributeError, TypeError, ValueError) as exc:
            raise ValueError(f"{type(robot).__name__}: its friction coefficients are not entries of its "
                             f"parameter vector ({exc})") from exc
        fv, fc = np.asarray(fv, dtype=float), np.asarray(fc, dtype=float)
        if not (np.array_equal(fv, np.round(fv)) and np.array_equal(fc, np.round(fc))):
            raise ValueError(f"{type(robot).__name__}: its friction coefficients are not entries of its parameter vector")
        return cls(n, tuple(int(i) for i in fv), tuple(int(i) for i in fc))

    def place(self, W: np.ndarray, friction: np.ndarray) -> np.ndarray:
        """``W`` (M, n_params) with the friction columns ``friction`` (M, 2k) ``[f_v block, f_c
        block]`` added at ``fv``, ``fc`` (where an energy regressor has zeros)."""
        k = len(self.fv)
        W = np.array(W, dtype=float)
        if W.shape[1] != self.n_params or friction.shape != (W.shape[0], 2 * k):
            raise ValueError(f"expected W (M, {self.n_params}) and friction (M, {2 * k}); got {W.shape}, {friction.shape}")
        W[:, list(self.fv)] += friction[:, :k]
        W[:, list(self.fc)] += friction[:, k:]
        return W



def friction_power(Thetad, coulomb_width: float) -> np.ndarray:
    """Friction power regressor (N, 2k) ``[qd², qd tanh(qd / w)]`` of rates ``Thetad`` (N, k):
    W per unit of ``f_v`` and of ``f_c``."""
    Thetad = np.atleast_2d(np.asarray(Thetad, dtype=float))
    return np.concatenate([Thetad**2, Thetad * np.tanh(Thetad / coulomb_width)], axis=1)


def _friction_appended(H: np.ndarray, actuators: int) -> tuple[np.ndarray, FrictionLayout]:
    """``H`` (N, p) with ``2 actuators`` zero columns appended, and the layout that puts
    ``f_v``, ``f_c`` there: the 3PRRR's ``[inertial, f_v, f_c]``."""
    p, k = H.shape[1], actuators
    layout = FrictionLayout(p + 2 * k, tuple(range(p, p + k)), tuple(range(p + k, p + 2 * k)))
    return np.concatenate([H, np.zeros((H.shape[0], 2 * k))], axis=1), layout


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
    H, layout = _friction_appended(H, Thetad.shape[1])
    return power_rows_in_layout(t, H, Thetad, tau, coulomb_width, layout)


def energy_rows(t, H, Thetad, tau, coulomb_width: float, window: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Energy-model equations over consecutive windows of ``window`` samples.

    Returns ``W`` (M, p + 2k) and ``y`` (M,) = work of the actuators over each window, J.
    """
    t, H, Thetad, tau = _check(t, H, Thetad, tau)
    H, layout = _friction_appended(H, Thetad.shape[1])
    return energy_rows_in_layout(t, H, Thetad, tau, coulomb_width, layout, window)


def _check_layout(H: np.ndarray, Thetad: np.ndarray, layout: FrictionLayout) -> None:
    if H.shape[1] != layout.n_params or Thetad.shape[1] != len(layout.fv):
        raise ValueError(f"expected H (N, {layout.n_params}) and Thetad (N, {len(layout.fv)}); "
                         f"got {H.shape}, {Thetad.shape}")
    if np.any(H[:, list(layout.fv + layout.fc)] != 0.0):
        raise ValueError("the energy regressor has non-zero friction columns: friction stores no energy")


def power_rows_in_layout(t, H, Thetad, tau, coulomb_width: float, layout: FrictionLayout,
                         edges: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Power-model equations in the robot's own parameter order: ``W`` (M, P) and ``y`` (M,) =
    actuated power, W (``Thetadᵀ tau``), with ``H`` (N, P) the robot's energy regressor (J).

    ``edges`` False: the samples 2 .. N − 3 (M = N − 4), where ``dH/dt`` is fourth order (as
    :func:`power_rows`). True: every sample (M = N), the two at each end second order, for a
    caller that filters the rows in parallel and trims more than two samples at each end anyway
    (:func:`ident_hw.filtering.parallel_decimate`).
    """
    t, H, Thetad, tau = _check(t, H, Thetad, tau)
    _check_layout(H, Thetad, layout)
    if t.size < 5:
        raise ValueError(f"the power model needs at least 5 samples, got {t.size}")
    energy = np.setdiff1d(np.arange(layout.n_params), layout.fv + layout.fc)    # friction stores none
    dH = np.zeros_like(H)
    dH[:, energy] = central_derivatives(np.ascontiguousarray(H[:, energy]), t)[0]
    W = layout.place(dH, friction_power(Thetad, coulomb_width))
    y = np.sum(Thetad * tau, axis=1)
    rows = slice(None) if edges else slice(2, t.size - 2)
    return W[rows], y[rows]


def energy_rows_in_layout(t, H, Thetad, tau, coulomb_width: float, layout: FrictionLayout,
                          window: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Energy-model equations in the robot's own parameter order over consecutive windows of
    ``window`` samples (as :func:`energy_rows`): ``W`` (M, P) = ``[ΔH, friction work]`` and
    ``y`` (M,) = work of the actuators over each window, J."""
    t, H, Thetad, tau = _check(t, H, Thetad, tau)
    _check_layout(H, Thetad, layout)
    return windowed_energy_rows(t, H, np.sum(Thetad * tau, axis=1), friction_power(Thetad, coulomb_width),
                                layout, window)


def windowed_energy_rows(t, H, power, friction, layout: FrictionLayout,
                         window: int) -> tuple[np.ndarray, np.ndarray]:
    """Energy-model equations from their integrands: ``H`` (N, P) the energy regressor (J),
    ``power`` (N,) the actuated power (W), ``friction`` (N, 2k) the friction power regressor
    (:func:`friction_power`), all at times ``t`` (N,); for a caller that filters the integrands
    first (a linear filter commutes with the integral and the differences of ``H``). Returns
    ``W`` (M, P) = ``[ΔH, friction work]`` and ``y`` (M,) = actuated work, J, over consecutive
    windows of ``window`` samples (cumulative Simpson rule)."""
    t, H, power, friction = (np.asarray(a, dtype=float) for a in (t, H, power, friction))
    if t.ndim != 1 or H.shape[0] != t.size or power.shape != t.shape or friction.shape[0] != t.size:
        raise ValueError(f"expected t (N,), H (N, P), power (N,), friction (N, 2k); got {t.shape}, {H.shape}, "
                         f"{power.shape}, {friction.shape}")
    if window < 1 or window >= t.size:
        raise ValueError(f"window must lie in [1, {t.size - 1}] samples, got {window}")
    cum_power = integrate.cumulative_simpson(power, x=t, initial=0.0)
    cum_friction = integrate.cumulative_simpson(friction, x=t, axis=0, initial=0.0)
    ends = np.arange(0, t.size, window)
    a, b = ends[:-1], ends[1:]
    return layout.place(H[b] - H[a], cum_friction[b] - cum_friction[a]), cum_power[b] - cum_power[a]
