"""Rest-to-rest timing: continuity, finite differences, limits (pure path layer, no robot)."""

import numpy as np
import pytest

from trajectories.motion import SampledMotion
from trajectories.timing import (QUINTIC_PEAK_ACCEL, QUINTIC_PEAK_SPEED, PiecewisePath, Segment, quintic,
                                 rest_to_rest_path, time_grid)


def identity(q, qd, qdd):
    return SampledMotion(q, qd, qdd)


def test_quintic_peaks_and_boundary_conditions():
    u = np.linspace(0, 1, 200001)
    profile = quintic(u)
    s, ds, dds = profile.q, profile.qd, profile.qdd
    assert s[0] == 0 and s[-1] == 1
    assert ds[0] == ds[-1] == dds[0] == dds[-1] == 0
    assert ds.max() == pytest.approx(QUINTIC_PEAK_SPEED, rel=1e-9)
    assert np.abs(dds).max() == pytest.approx(QUINTIC_PEAK_ACCEL, rel=1e-8)
    # derivatives against central differences
    h = u[1] - u[0]
    assert np.max(np.abs(np.gradient(s, h)[1:-1] - ds[1:-1])) < 1e-8
    assert np.max(np.abs(np.gradient(ds, h)[1:-1] - dds[1:-1])) < 1e-6


def test_piecewise_path_is_c2_and_derivatives_match_finite_differences():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(5, 6)) * 0.05
    shapes = [None, rng.normal(size=(2, 6)) * 0.01, None, rng.normal(size=(1, 6)) * 0.01]
    path = rest_to_rest_path(points, identity, np.full(6, 0.1), np.full(6, 1.0), shapes, dwell=0.2)
    dt = 2e-5
    t = np.arange(0, path.duration, dt)
    m = path.evaluate(t)
    q, qd, qdd = m.q, m.qd, m.qdd
    # no jumps: the largest step of each signal is bounded by its derivative's bound times dt
    assert np.max(np.abs(np.diff(q, axis=0))) <= np.abs(qd).max() * dt * 1.001
    assert np.max(np.abs(np.diff(qd, axis=0))) <= np.abs(qdd).max() * dt * 1.001
    # continuity of the acceleration across boundaries: steps bounded by jerk * dt (the jerk of
    # a segment is at most 60 |D| / T^3 plus the bend terms, far below 1e3 here)
    assert np.max(np.abs(np.diff(qdd, axis=0))) < 1e3 * dt
    # derivatives agree with central differences of the positions
    fd_v = (q[2:] - q[:-2]) / (2 * dt)
    fd_a = (qd[2:] - qd[:-2]) / (2 * dt)
    assert np.max(np.abs(fd_v - qd[1:-1])) < 1e-6
    assert np.max(np.abs(fd_a - qdd[1:-1])) < 1e-5
    # every waypoint is reached at rest at a segment boundary
    for k, point in enumerate(points):
        hits = np.flatnonzero(np.all(np.isclose(path.evaluate(path.boundaries).q, point, atol=1e-12), axis=1))
        assert hits.size, f"waypoint {k} not on a boundary"
        rest = path.evaluate(path.boundaries[hits])
        v, a = rest.qd, rest.qdd
        assert np.all(v == 0) and np.all(np.abs(a) < 1e-12)


def test_durations_meet_the_limits_exactly_at_the_utilisation():
    points = np.array([[0, 0, 0, 0, 0, 0], [0.06, 0, 0, 0, 0, 0], [0.06, 0.002, 0, 0, 0, 0.0]])
    vmax, amax = np.full(6, 0.1), np.full(6, 1.0)
    path = rest_to_rest_path(points, identity, vmax, amax, utilisation=1.0)
    # first segment: 0.06 m, speed-bound T = 1.875 * 0.06 / 0.1 = 1.125 s (accel bound 0.59 s)
    assert path.segments[0].duration == pytest.approx(QUINTIC_PEAK_SPEED * 0.06 / 0.1, rel=1e-12)
    # second: 2 mm, accel-bound T = sqrt(5.7735 * 0.002 / 1)
    assert path.segments[1].duration == pytest.approx(np.sqrt(QUINTIC_PEAK_ACCEL * 0.002 / 1.0), rel=1e-3)
    t = time_grid(path.duration, 1000.0)
    m = path.evaluate(t)
    qd, qdd = m.qd, m.qdd
    assert np.abs(qd).max() <= 0.1 * (1 + 1e-9) and np.abs(qd).max() > 0.0999
    assert np.abs(qdd).max() <= 1.0 * (1 + 1e-9) and np.abs(qdd).max() > 0.999


def test_time_grid_and_path_errors():
    assert np.allclose(np.diff(time_grid(1.0, 250.0)), 1 / 250)
    assert time_grid(1.001, 500.0)[-1] == 1.001
    with pytest.raises(ValueError, match="sample rate"):
        time_grid(1.0, 0)
    with pytest.raises(ValueError, match="segment 1 starts"):
        PiecewisePath([Segment(np.zeros(2), np.ones(2), 1.0), Segment(np.zeros(2), np.ones(2), 1.0)])
    with pytest.raises(ValueError, match="waypoints"):
        rest_to_rest_path(np.zeros(3), identity, np.ones(6), np.ones(6))
