"""The encoders' resolution in every sigma (issue 30): the recordings read again with the count
edges moved (ident_hw.experiment.encoder), the spread of those draws' estimates joining the
least-squares covariance (steps.fit_base, fit_sqp_step), and where the simulated rig's and the
study's encoders count (sim.encoder_edges)."""

import dataclasses
import json
import logging
from types import SimpleNamespace

import numpy as np
import pytest

from drivers.recording import Recording
from drivers.recording_metadata import RecordingMetadata
from ident_hw.config import load_config
from ident_hw.config.schema import ConfigError
from ident_hw.experiment.encoder import count_shifts, reread, smoothed_positions, spread_covariance, uncounted_axes
from ident_hw.experiment.offline import identify
from ident_hw.experiment.steps import fit_base
from ident_hw.experiment.plan import plan
from ident_hw.records import MassFitStep, RecordingCoverage
from ident_hw.storage import from_json, to_json
from ident_hw.report import coverage_text
from ident_hw.identification.least_squares import compensated, wls

from ident_scenarios import CONFIGS, exact_recording, without_draws
from ident_hw.config.to_drivers import encoder_edge_counts

RATE = 250.0


def smooth_recording(counts_per_unit: np.ndarray, seconds: float = 4.0) -> tuple[Recording, np.ndarray]:
    """Two axes on slow sines, read in whole counts; axis 0 loses its position for 11 rows."""
    t = np.arange(int(seconds * RATE)) / RATE
    truth = np.column_stack([0.3 * np.sin(2 * np.pi * 0.5 * t) + 0.1, 0.02 * np.sin(2 * np.pi * 0.8 * t + 1.0)])
    position = np.rint(truth * counts_per_unit) / counts_per_unit
    n = len(t)
    valid = np.ones((n, 2), bool)
    position_valid = valid.copy()
    position_valid[400:411, 0] = False
    position[400:411, 0] = np.nan
    rec = Recording(t=t, cycle=np.arange(n), position=position, velocity=np.zeros((n, 2)), current=np.zeros((n, 2)),
                    statusword=np.zeros((n, 2), np.int32), target=truth.copy(), valid=valid,
                    position_valid=position_valid, metadata=RecordingMetadata(sync_period=1 / RATE))
    return rec, truth


def test_reread_reads_the_motion_on_the_moved_count_grid():
    counts_per_unit = np.array([2.0e4, 4.0e5])
    rec, truth = smooth_recording(counts_per_unit)
    shift = np.array([0.3, -0.45])
    again = reread(rec, smoothed_positions(rec, RATE, cutoff_hz=10.0, order=4), counts_per_unit, shift)
    ok = rec.position_valid
    counts = again.position * counts_per_unit + shift
    # every valid position lies on the moved grid: a whole number of counts past the shift
    assert np.abs(counts[ok] - np.rint(counts[ok])).max() < 1e-6
    # away from the gap (bridged linearly, then smoothed), the motion read in whole counts: within
    # half a count plus what the smoothing of the recording's own counts left (a fraction of one),
    # with the RMS of a rounding, 1/sqrt(12) count
    off = ((again.position - truth) * counts_per_unit)[np.r_[:340, 470:len(truth)]]
    assert np.abs(off).max() <= 0.8
    np.testing.assert_allclose(np.sqrt(np.mean(off ** 2, axis=0)), 12 ** -0.5, rtol=0.15)
    # and not the recording's own reading: the shift moves some readings by a count
    moved = np.rint(again.position * counts_per_unit) != np.rint(rec.position * counts_per_unit)
    assert moved[ok].mean() > 0.2
    # rows without a valid position keep what they held
    assert np.all(np.isnan(again.position[~ok]))
    assert np.array_equal(again.current, rec.current) and np.array_equal(again.t, rec.t)


def test_count_shifts_are_seeded_and_within_half_a_count():
    a, b = count_shifts(8, 6), count_shifts(8, 6)
    assert np.array_equal(a, b) and a.shape == (8, 6)
    assert np.all(np.abs(a) <= 0.5) and len(np.unique(a)) == a.size


def _weighted_lstsq(Y: np.ndarray, tau: np.ndarray, std: np.ndarray) -> np.ndarray:
    """Independent WLS: outputs divided by their std, stacked, numpy's lstsq."""
    W = (Y / std[None, :, None]).reshape(-1, Y.shape[2])
    return np.linalg.lstsq(W, (tau / std).reshape(-1), rcond=None)[0]


def test_fit_base_adds_the_covariance_of_the_draws_estimates():
    rng = np.random.default_rng(7)
    names = ("a", "b", "c")
    N = 400
    Y = rng.normal(size=(N, 2, 3))
    theta = np.array([1.0, -2.0, 0.5])
    tau = Y @ theta + rng.normal(0, [0.01, 0.05], (N, 2))
    draws = [(Y + rng.normal(0, 0.02, Y.shape), tau) for _ in range(6)]
    step = SimpleNamespace(name="base", method="wls", trajectories=("t",))
    coef0 = np.zeros(3)
    one = fit_base(step, names, names, Y, tau, coef0, coef0, None, 10.0)
    alone, record_alone = one.fit, one.record
    both = fit_base(step, names, names, Y, tau, coef0, coef0, None, 10.0, draws=draws)
    fit, record = both.fit, both.record
    # the estimate: the data's own, corrected for the regressor noise the draws show
    np.testing.assert_allclose(np.array(record.encoder_shift), fit.coef - alone.coef, rtol=0, atol=1e-15)
    assert np.all(np.abs(fit.coef - alone.coef) > 0) and record_alone.encoder_shift == ()
    std = np.array(record_alone.output_std)
    estimates = np.array([_weighted_lstsq(Yk, tk, std) for Yk, tk in draws])
    spread = np.cov(estimates, rowvar=False)
    np.testing.assert_allclose(fit.covariance, alone.covariance + spread, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(fit.sigma, np.sqrt(np.diag(alone.covariance) + np.diag(spread)), rtol=1e-9)
    np.testing.assert_allclose(record.encoder_sigma, np.sqrt(np.diag(spread)), rtol=1e-9)
    assert record.encoder_draws == 6 and record_alone.encoder_draws == 0
    assert "encoder_draws" in to_json(record) and "encoder_draws" not in to_json(record_alone)


def test_spread_covariance_of_fewer_than_two_draws_is_zero():
    assert np.array_equal(spread_covariance([np.ones(3)], 3), np.zeros((3, 3)))
    assert np.array_equal(spread_covariance([], 2), np.zeros((2, 2)))


def _sim_config(tmp_path, extra: str):
    path = tmp_path / "sim.yaml"
    path.write_text(f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n{extra}\n")
    return load_config(path)


def test_sim_encoder_edges_fixed_by_default_random_from_the_seed(tmp_path):
    assert np.array_equal(encoder_edge_counts(_sim_config(tmp_path, "").sim, 6), np.zeros(6))
    five = _sim_config(tmp_path, "sim: {seed: 5, encoder_edges: random}").sim
    six = _sim_config(tmp_path, "sim: {seed: 6, encoder_edges: random}").sim
    edges = encoder_edge_counts(five, 6)
    assert np.array_equal(edges, encoder_edge_counts(five, 6))
    assert np.all(np.abs(edges) <= 0.5) and not np.array_equal(edges, encoder_edge_counts(six, 6))
    with pytest.raises(ConfigError, match="encoder_edges"):
        _sim_config(tmp_path, "sim: {encoder_edges: sometimes}")


def test_the_draws_regressor_spread_undoes_the_shrinking_of_noise_in_the_regressor():
    """Errors in variables: a regressor measured with noise (here 0.6 of each column's spread)
    shrinks the least-squares estimate towards zero, by 1 / (1 + 0.36) on independent unit
    columns. Draws of the same regressor with the same noise give its covariance, and the
    compensated estimate is unbiased: over 60 data sets its mean is within 3 standard errors
    of the truth, where the plain one is 26 % short. The compensated estimate of one data set is
    also the normal equations with the draws' per-row covariance, written out here row by row."""
    rng = np.random.default_rng(3)
    theta = np.array([1.0, -2.0, 0.5])
    N, noise = 300, 0.6
    plain, corrected = [], []
    for _ in range(60):
        truth = rng.normal(size=(N, 2, 3))
        tau = truth @ theta + rng.normal(0, [0.05, 0.1], (N, 2))
        measured = truth + rng.normal(0, noise, truth.shape)
        draws = [truth + rng.normal(0, noise, truth.shape) for _ in range(8)]
        fit = wls(measured, tau, ("a", "b", "c"), output_std=np.array([1.0, 2.0]))
        plain.append(fit.coef)
        corrected.append(compensated(fit, measured, tau, draws).coef)
    plain, corrected = np.array(plain), np.array(corrected)
    np.testing.assert_allclose(plain.mean(axis=0), theta / (1 + noise ** 2), rtol=0.05)
    assert np.all(np.abs(corrected.mean(axis=0) - theta) < 3 * corrected.std(axis=0, ddof=1) / np.sqrt(60))

    w = np.array([1.0, 0.5])                      # 1 / output_std, rows of the last data set
    rows = [(measured[t, j] * w[j], tau[t, j] * w[j], np.cov(np.array([d[t, j] * w[j] for d in draws]), rowvar=False))
            for t in range(N) for j in range(2)]
    A = sum(np.outer(r, r) - D for r, _, D in rows)
    b = sum(r * y for r, y, _ in rows)
    np.testing.assert_allclose(compensated(fit, measured, tau, draws).coef, np.linalg.solve(A, b), rtol=1e-10)


def test_compensation_needs_two_draws():
    rng = np.random.default_rng(4)
    Y = rng.normal(size=(50, 2, 3))
    tau = Y @ np.ones(3)
    fit = wls(Y, tau, ("a", "b", "c"), output_std=np.ones(2))
    assert compensated(fit, Y, tau, [Y + 0.1]) is fit and compensated(fit, Y, tau, []) is fit


def test_positions_off_the_count_grid_are_found_per_axis():
    """Whole counts pass, on a grid offset by a constant too (a home between two counts); exact
    positions (a simulation's truth, a resampled file) do not."""
    counts = np.array([4096 / (2 * np.pi), 2e5])
    rec, truth = smooth_recording(counts)
    assert uncounted_axes(rec, counts) == ()
    shifted = rec.position + np.array([0.0, 0.3]) / counts
    assert uncounted_axes(dataclasses.replace(rec, position=shifted), counts) == ()
    exact = rec.position.copy()
    exact[:, 1] = truth[:, 1]
    assert uncounted_axes(dataclasses.replace(rec, position=exact), counts) == (1,)


def test_a_recording_not_in_whole_counts_is_identified_without_draws(tmp_path, caplog):
    """The plant's exact positions under a config that asks for draws: none are taken (they would
    round what was never rounded, and the compensation would remove noise that is not there), the
    estimates and sigma are those of the same config without draws, and the recording's coverage
    names the axes, in the terminal text and through parameters.json."""
    path = tmp_path / "exact.yaml"
    path.write_text(f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n"
                    "bus: {interface: virtual, channel: unused, sync_rate: 100.0}\n"
                    "trajectories:\n  - {name: square, kind: square, size: 0.06, speed_scale: 0.6}\n"
                    "identification:\n  steps: [{name: links, trajectories: [square], parameters: [m_l2, m_ee, I_l1]}]\n"
                    "  validation: []\n")
    config = load_config(path)
    assert config.identification.encoder_draws > 1
    (planned,) = plan(config, ["square"])
    rec = exact_recording(config, planned.trajectory, None)
    with caplog.at_level(logging.INFO, logger="ident_hw"):
        results = identify(config, {"square": rec})
    said = [r.getMessage() for r in caplog.records]
    plain = identify(without_draws(config), {"square": rec})
    np.testing.assert_array_equal(results.parameters.identified, plain.parameters.identified)
    np.testing.assert_array_equal(results.parameters.sigma, plain.parameters.sigma)
    assert [type(step) for step in results.steps] == [MassFitStep] and results.steps[0].encoder_draws == 0
    actuators = tuple(a.name for a in config.robot.actuators)
    used = results.trajectories["square"]
    assert used.positions_not_in_counts == actuators
    assert any("no encoder draws" in line and "not whole encoder counts" in line for line in said), said
    assert "not in whole encoder counts" in coverage_text(used)
    assert from_json(RecordingCoverage, json.loads(json.dumps(to_json(used)))) == used
