"""The quality verdict (issue: a wrong result is never marked good): its figures against values
computed here, its thresholds as config keys, and where it shows (STATUS, parameters.json, the
report, the terminal)."""

from __future__ import annotations

import dataclasses
import html
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
    assert row.coverage == 1.0 and row.valid_fraction == 1.0 and row.longest_gap_s == 0.0
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
    # the keys of the checks against twin axes, retired: the message says what became of them
    with pytest.raises(ConfigError, match=r"identification.quality.max_axis_residual_ratio: no longer a key: removed: "
                                          r"an axis's residual is judged against its own noise floor"):
        with_quality(path, tmp_path, "{max_axis_residual_ratio: 3}")
    with pytest.raises(ConfigError, match=r"max_axis_gain_spread: no longer a key: replaced by max_axis_gain"):
        with_quality(path, tmp_path, "{max_axis_gain_spread: 2}")


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


def test_the_verdict_names_the_first_cause_before_its_consequences(sweep):
    """Every row of the sweep with zeta2's current at 71 A (its limit 8 A: a drive that lets no such
    current through, a log decoded with another drive's scaling): the first reason names zeta2,
    its current and its limit, and says what to check; then that nothing of the sweep could be
    fitted (rows left out: all saturated); then the step it leaves unfitted. Each reason once.
    Every other cycle without zeta2's frames: the share of complete cycles names zeta2."""
    path, rec = sweep
    config = load_config(path)
    keys = ("t", "cycle", "position", "velocity", "current", "statusword", "target", "valid")
    current = rec.current.copy()
    current[:, 4] = 71.0
    clipped = Recording(**{k: current if k == "current" else getattr(rec, k) for k in keys}, metadata=rec.metadata)
    reasons = identify(config, {"sweep": clipped}).quality.reasons
    n = len(rec.t)
    assert reasons == (
        f"sweep: currents at their drive's limit, clipped, not measured (rows left out): zeta2 in {n} of {n} rows, "
        "up to 71 A against its 8 A limit (beyond what the drive lets through: check the recording's current "
        "scaling and drive type)",
        f"sweep: no stretch of consecutive usable rows long enough to filter (rows left out: {n} saturated); "
        "nothing of it was fitted",
        "step carriages: not fitted (no stretch of its recordings could be filtered)")
    valid = rec.valid.copy()
    valid[::2, 4] = False
    lossy = Recording(**{k: getattr(rec, k) for k in ("t", "cycle", "velocity", "statusword", "target")},
                      position=np.where(valid, rec.position, np.nan), current=np.where(valid, rec.current, np.nan),
                      valid=valid, metadata=rec.metadata)
    reasons = identify(config, {"sweep": lossy}).quality.reasons
    assert reasons[0] == f"sweep: 50.0 % of the cycles complete (< 90 %); missing: zeta2 in {(n + 1) // 2} cycles"
    assert reasons[1].startswith("sweep: no stretch") and reasons[2].startswith("step carriages: not fitted")


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
    (reason,) = results.quality.reasons
    assert page.count(html.escape(reason)) == 1               # each reason once, with the verdict
    lines = summary_lines(folder)
    assert lines[0] == "status: degraded (the quality verdict's reasons below)"
    assert ("quality verdict: DEGRADED (identification.quality thresholds; noise floor: not judged "
            "(no standstill)):") in lines
    assert sum(reason in line for line in lines) == 1
    # the judged trajectory's figure against its limit, failed, where the thresholds are
    assert re.search(r"<td>sweep \(identification\)</td>.*<td class='partial'>[0-9.]+ / — \(fail\)</td>", page)


def test_each_prediction_is_called_what_it_is(sweep):
    """The step-by-step prediction is the mass-fit steps' parameters where a step fitted one
    (the sweep's), the CAD values' where none did (a results table with nothing fitted)."""
    path, rec = sweep
    assert identify(load_config(path), {"sweep": rec}).stepwise_label == "step by step"
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    assert _results_of(config.robot.actuators, []).stepwise_label == "CAD values"


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
                   actuator_kinds=tuple(a.kind for a in actuators), fits=tuple(fits))


def _residual_fit(name, rms_mA, per_amp, at_rest_mA=None, n=400):
    """A TrajectoryFit whose residual (measured minus base-fit forces) has RMS ``rms_mA`` (6,)
    on the rows the fits use, and ``at_rest_mA`` (6,) on the others (the first quarter of the rows,
    each axis at rest there: friction holding whatever the last motion left)."""
    from ident_hw.results import TrajectoryFit
    signs = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)[:, None]      # RMS of +-r is r
    moving = np.ones((n, 6), bool)
    residual = signs * np.asarray(rms_mA) * 1e-3 * per_amp
    if at_rest_mA is not None:
        moving[: n // 4] = False
        residual[: n // 4] = signs[: n // 4] * np.asarray(at_rest_mA) * 1e-3 * per_amp
    tau = np.full((n, 6), 100.0)               # forces large beside the residuals: d_tau well within its limit
    return TrajectoryFit(name=name, role="identification", t=np.arange(n) * 0.01, tau=tau + residual,
                         tau_model=tau, Theta=np.zeros((n, 6)), tau_base=tau, moving=moving)


def test_the_floor_judges_each_axis_on_its_fitted_rows_by_hand():
    """floor_figures: each axis's RMS residual in A over the rows the fits use, over its floor;
    the worst trajectory counts. Rows at rest (50 mA of held friction, which no rate-dependent
    friction model predicts and the fits leave out) do not count. Floors 1 mA (trajectory a) and
    2 mA (b); links 6.1, 1, 5.9 mA and carriages 1, 8, 1 mA on a, everything 1.5 mA on b. One
    reason names every axis beyond the limit of 5, with its figures, in the axes' own names."""
    from ident_hw.experiment.quality import floor_figures, floor_reason, thresholds_of
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    actuators, limits = config.robot.actuators, thresholds_of(config.identification.quality)
    assert limits.max_residual_over_floor == 5
    per_amp = np.array([axis_scaling(a).force_per_amp for a in actuators])
    held = np.full(6, 50.0)
    fits = [_residual_fit("a", [6.1, 1.0, 5.9, 1.0, 8.0, 1.0], per_amp, at_rest_mA=held),
            _residual_fit("b", np.full(6, 1.5), per_amp, at_rest_mA=held)]
    floors = {"a": np.full(6, 1e-3), "b": np.full(6, 2e-3)}
    figures = floor_figures(_results_of(actuators, fits), per_amp, floors)
    assert {n: f.ratio for n, f in figures.items()} == pytest.approx(
        {"theta1": 6.1, "theta2": 1.0, "theta3": 5.9, "zeta1": 1.0, "zeta2": 8.0, "zeta3": 1.0})
    assert {f.trajectory for n, f in figures.items()} == {"a"} and figures["zeta2"].residual == pytest.approx(8e-3)
    beyond = {n: f for n, f in figures.items() if f.ratio > 5}
    (reason,) = floor_reason(beyond, limits, {"theta1": ("theta2",), "zeta2": ("theta2", "zeta1")})
    assert reason.startswith("theta1, theta3, zeta2: residuals 6.1, 5.9, 8.0 times what noise alone leaves"), reason
    assert "zeta2 8 mA on a against 1 mA" in reason and reason.endswith(
        "of theta1, theta3, zeta2, and those of the axes sharing their parameters (theta2, zeta1)")
    assert floor_figures(_results_of(actuators, fits), per_amp, floors, judged=["zeta2"]).keys() == {"zeta2"}


def test_a_named_gain_is_the_cause_and_the_floor_excess_its_consequence():
    """The verdict with the evidence of a third link's torque constant 3 % off (its gain named,
    as :func:`axis_gains` finds it on the main job) and the first link above its floor (the fit
    spread the error there): one reason, naming theta3, with theta1's figure in it; every
    axis's figures, and the checks that fail on it."""
    from ident_hw.experiment.quality import AxisEvidence, thresholds_of, verdict
    from ident_hw.identification.axis_gain import AxisGain, AxisGains, NamedGain
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    actuators, limits = config.robot.actuators, thresholds_of(config.identification.quality)
    per_amp = np.array([axis_scaling(a).force_per_amp for a in actuators])
    fits = [_residual_fit("a", [5.5, 1.0, 2.0, 1.0, 1.0, 1.0], per_amp)]
    gains = AxisGains(gains={n: AxisGain(2.92 if n == "theta3" else 0.01, 0.04, 0.4 if n == "theta3" else 0.0)
                             for n in ("theta1", "theta2", "theta3", "zeta1", "zeta2", "zeta3")},
                      named=(NamedGain("theta3", 2.92, 0.04),))
    evidence = AxisEvidence(judged=("theta1", "theta2", "theta3", "zeta1", "zeta2", "zeta3"), gains=gains,
                            floors={"a": np.full(6, 1e-3)})
    q = verdict(_results_of(actuators, fits), limits, per_amp, evidence)
    (reason,) = q.reasons
    assert reason.startswith("theta3: forces +2.92 % (sigma 0.04 %) off the model, every fitted parameter refitted")
    assert reason.endswith("left above the noise floor with it: theta1 5.5 (a) times its noise floor"), reason
    assert q.axes["theta3"].failed == ("gain",) and q.axes["theta1"].failed == ("noise floor",)
    assert q.axes["theta2"].failed == () and q.axes["theta2"].gain_percent == 0.01
    assert q.axes["theta1"].residual_over_floor == pytest.approx(5.5) and q.not_judged == {}


def test_without_a_standstill_the_noise_floor_is_not_judged_and_says_so(sweep, tmp_path):
    """The sweep-only config has no standstill: its verdict passes on the gains, and says where the
    thresholds are (terminal, report, parameters.json) that the noise floor was not judged."""
    path, rec = sweep
    results = identify(load_config(path), {"sweep": rec})
    q = results.quality
    assert q.passed and q.not_judged == {"noise floor": "no standstill"}
    assert all(f.residual_over_floor is None and f.gain_percent is not None for f in q.axes.values())
    folder = tmp_path / "res"
    folder.mkdir()
    mark_status(folder, final_status(results))
    build_report(save_results(folder, results))
    doc = json.loads((folder / "parameters.json").read_text())
    assert doc["quality"]["not_judged"] == {"noise floor": "no standstill"}
    verdict_line = next(line for line in summary_lines(folder) if line.startswith("quality verdict"))
    assert verdict_line == ("quality verdict: passed (identification.quality thresholds; "
                            "noise floor: not judged (no standstill))")
    page = (folder / "report.html").read_text()
    thresholds = page[page.index("<h2>Quality</h2>"):]
    assert "<span class='partial'>noise floor: not judged (no standstill)</span>" in thresholds[:thresholds.index("<table")]
    # each carriage's gain, judged, in the table beside the floor's "not judged"
    assert re.search(r"<tr><td>zeta1</td><td>[-+][0-9.]+ ± [0-9.e-]+ ✓</td><td>not judged</td>", page), page


def test_force_lags_by_hand():
    """force_lags: measured forces that are the predicted ones T later (tau(t) = p(t - T)), on
    trajectories with a gap in their sample times, give back T per axis (to first order in
    omega T, and the central difference's (omega h)^2 / 6: both below 1e-3 here); a lag beyond
    max_force_lag fails the verdict, naming the axes."""
    from ident_hw.experiment.quality import force_lags, thresholds_of, verdict
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
    per_amp = np.array([axis_scaling(a).force_per_amp for a in actuators])
    q = verdict(results, thresholds_of(config.identification.quality), per_amp)
    (reason,) = [r for r in q.reasons if "lag" in r]
    named = re.findall(r"\) on (\w+)", reason)
    assert named == ["zeta1", "zeta2", "zeta3"], reason
    assert reason.startswith("the measured forces lag the model's by 2.00 ms (sigma "), reason
