"""Power and energy models on noise-free model data: error set by the numerical
differentiation (power) or integration (energy), falling as h² with the sample period."""

from __future__ import annotations

import numpy as np
import pytest

from ident_hw.identification.base_params import identify_base
from ident_hw.identification.power import energy_rows, power_rows
from ident_scenarios import CAD, NAMES, ROBOT, TRUE, make_motion


def base_error(rate: float, kind: str) -> float:
    m = make_motion(duration=10.0, rate=rate)
    H = ROBOT.energy_regressor(m.X, m.Xd, m.zeta, m.zetad)
    if kind == "power":
        W, y = power_rows(m.t, H, m.Thetad, m.tau, ROBOT.coulomb_width)
    else:  # windows of 20 ms at every rate
        W, y = energy_rows(m.t, H, m.Thetad, m.tau, ROBOT.coulomb_width, window=int(rate // 50))
    base, fit = identify_base(W[:, None], y[:, None], NAMES, scale=CAD.as_vector())
    assert base.rank == len(NAMES) - 1  # same structural null direction as the dynamic model
    return float(np.max(np.abs(fit.coef / base.reduce(TRUE.as_vector()) - 1)))


@pytest.mark.parametrize("kind", ["power", "energy"])
def test_error_falls_as_h_squared(kind):
    e200, e400 = base_error(200.0, kind), base_error(400.0, kind)
    assert 3.0 < e200 / e400 < 5.0, (e200, e400)


def test_energy_rows_are_exact_work_for_a_constant_force_field():
    t = np.linspace(0.0, 1.0, 101)
    Thetad = np.tile(np.sin(2 * np.pi * t)[:, None], (1, 2))
    tau = np.ones_like(Thetad)
    H = np.zeros((t.size, 1))
    W, y = energy_rows(t, H, Thetad, tau, coulomb_width=1e-3, window=25)
    np.testing.assert_allclose(y, 2 * np.diff(-np.cos(2 * np.pi * t[::25])) / (2 * np.pi), rtol=1e-3)
    assert W.shape == (4, 1 + 4)
