"""The quality verdict (issue: a wrong result is never marked good): its figures against values
computed here, its thresholds as config keys, and where it shows (STATUS, parameters.json, the
report, the terminal)."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest
from ident_scenarios import CONFIGS
from test_cli import SWEEP_ONLY, synthetic_recordings

from drivers.acquisition import CycleBooks
from drivers.recording import Recording
from ident_hw.config import ConfigError, load_config
from ident_hw.experiment.offline import identify
from ident_hw.experiment.quality import relative_difference
from ident_hw.report import build_report, summary_lines
from ident_hw.results import final_status, mark_status, save_results
from ident_hw.config.to_drivers import axis_scaling


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """The sweep-only config (m_c and carriage friction) and model-made recordings of it."""
    folder = tmp_path_factory.mktemp("sweep")
    path = folder / "sweep.yaml"
    path.write_text(SWEEP_ONLY)
    config = load_config(path)
    (rec_path,) = synthetic_recordings(config, folder)
    return path, Recording.load(rec_path)


def with_quality(path, tmp_path, text: str):
    """The config at ``path`` with ``identification.quality`` set to ``text`` (flow mapping)."""
    edited = tmp_path / "q.yaml"
    edited.write_text(f"extends: {path}\nidentification:\n  quality: {text}\n")
    return load_config(edited)


def test_a_clean_recording_passes_and_the_figures_are_the_data(sweep):
    path, rec = sweep
    results = identify(load_config(path), {"sweep": rec})
    q = results.quality
    assert q.passed and q.reasons == () and final_status(results) == "complete"
    row = q.trajectories["sweep"]
    assert row.planned_fraction == 1.0 and row.valid_fraction == 1.0 and row.longest_gap_s == 0.0
    fit = results.fits[0]
    norm = np.linalg.norm(fit.tau, axis=1)
    by_hand = 100 * np.mean(np.linalg.norm(fit.tau - fit.tau_model, axis=1)[norm > 0] / norm[norm > 0])
    assert row.d_tau_percent == pytest.approx(by_hand, rel=1e-12) and by_hand < 10
    assert set(q.well_identified) >= {"m_c", "fv_zeta1", "fc_zeta1"}
    assert q.thresholds.max_d_tau == 10.0 and q.thresholds.min_valid_fraction == 0.9


def test_thresholds_are_config_keys(sweep, tmp_path):
    path, rec = sweep
    strict = with_quality(path, tmp_path, "{max_d_tau: 0.01, min_well_identified: 8}")
    q = identify(strict, {"sweep": rec}).quality
    assert not q.passed and len(q.reasons) == 2
    assert "d_tau" in q.reasons[1] and "0.01 %" in q.reasons[1]
    assert q.reasons[0].startswith("7 of 7 fitted parameters well identified") and "at least 8" in q.reasons[0]
    with pytest.raises(ConfigError, match=r"identification.quality.max_dtau: unknown key; did you mean 'max_d_tau'"):
        with_quality(path, tmp_path, "{max_dtau: 5}")
    with pytest.raises(ConfigError, match="identification.quality.min_valid_fraction"):
        with_quality(path, tmp_path, "{min_valid_fraction: 1.5}")


def test_incomplete_cycles_and_a_gap_degrade_the_result(sweep):
    """Every 4th cycle loses zeta2's frame and 0.3 s lose every frame (NaN, invalid): 25 % +
    0.3 s of the cycles incomplete, gap 0.3 s + one period around it."""
    path, rec = sweep
    config = load_config(path)
    period = 1.0 / config.bus.sync_rate
    valid = rec.valid.copy()
    valid[::4, 4] = False
    hole = slice(200, 230)                     # 30 cycles = 0.3 s
    valid[hole] = False
    damaged = Recording(**{k: getattr(rec, k) for k in ("t", "cycle", "statusword", "target")},
                        position=np.where(valid, rec.position, np.nan), velocity=rec.velocity,
                        current=np.where(valid, rec.current, np.nan), valid=valid, metadata=rec.metadata)
    q = identify(config, {"sweep": damaged}).quality
    complete = valid.all(axis=1).mean()
    row = q.trajectories["sweep"]
    assert row.valid_fraction == pytest.approx(complete, abs=1e-12) and complete < 0.9
    # the longest stretch without a complete cycle: from the complete cycle before the hole to the one after
    before = max(i for i in range(200) if valid[i].all())
    after = min(i for i in range(230, len(valid)) if valid[i].all())
    assert row.longest_gap_s == pytest.approx((after - before - 1) * period, abs=1e-6)
    assert not q.passed
    assert any(r.startswith(f"sweep: {100 * complete:.1f} % of the cycles complete") for r in q.reasons)
    assert any(r.startswith("sweep: 0.") and "without a complete cycle" in r for r in q.reasons)


def test_a_frame_the_master_could_not_place_degrades_the_result(sweep):
    """A recording whose assembler met a frame it could not place (late beyond its look-ahead:
    some cells handed out before may hold another cycle's data) is not marked good, however
    clean its samples look."""
    path, rec = sweep
    meta = dataclasses.replace(rec.metadata, books=CycleBooks(unplaced_frames=2))
    marked = Recording(**{k: getattr(rec, k) for k in ("t", "cycle", "position", "velocity", "current",
                                                       "statusword", "target", "valid")}, metadata=meta)
    q = identify(load_config(path), {"sweep": marked}).quality
    assert not q.passed and q.trajectories["sweep"].unplaced_frames == 2
    assert q.reasons == ("sweep: 2 frame(s) could not be placed in their SYNC cycle (late by more than "
                           "the assembler's look-ahead, or sent twice)",)


def test_the_verdict_is_in_status_parameters_report_and_terminal(sweep, tmp_path):
    path, rec = sweep
    strict = with_quality(path, tmp_path, "{max_d_tau: 0.01}")
    results = identify(strict, {"sweep": rec})
    folder = tmp_path / "res"
    folder.mkdir()
    mark_status(folder, final_status(results))
    build_report(save_results(folder, results))
    status = (folder / "STATUS").read_text().strip()
    assert status == "degraded: " + results.quality.reasons[0]
    doc = json.loads((folder / "parameters.json").read_text())
    assert doc["quality"]["passed"] is False and doc["quality"]["reasons"] == list(results.quality.reasons)
    assert doc["trajectories"]["sweep"]["cycles"] == len(rec.t)
    page = (folder / "report.html").read_text()
    assert "Quality verdict: DEGRADED" in page and "max_d_tau = 0.01" in page
    lines = summary_lines(folder)
    assert lines[0] == f"status: {status}" and "quality verdict: DEGRADED (identification.quality thresholds):" in lines


def test_relative_difference_by_hand():
    tau = np.array([[3.0, 4.0], [0.0, 0.0], [1.0, 0.0]])       # norms 5, 0 (left out), 1
    a = np.array([[1.0, 1.0], [9.0, 9.0], [2.0, 0.0]])
    b = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]])          # differences 1 and 2
    assert relative_difference(tau, a, b) == pytest.approx(100 * (1 / 5 + 2 / 1) / 2)


def test_a_parameter_its_data_do_not_excite_is_held_and_named(sweep):
    """Every cycle in which carriage 3 moves came incomplete: its friction has no row to be
    fitted from. It is held (not fitted, no sigma) and the verdict names it; the rest is fitted."""
    path, rec = sweep
    moving = np.abs(rec.velocity[:, 5]) > 0
    # the cycles around its motion too: the filters' support at the ends of each stretch
    moving = np.convolve(moving, np.ones(41), mode="same") > 0
    valid = rec.valid & ~moving[:, None]
    damaged = Recording(**{k: getattr(rec, k) for k in ("t", "cycle", "statusword", "target", "velocity")},
                        position=np.where(valid, rec.position, np.nan), current=np.where(valid, rec.current, np.nan),
                        valid=valid, metadata=rec.metadata)
    results = identify(load_config(path), {"sweep": damaged})
    rows = {r.name: r for r in results.parameter_rows()}
    assert rows["fv_zeta3"].step == "" and rows["fc_zeta3"].step == ""          # held
    assert rows["m_c"].step == "carriages" and rows["fv_zeta1"].step == "carriages"
    assert any(r.startswith("step carriages: fv_zeta3, fc_zeta3 not excited") for r in results.quality.reasons)


def _results_of(actuators, fits):
    from ident_hw.results import ParameterTable, Results
    table = ParameterTable(names=(), units=(), initial=np.zeros(0), identified=np.zeros(0), sigma=np.zeros(0),
                           lower=np.zeros(0), upper=np.zeros(0), step=(), method=(), truth=None)
    return Results(parameters=table, actuators=tuple(a.name for a in actuators),
                   actuator_kinds=tuple(a.kind for a in actuators), fits=fits)


def test_axis_residuals_against_the_same_drives_by_hand():
    """axis_reasons: per trajectory, each axis's RMS residual in A (force over the config's force per
    ampere) over the median of its group's others; the worst trajectory counts. Built here from
    residuals of known RMS, orthogonal to the prediction (no gain), on the 3PRRR's actuators (links
    and carriages two groups of three)."""
    from ident_hw.experiment.quality import axis_reasons, same_drive_groups
    from ident_hw.results import TrajectoryFit
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    actuators = config.robot.actuators
    assert same_drive_groups(actuators) == [(0, 1, 2), (3, 4, 5)]
    per_amp = np.array([axis_scaling(a).force_per_amp for a in actuators])
    n = 400
    signs = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)[:, None]      # RMS of +-r is r, sum 0
    ma = {"a": np.array([10, 10, 10, 2, 2, 2.0]), "b": np.array([10, 40, 10, 2, 2, 5.0])}
    fits = []
    for name, rms_ma in ma.items():
        tau = np.ones((n, 6))
        residual = signs * rms_ma * 1e-3 * per_amp
        fits.append(TrajectoryFit(name=name, role="identification", t=np.arange(n) * 0.01, tau=tau + residual,
                                  tau_model=tau, Theta=np.zeros((n, 6)), tau_base=tau))
    spreads, ratios, reasons = axis_reasons(_results_of(actuators, fits), actuators, config.identification.quality)
    assert spreads == pytest.approx(dict.fromkeys(ratios, 0.0), abs=1e-12)
    # trajectory b: theta2 40 mA against 10 and 10 -> 4; zeta3 5 mA against 2 and 2 -> 2.5 (under 3)
    assert ratios == pytest.approx({"theta1": 1.0, "theta2": 4.0, "theta3": 1.0, "zeta1": 1.0, "zeta2": 1.0,
                                    "zeta3": 2.5})
    # theta1's worst: b, against theta2 and theta3's median (10 + 40) / 2 -> 10 / 25 = 0.4 < a's 1.0
    assert len(reasons) == 1 and reasons[0].startswith("theta2: residual 40 mA on b, 4.0 times")


def test_axis_gains_against_the_same_drives_by_hand():
    """axis_reasons: the least-squares gain of measured over predicted forces per axis, over all
    trajectories, against its group's median. Forces here are (1 + g) times the prediction: links
    +1, 0, +5 % (median 1: spreads 0, -1, +4), carriages 0, 0, -3 % (spreads 0, 0, -3)."""
    from ident_hw.experiment.quality import axis_reasons
    from ident_hw.results import TrajectoryFit
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    actuators = config.robot.actuators
    g = np.array([0.01, 0.0, 0.05, 0.0, 0.0, -0.03])
    t = np.arange(500) * 0.004
    fits = []
    for name, f in (("a", 0.5), ("b", 1.3)):
        predicted = np.sin(2 * np.pi * f * t)[:, None] * np.array([1, 2, 3, 40, 50, 60.0])
        fits.append(TrajectoryFit(name=name, role="identification", t=t, tau=predicted * (1 + g),
                                  tau_model=predicted, Theta=np.zeros_like(predicted), tau_base=predicted))
    spreads, _, reasons = axis_reasons(_results_of(actuators, fits), actuators, config.identification.quality)
    assert spreads == pytest.approx({"theta1": 0.0, "theta2": -1.0, "theta3": 4.0, "zeta1": 0.0, "zeta2": 0.0,
                                     "zeta3": -3.0}, abs=1e-9)
    gains = [r for r in reasons if "off what the model predicts" in r]
    assert [r.split(":")[0] for r in gains] == ["theta3", "zeta3"]
    assert gains[0].startswith("theta3: forces +5.00 % off what the model predicts, against +1.00 %")


def test_the_floor_names_one_axis_of_a_group_and_defers_to_the_same_drives_comparison():
    """floor_reasons on residuals of known RMS against a floor of 1 mA (limit 5): the links 6.1, 1
    and 5.9 mA, the carriages 1, 8 and 1 mA. Of the links beyond (theta1, theta3) only the one
    furthest above is named; where the comparison with the same drives named theta3 (its gain),
    the floor names theta3, not the twin the fit spread its error onto; where it named theta2,
    within its floor, no link. The carriages are another group: zeta2 named each time."""
    from ident_hw.experiment.quality import floor_reasons
    from ident_hw.results import TrajectoryFit
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    actuators, limits = config.robot.actuators, config.identification.quality
    assert limits.max_residual_over_floor == 5
    per_amp = np.array([axis_scaling(a).force_per_amp for a in actuators])
    n = 400
    signs = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)[:, None]      # RMS of +-r is r
    tau = np.ones((n, 6))
    residual = signs * np.array([6.1, 1.0, 5.9, 1.0, 8.0, 1.0]) * 1e-3 * per_amp
    fit = TrajectoryFit(name="a", role="identification", t=np.arange(n) * 0.01, tau=tau + residual,
                        tau_model=tau, Theta=np.zeros((n, 6)), tau_base=tau)
    results, floors = _results_of(actuators, [fit]), {"a": np.full(6, 1e-3)}
    ratios, reasons = floor_reasons(results, actuators, limits, floors)
    assert ratios == pytest.approx({"theta1": 6.1, "theta2": 1.0, "theta3": 5.9, "zeta1": 1.0, "zeta2": 8.0,
                                    "zeta3": 1.0})
    for named, expected in ((frozenset(), ["theta1", "zeta2"]), (frozenset({"theta3"}), ["theta3", "zeta2"]),
                            (frozenset({"theta2"}), ["zeta2"])):
        _, reasons = floor_reasons(results, actuators, limits, floors, named=named)
        assert [r.split(":")[0] for r in reasons] == expected, named
    assert reasons[0].startswith("zeta2: residual 8 mA on a, 8.0 times its current noise at standstill")


def test_force_lags_by_hand():
    """force_lags: measured forces that are the predicted ones T later (tau(t) = p(t - T)), on
    trajectories with a gap in their sample times, give back T per axis (to first order in
    omega T, and the central difference's (omega h)^2 / 6: both below 1e-3 here); a lag beyond
    max_force_lag fails the verdict, naming the axes."""
    from ident_hw.experiment.quality import force_lags, verdict
    from ident_hw.results import TrajectoryFit
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    actuators = config.robot.actuators
    lag = np.array([0.0, 0.2e-3, 0.4e-3, 2.0e-3, 3.0e-3, -1.5e-3])
    t = np.concatenate([np.arange(0, 5, 0.004), 7 + np.arange(0, 5, 0.004)])      # a 2 s gap
    fits = []
    for name, f in (("a", 0.7), ("b", 1.1)):
        amplitude = np.array([1, 2, 3, 40, 50, 60.0])
        predicted = np.sin(2 * np.pi * f * t)[:, None] * amplitude
        measured = np.sin(2 * np.pi * f * (t[:, None] - lag)) * amplitude
        fits.append(TrajectoryFit(name=name, role="identification", t=t, tau=measured, tau_model=predicted,
                                  Theta=np.zeros_like(predicted), tau_base=predicted))
    results = _results_of(actuators, fits)
    found = force_lags(results)
    assert list(found) == [a.name for a in actuators]
    np.testing.assert_allclose([f.seconds for f in found.values()], lag, rtol=1e-3, atol=1e-9)
    # the residual beside the lag: the second-order term (omega T)^2 / 2, tiny against T itself
    assert all(f.sigma < 1e-3 * abs(f.seconds) for f, true in zip(found.values(), lag) if true)
    q = verdict(results, config.identification.quality, actuators)
    (reason,) = [r for r in q.reasons if "lag" in r]
    named = re.findall(r"\) on (\w+)", reason)
    assert named == ["zeta1", "zeta2", "zeta3"], reason
    assert reason.startswith("the measured forces lag the model's by 2.00 ms (sigma "), reason
