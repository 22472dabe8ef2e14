"""Results folder and report, built from synthetic results with known numbers."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import scipy.io
import yaml

from ident_hw.config import QualityConfig
from ident_hw.model import InertialParams, ThreePRRR
from ident_hw.records import (AxisFigures, BaseAnalysis, MassFitStep, RecordingCoverage, StepRecord, Thresholds,
                              TrajectoryVerdict, Verdict)
from ident_hw.report import build_report, summary_lines
from ident_hw.results import (BaseFit, OnlineTrace, ParameterTable, Results, TrajectoryFit, load_results, mark_status,
                              read_status, save_results, settling_time, tracked)
from ident_hw.storage import from_json, to_json

NAMES = InertialParams.NAMES


def synthetic_results(rng) -> Results:
    n = len(NAMES)
    truth = np.linspace(1.0, 2.0, n)
    identified = truth * (1 + 0.01 * np.arange(n) / n)
    sigma = np.full(n, np.nan)
    sigma[:7] = 0.001 * np.arange(1, 8)
    sigma[1] = 0.5  # 0.5 / 1.05... -> %sigma far above 10: flagged as poor
    table = ParameterTable(names=NAMES, units=tuple(ThreePRRR.parameter_unit(p) for p in NAMES), initial=truth * 1.3, identified=identified, sigma=sigma,
                           lower=np.zeros(n), upper=np.full(n, np.inf),
                           step=("carriages",) + ("links",) * 6 + ("",) * 12, method=("sqp",) * 7 + ("",) * 12,
                           truth=truth)
    fits = []
    for name, role in (("sweep", "identification"), ("triangle", "validation")):
        t = np.arange(500) / 250.0
        tau_model = np.column_stack([np.sin(t * (j + 1)) * (1 + 10 * (j >= 3)) for j in range(6)])
        tau = tau_model + 0.01 * rng.standard_normal(tau_model.shape)
        X = np.column_stack([0.1 * np.cos(t), 0.1 * np.sin(t), 0 * t])
        fits.append(TrajectoryFit(name, role, t, tau, tau_model, Theta=np.tile(t[:, None], (1, 6)), X=X,
                                  tau_base=tau_model * 1.1))
    online = OnlineTrace(names=NAMES, t=np.arange(100) * 0.01,
                         estimates={"SVD-DLS": np.outer(np.linspace(0.5, 1, 100), truth)})
    H = np.zeros((2, n))
    H[0, 0], H[1, [1, 2]] = 1.0, [-0.0225, 1.0]
    base_fit = BaseFit(step="fourier", method="WLS", trajectories=("fourier",),
                       expressions=("m_c", "-0.0225 m_l1 + I_l1"), H=H, coef=np.array([2.0, 0.5]),
                       sigma=np.array([0.02, 0.1]), initial=H @ (truth * 1.3), truth=H @ truth,
                       held=("fv_zeta1",), unexcited=(), threshold=10.0)
    return Results(parameters=table, actuators=ThreePRRR.actuator_names, actuator_kinds=ThreePRRR.actuator_kinds,
                   fits=tuple(fits), steps=(MassFitStep("carriages", ("sweep",), method="sqp", free=("m_c",)),),
                   base_analysis=BaseAnalysis(rank=18, n_params=19, base_parameters=("I_l1 + 0.0225 m_l1",),
                                              unexcited=("m_c",)), online=online, base_fit=base_fit)


def test_results_folder_round_trip_and_metrics(tmp_path):
    results = synthetic_results(np.random.default_rng(0))
    mark_status(tmp_path, "complete")
    page = build_report(save_results(tmp_path, results))
    assert page == tmp_path / "report.html"
    for name in ("parameters.json", "parameters.yaml", "metrics.yaml", "results.mat", "online.npz",
                 "plots/forces_sweep.png", "plots/residuals_triangle.png", "plots/motion_sweep.png",
                 "plots/online.png"):
        assert (tmp_path / name).is_file(), name
    assert (tmp_path / "plots/forces_sweep.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    back = load_results(tmp_path)
    np.testing.assert_array_equal(back.parameters.identified, results.parameters.identified)
    np.testing.assert_array_equal(back.parameters.truth, results.parameters.truth)
    np.testing.assert_array_equal(back.parameters.upper, results.parameters.upper)  # inf survives JSON null
    assert [f.name for f in back.fits] == ["sweep", "triangle"]
    np.testing.assert_array_equal(back.fits[1].tau, results.fits[1].tau)
    np.testing.assert_array_equal(back.online.estimates["SVD-DLS"], results.online.estimates["SVD-DLS"])
    assert back.online.change_time is None and back.online.diverged == {}
    assert back.steps == results.steps and back.base_analysis == results.base_analysis

    rows = json.loads((tmp_path / "parameters.json").read_text())["parameters"]
    assert rows[1]["rel_sigma_percent"] == pytest.approx(100 * 0.5 / results.parameters.identified[1])
    assert rows[0]["error_percent"] == pytest.approx(100 * (results.parameters.identified[0] - 1.0))

    # metrics recomputed here independently of the identification package
    m = yaml.safe_load((tmp_path / "metrics.yaml").read_text())["triangle"]
    fit = results.fits[1]
    err = fit.tau_model - fit.tau
    assert m["role"] == "validation"
    assert m["rms"]["zeta2"] == pytest.approx(np.sqrt(np.mean(err[:, 4] ** 2)))
    assert m["j_rmse"] == pytest.approx(np.sqrt(np.mean(np.sum(err**2, axis=1))))
    moving = np.linalg.norm(fit.tau, axis=1) > 0
    expected = 100 * np.mean(np.linalg.norm(err[moving], axis=1) / np.linalg.norm(fit.tau[moving], axis=1))
    assert m["d_tau_percent"] == pytest.approx(expected)

    mat = scipy.io.loadmat(tmp_path / "results.mat", simplify_cells=True)
    np.testing.assert_allclose(mat["identified"], results.parameters.identified)
    np.testing.assert_allclose(mat["fits"]["sweep"]["tau"], results.fits[0].tau)

    text = page.read_text()
    assert "Table 1" in text and "m_l1" in text and "Poorly identified" in text
    # one base form: with a base fit its table's expressions, not the analysis list's
    assert "-0.0225 m_l1 + I_l1" in text and "I_l1 + 0.0225 m_l1" not in text
    assert "plots/forces_triangle.png" in text
    # the poorly identified rows of both tables are marked in the row, not only in a note
    assert text.count("<tr class='poor'>") >= 1 and "poorly identified (%σ &gt; 10)" in text
    lines = summary_lines(tmp_path)
    head = next(line for line in lines if line.split()[:1] == ["parameter"])
    assert "error %" in head and "initial" in head
    m_c = next(line.split() for line in lines if line.split()[:1] == ["m_c"])
    # m_c: initial 1.3, identified 1.0, truth 1.0 (error +0.00 %), step carriages
    assert [float(v) for v in m_c[2:4]] == pytest.approx([1.3, 1.0]) and m_c[-1] == "carriages"


def test_base_fit_round_trip_table_and_metrics(tmp_path):
    results = synthetic_results(np.random.default_rng(2))
    mark_status(tmp_path, "complete")
    build_report(save_results(tmp_path, results))
    back = load_results(tmp_path).base_fit
    for key in ("H", "coef", "sigma", "initial", "truth"):
        np.testing.assert_array_equal(getattr(back, key), getattr(results.base_fit, key), err_msg=key)
    assert back.expressions == results.base_fit.expressions and back.held == ("fv_zeta1",)
    rows = json.loads((tmp_path / "parameters.json").read_text())["base_fit"]["rows"]
    # m_c: 2.0 +- 0.02 (1 %), truth H @ truth = 1.0 -> +100 %; second: 0.1 / 0.5 = 20 % > 10 %: poorly identified
    assert rows[0]["error_percent"] == pytest.approx(100.0) and rows[0]["well_identified"]
    assert rows[1]["rel_sigma_percent"] == pytest.approx(20.0) and not rows[1]["well_identified"]
    truth = results.parameters.truth
    assert rows[1]["truth"] == pytest.approx(truth[2] - 0.0225 * truth[1])

    lines = summary_lines(tmp_path)
    poor = next(line for line in lines if "I_l1" in line and "m_l1" in line)
    assert poor.endswith("poorly identified")
    assert any("held at known values during this fit: fv_zeta1" in line for line in lines)
    # the base fit's prediction is tau_model * 1.1: its metrics are recomputed here
    fit = results.fits[1]
    m = yaml.safe_load((tmp_path / "metrics.yaml").read_text())["triangle"]["base_fit"]
    assert m["rms"]["theta1"] == pytest.approx(np.sqrt(np.mean((fit.tau_base[:, 0] - fit.tau[:, 0]) ** 2)))
    triangle = next(line for line in lines if "triangle" in line)
    assert f"base fit d_tau = {m['d_tau_percent']:.2f} %" in triangle
    text = (tmp_path / "report.html").read_text()
    assert "Base parameters: WLS on fourier" in text and "poorly identified (%σ &gt; 10)" in text
    mat = scipy.io.loadmat(tmp_path / "results.mat", simplify_cells=True)
    np.testing.assert_allclose(mat["base_fit"]["identified"], [2.0, 0.5])


def test_report_rebuilds_from_the_folder_alone(tmp_path):
    build_report(save_results(tmp_path, synthetic_results(np.random.default_rng(1))))
    mark_status(tmp_path, "partial: interrupted (SIGINT)")
    metrics_before = (tmp_path / "metrics.yaml").read_text()
    for built in ("report.html", "metrics.yaml", "results.mat"):
        (tmp_path / built).unlink()
    for png in (tmp_path / "plots").glob("*.png"):
        png.unlink()
    build_report(tmp_path)
    assert (tmp_path / "metrics.yaml").read_text() == metrics_before
    assert "partial: interrupted (SIGINT)" in (tmp_path / "report.html").read_text()
    assert read_status(tmp_path) == "partial: interrupted (SIGINT)"
    assert len(list((tmp_path / "plots").glob("*.png"))) == 7


def test_not_a_results_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match="no parameters.json"):
        build_report(tmp_path)


def test_online_settling_time_and_diverged_estimator_by_hand():
    """A base parameter stepping from 1 to 2 at t = 1 s, an estimate approaching it as
    2 (1 − 0.5 e^{−(t−1)/τ}): within 2 % from t − 1 = τ ln 25; a NaN estimate (diverged) never
    counts as settled."""
    t = np.arange(0, 10, 0.01)
    names = ("a", "b")
    H = np.eye(2)
    truth = np.column_stack([np.where(t >= 1.0, 2.0, 1.0), np.ones_like(t)])
    tau = 0.8
    good = np.column_stack([np.where(t >= 1.0, 2 * (1 - 0.5 * np.exp(-(t - 1.0) / tau)), 1.0), np.ones_like(t)])
    bad = good.copy()
    bad[t > 5.0] = np.nan
    trace = OnlineTrace(names, t, {"SVD-DLS": good, "RLS": bad}, H=H, base_names=names, truth=truth,
                        change_time=1.0, diverged={"RLS": 5.0})
    assert tracked(trace) == [0]
    assert settling_time(trace, "SVD-DLS", 0) == pytest.approx(tau * np.log(25), abs=0.011)
    assert settling_time(trace, "RLS", 0) is None


#: the JSON of each record, as parameters.json holds it (key order included)
RECORDS = [
    (StepRecord, {"name": "carriages", "trajectories": ["sweep"], "method": "SQP", "free": ["m_c"],
                  "parameters": {"m_c": 2.0, "m_l1": 0.5}, "parameters_lsq_linear": {"m_c": 2.0, "m_l1": 0.5},
                  "max_rel_difference": 1e-9, "cost": 1.5, "residual_rms": [0.1], "output_std": [0.2],
                  "iterations": 7, "success": True, "message": "Optimization terminated successfully",
                  "at_bounds": [], "rows_left_out": {"sweep": {"incomplete": 3}}, "cond_scaled": 12.0, "unexcited": ["fv_zeta3"],
                  "encoder_draws": 4, "encoder_sigma": [0.1], "held_sigma": [0.05], "cond_W": 20.0}),
    (StepRecord, {"name": "links", "trajectories": ["square1"], "method": "SQP", "free": ["m_l2"],
                  "parameters": {"m_l2": 0.0}, "parameters_lsq_linear": {"m_l2": 0.0}, "max_rel_difference": 0.0,
                  "cost": 3.0, "residual_rms": [0.1, 0.2], "output_std": [0.2, 0.2], "iterations": 1, "success": False,
                  "message": "Singular matrix", "at_bounds": ["m_l2"], "rows_left_out": {}, "cond_scaled": 1e9, "statistics": "rank deficient"}),
    (StepRecord, {"name": "base", "trajectories": ["excitation"], "free": ["m_c", "m_l1"], "method": "WLS",
                  "eliminated": ["m_l1"], "sigma2": 2.0, "cond": 4.0, "covariance": "Newey-West HAC, 3 lags",
                  "residual_rms": [0.1], "output_std": None, "poorly_identified": ["m_c"], "cond_scaled": 3.0,
                  "consistent": "no body fits"}),
    (StepRecord, {"name": "empty", "trajectories": ["sweep"], "skipped": "no stretch of its recordings"}),
    (BaseAnalysis, {"rank": 1, "n_params": 2, "rtol": 1e-8, "singular_values": [2.0, 0.0],
                    "base_parameters": ["m_c"], "eliminated": ["m_l1"], "unexcited": ["m_l1"]}),
    (RecordingCoverage, {"file": "sweep.npz", "recording_status": "complete", "cycles": 10, "cycles_planned": 12,
                         "coverage": 10 / 12, "valid_fraction": 0.9, "longest_gap_s": 0.004, "skipped_slots": 1,
                         "unplaced_frames": 0, "samples_used": 5, "rows_left_out": {"edges": 2}, "gaps": 1,
                         "stretches": 2}),
    (RecordingCoverage, {"file": None, "recording_status": "complete", "cycles": 10, "cycles_planned": 10,
                         "coverage": 1.0, "valid_fraction": 0.8, "longest_gap_s": 0.0, "skipped_slots": 0,
                         "unplaced_frames": 0, "samples_used": 0, "rows_left_out": {"saturated": 8}, "gaps": 0,
                         "stretches": 0, "shortfalls": {"zeta2": {"missing": 2, "saturated": 8, "peak_A": 71.0,
                                                                   "limit_A": 8.0}}}),
    (Verdict, {"passed": False, "reasons": ["why"], "thresholds": dataclasses.asdict(Thresholds(max_d_tau=5.0)),
               "trajectories": {"sweep": {"recording_status": "complete", "coverage": 1.0, "valid_fraction": 1.0,
                                          "longest_gap_s": 0.0, "unplaced_frames": 0, "role": "identification",
                                          "d_tau_percent": 2.0},
                                "triangle": {"role": "validation", "d_tau_percent": 1.0,
                                             "base_fit_d_tau_percent": 1.1, "disagreement_percent": 0.1}},
               "steps": {"carriages": {"cond_scaled": 12.0}}, "well_identified": ["m_c"],
               "axes": {"zeta1": {"gain_percent": 0.1, "gain_sigma_percent": 0.01, "residual_over_floor": 1.2,
                                  "floor_trajectory": "sweep", "residual_A": 0.0012, "floor_A": 0.001,
                                  "force_lag_s": 1e-4, "force_lag_sigma_s": 1e-5, "failed": ["noise floor"]},
                        "zeta2": {"force_lag_s": 2e-4, "force_lag_sigma_s": 1e-5, "failed": []}},
               "axes_judged": ["zeta1", "zeta2"], "not_judged": {"noise floor": "no standstill"}}),
    (Verdict, {"passed": True, "reasons": [], "thresholds": dataclasses.asdict(Thresholds()), "trajectories": {},
               "steps": {"gains": {"cond_scaled": None}}, "well_identified": [], "axes": {}, "axes_judged": [],
               "notes": ["a lag noted"]}),
]


@pytest.mark.parametrize("record, doc", RECORDS, ids=[f"{r.__name__}-{i}" for i, (r, _) in enumerate(RECORDS)])
def test_each_record_reads_and_writes_its_json_unchanged(record, doc):
    """parameters.json keeps its keys, values and their order through the typed records."""
    back = to_json(from_json(record, doc))
    assert json.dumps(back) == json.dumps(doc)


def test_the_verdict_stores_the_config_thresholds_under_its_own_names():
    """The results format holds its own copy of the limits (a renamed config key must be mapped
    in ident_hw.experiment.quality.thresholds_of, not change the files): same names and defaults
    today, and every limit of the config mapped."""
    from ident_hw.experiment.quality import thresholds_of
    assert dataclasses.asdict(Thresholds()) == dataclasses.asdict(QualityConfig())
    given = QualityConfig(**{f.name: 0.5 + i for i, f in enumerate(dataclasses.fields(QualityConfig))
                             if f.type in ("float", float)})
    assert dataclasses.asdict(thresholds_of(given)) == dataclasses.asdict(given)


def test_records_read_folders_written_before_a_key_existed():
    """A verdict and a coverage without the keys added later read as None or empty."""
    verdict = from_json(Verdict, {"passed": True, "reasons": [], "thresholds": {}, "trajectories": {
        "sweep": {"recording_status": "complete", "coverage": None, "valid_fraction": 1.0, "longest_gap_s": 0.0}},
        "steps": {}, "well_identified": []})
    assert verdict.passed and verdict.axes == {} and verdict.not_judged == {}
    assert verdict.trajectories["sweep"] == TrajectoryVerdict(recording_status="complete", valid_fraction=1.0,
                                                               longest_gap_s=0.0)
    assert verdict.trajectories["sweep"].recorded
    assert verdict.thresholds is None
    # a folder of before the per-axis records: its lags and floor ratios read into them; the keys
    # of retired checks (gain spread, residual ratio against the same drives) are dropped
    flat = from_json(Verdict, {"passed": True, "axis_gain_spread_percent": {"zeta1": 0.1},
                              "axis_residual_ratio": {"zeta1": 1.2}, "axis_residual_over_floor": {"zeta1": 2.0},
                              "force_lag_s": {"zeta1": 1e-4}, "force_lag_sigma_s": {"zeta1": 1e-5},
                              "thresholds": {"max_axis_gain_spread": 2.0, "max_d_tau": 5.0}})
    assert flat.axes == {"zeta1": AxisFigures(residual_over_floor=2.0, force_lag_s=1e-4, force_lag_sigma_s=1e-5)}
    assert flat.thresholds == Thresholds(max_d_tau=5.0)
    older = from_json(Verdict, {"passed": True, "thresholds": {"max_d_tau": 5.0, "min_coverage": 1.0}})
    assert older.thresholds == Thresholds(max_d_tau=5.0)
    used = from_json(RecordingCoverage, {"file": None, "recording_status": "complete", "cycles": 5,
                                        "cycles_planned": None, "coverage": None, "valid_fraction": 1.0,
                                        "longest_gap_s": 0.0})
    assert not used.prepared and used.skipped_slots == 0 and used.unplaced_frames is None
