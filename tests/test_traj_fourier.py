"""Optimised Fourier excitation: analytic derivatives, rest at both ends, base columns, criterion."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ident_hw.config import load_config
from ident_hw.config.robots import model_of
from trajectories import carriage_sweep, check_trajectory, five_squares, validation_triangle
from scipy.optimize._numdiff import approx_derivative

from trajectories.fourier import FourierExcitation, _Problem, base_scaling, optimise_excitation, stacked_regressor
from ident_hw.experiment.robot_trajectories import feasibility_limits

ROOT = Path(__file__).resolve().parents[1]
CACHED = ROOT / "trajectories" / "data" / "fourier-nominal.json"


@pytest.fixture(scope="module")
def rig():
    cfg = load_config(ROOT / "configs" / "robot-3prrr.yaml").robot
    return model_of(cfg), feasibility_limits(cfg)


def test_series_derivatives_and_rest_to_rest():
    rng = np.random.default_rng(1)
    ex = FourierExcitation(0.2, 5.0, 1.0, rng.normal(size=6) * 0.01, rng.normal(size=(6, 3)) * 0.02,
                           rng.normal(size=(6, 3)) * 0.02)
    dt = 1e-4
    t = np.arange(0, 5.0 + dt / 2, dt)
    m = ex.evaluate(t)
    q, qd, qdd = m.q, m.qd, m.qdd
    assert np.all(q[[0, -1]] == 0) and np.all(qd[[0, -1]] == 0) and np.all(qdd[[0, -1]] == 0)
    jerk = np.abs(np.diff(qdd, axis=0)).max(axis=0) / dt  # bounded, piecewise continuous
    assert np.all(np.abs((q[2:] - q[:-2]) / (2 * dt) - qd[1:-1]) <= dt**2 * jerk / 6 * 1.05 + 1e-13)
    assert np.all(np.abs((qd[2:] - qd[:-2]) / (2 * dt) - qdd[1:-1]) <= dt * jerk / 2 * 1.05 + 1e-12)
    # eq. 84-85 in the middle (envelope = 1): velocity is sum a cos + b sin
    mid = np.searchsorted(t, 2.5)
    w = 2 * np.pi * 0.2 * np.arange(1, 4)
    np.testing.assert_allclose(qd[mid], ex.a @ np.cos(w * t[mid]) + ex.b @ np.sin(w * t[mid]), rtol=1e-12)


def test_base_columns_drop_exactly_the_structural_regrouping(rig):
    robot, _ = rig
    base = base_scaling(robot)
    names = [robot.parameter_names[i] for i in base.columns]
    assert len(names) == 18 and "m_l2" not in names
    # independent derivation: link 2 (m_l2 = 1, I_l2 = s2 (l2 - s2)) equals point masses
    # m_B = 1 - s2/l2 at B_i and m_C = s2/l2 at C_i; m_B regroups with the carriage and link 1
    # (same translating mass, first moment and inertia about A_i), the three m_C with the
    # end-effector (mass 3 m_C, inertia 3 m_C h^2, valid for guides 120 deg apart).
    g = robot.geometry
    mB, mC = 1 - g.s2 / g.l2, g.s2 / g.l2
    dm_l1 = mB * g.l1 / g.s1
    p = np.zeros(robot.n_params)
    p[:7] = [-(mB - dm_l1), -dm_l1, -(mB * g.l1**2 - dm_l1 * g.s1**2), 1.0, g.s2 * (g.l2 - g.s2), -3 * mC,
             -3 * mC * g.h**2]
    rng = np.random.default_rng(5)
    q = rng.uniform(-1, 1, (200, 6)) * [0.05, 0.05, 0.3, 0.05, 0.05, 0.05]
    W = stacked_regressor(robot, q, rng.normal(size=(200, 6)) * 0.05, rng.normal(size=(200, 6)) * 0.3)
    assert np.linalg.norm(W @ p) < 1e-12 * np.linalg.norm(W, 2) * np.linalg.norm(p)
    assert np.linalg.matrix_rank(W[:, base.columns]) == 18


def test_cached_excitation_is_feasible_and_excites_every_base_parameter(rig):
    robot, limits = rig
    ex = FourierExcitation.load(CACHED)
    traj = ex.trajectory(robot, rate=250.0)
    report = check_trajectory(traj, robot, limits)
    assert report.ok, str(report)
    base = base_scaling(robot)
    W = stacked_regressor(robot, np.c_[traj.X, traj.zeta], np.c_[traj.Xd, traj.zetad], np.c_[traj.Xdd, traj.zetadd])
    assert np.linalg.matrix_rank(W[:, base.columns]) == len(base.columns)  # full column rank
    cond = base.cond(W)
    # locally optimal: no small feasible change of its coefficients conditions it better
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(6):
        da, db = (rng.normal(size=ex.a.shape) * 1e-3 * np.abs(ex.a).max(),
                  rng.normal(size=ex.b.shape) * 1e-3 * np.abs(ex.b).max())
        for sign in (1.0, -1.0):
            moved = dataclasses.replace(ex, a=ex.a + sign * da, b=ex.b + sign * db).trajectory(robot, rate=250.0)
            if not check_trajectory(moved, robot, limits).ok:
                continue
            Wm = stacked_regressor(robot, np.c_[moved.X, moved.zeta], np.c_[moved.Xd, moved.zetad],
                                   np.c_[moved.Xdd, moved.zetadd])
            assert base.cond(Wm) >= cond * (1 - 1e-3)
            checked += 1
    assert checked >= 4    # better conditioned than the paper's whole campaign stacked
    paper = [carriage_sweep(robot, limits), *five_squares(robot, limits), validation_triangle(robot, limits)]
    Wp = np.vstack([stacked_regressor(robot, np.c_[t.X, t.zeta], np.c_[t.Xd, t.zetad], np.c_[t.Xdd, t.zetadd])
                    for t in paper])
    assert 2 * cond <= base.cond(Wp)
    squares = np.vstack([stacked_regressor(robot, np.c_[s.X, s.zeta], np.c_[s.Xd, s.zetad], np.c_[s.Xdd, s.zetadd])
                         for s in five_squares(robot, limits)])
    # five squares: carriages blocked, m_c and the carriage friction are not excited at all
    assert np.linalg.matrix_rank(squares[:, base.columns]) < len(base.columns)
    assert base.cond(squares) >= 10 * cond


def test_malformed_coefficient_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"excitation": {"base_frequency": 0.1}}')
    with pytest.raises(ValueError, match="bad.json: not a Fourier excitation file"):
        FourierExcitation.load(bad)


@pytest.mark.slow
def test_optimisation_improves_on_its_start_and_on_the_papers_campaign(rig):
    """The defaults (0.2 Hz, five harmonics: link accelerations twice those of 0.1 Hz with three,
    which the identification on the simulated rig needs against set-point quantisation): the
    optimum is feasible, four times better conditioned than its random feasible start and five
    times better than the paper's whole campaign stacked."""
    robot, limits = rig
    result = optimise_excitation(robot, limits)
    assert result.cond_final * 4 <= result.cond_initial
    paper = [carriage_sweep(robot, limits), *five_squares(robot, limits), validation_triangle(robot, limits)]
    W = np.vstack([stacked_regressor(robot, np.c_[t.X, t.zeta], np.c_[t.Xd, t.zetad], np.c_[t.Xdd, t.zetadd])
                   for t in paper])
    assert result.cond_final * 5 <= result.base.cond(W)
    assert check_trajectory(result.excitation.trajectory(robot), robot, limits).ok


def test_the_batched_gradient_is_as_good_as_scipys_own_differences(rig):
    """The optimiser's gradient (every perturbed excitation in one batch of samples) against
    SciPy's central differences of the same cost, one excitation at a time: within a thousandth
    of the gradient's scale, and no further from them than SciPy's own forward differences (the
    cost's kinematics carry ~1e-12 of noise, which a step of 1.5e-8 makes ~3e-4)."""
    robot, limits = rig
    problem = _Problem(robot, limits, base_scaling(robot), np.linspace(0.0, 5.0, 100), 0.2, 5.0, 1.5, 5)
    v = np.concatenate([np.random.default_rng(3).normal(0.0, 0.1, 60), np.zeros(6)])
    assert problem.cost(v) < 1e3                                          # within reach
    central = approx_derivative(problem.cost, v, method="3-point")
    forward = approx_derivative(problem.cost, v, method="2-point")
    error = np.abs(problem.gradient(v) - central).max()
    assert error <= 1e-3 * np.abs(central).max()
    assert error <= 1.5 * np.abs(forward - central).max()
