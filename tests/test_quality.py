"""The quality verdict (issue: a wrong result is never marked good): its figures against values
computed here, its thresholds as config keys, and where it shows (STATUS, parameters.json, the
report, the terminal)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_cli import SWEEP_ONLY, synthetic_recordings

from drivers.recording import Recording
from ident_hw.config import ConfigError, load_config
from ident_hw.experiment.offline import identify
from ident_hw.experiment.quality import relative_difference
from ident_hw.report import build_report, summary_lines
from ident_hw.results import final_status, mark_status, save_results


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
    assert q["passed"] and q["reasons"] == [] and final_status(results) == "complete"
    row = q["trajectories"]["sweep"]
    assert row["coverage"] == 1.0 and row["valid_fraction"] == 1.0 and row["longest_gap_s"] == 0.0
    fit = results.fits[0]
    norm = np.linalg.norm(fit.tau, axis=1)
    by_hand = 100 * np.mean(np.linalg.norm(fit.tau - fit.tau_model, axis=1)[norm > 0] / norm[norm > 0])
    assert row["d_tau_percent"] == pytest.approx(by_hand, rel=1e-12) and by_hand < 10
    assert set(q["well_identified"]) >= {"m_c", "fv_zeta1", "fc_zeta1"}
    assert q["thresholds"]["max_d_tau"] == 10.0 and q["thresholds"]["min_valid_fraction"] == 0.9


def test_thresholds_are_config_keys(sweep, tmp_path):
    path, rec = sweep
    strict = with_quality(path, tmp_path, "{max_d_tau: 0.01, min_well_identified: 8}")
    q = identify(strict, {"sweep": rec}).quality
    assert not q["passed"] and len(q["reasons"]) == 2
    assert "d_tau" in q["reasons"][1] and "0.01 %" in q["reasons"][1]
    assert q["reasons"][0].startswith("7 of 7 fitted parameters well identified") and "at least 8" in q["reasons"][0]
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
                        current=np.where(valid, rec.current, np.nan), valid=valid, metadata=dict(rec.metadata))
    q = identify(config, {"sweep": damaged}).quality
    complete = valid.all(axis=1).mean()
    row = q["trajectories"]["sweep"]
    assert row["valid_fraction"] == pytest.approx(complete, abs=1e-12) and complete < 0.9
    # the longest stretch without a complete cycle: from the complete cycle before the hole to the one after
    before = max(i for i in range(200) if valid[i].all())
    after = min(i for i in range(230, len(valid)) if valid[i].all())
    assert row["longest_gap_s"] == pytest.approx((after - before - 1) * period, abs=1e-6)
    assert not q["passed"]
    assert any(r.startswith(f"sweep: {100 * complete:.1f} % of the cycles complete") for r in q["reasons"])
    assert any(r.startswith("sweep: 0.") and "without a complete cycle" in r for r in q["reasons"])


def test_a_frame_the_master_could_not_place_degrades_the_result(sweep):
    """A recording whose assembler met a frame it could not place (late beyond its look-ahead:
    some cells handed out before may hold another cycle's data) is not marked good, however
    clean its samples look."""
    path, rec = sweep
    meta = dict(rec.metadata, unplaced_frames=2)
    marked = Recording(**{k: getattr(rec, k) for k in ("t", "cycle", "position", "velocity", "current",
                                                       "statusword", "target", "valid")}, metadata=meta)
    q = identify(load_config(path), {"sweep": marked}).quality
    assert not q["passed"] and q["trajectories"]["sweep"]["unplaced_frames"] == 2
    assert q["reasons"] == ["sweep: 2 frame(s) could not be placed in their SYNC cycle (late by more than "
                            "the assembler's look-ahead, or sent twice)"]


def test_the_verdict_is_in_status_parameters_report_and_terminal(sweep, tmp_path):
    path, rec = sweep
    strict = with_quality(path, tmp_path, "{max_d_tau: 0.01}")
    results = identify(strict, {"sweep": rec})
    folder = tmp_path / "res"
    folder.mkdir()
    mark_status(folder, final_status(results))
    build_report(save_results(folder, results))
    status = (folder / "STATUS").read_text().strip()
    assert status == "degraded: " + results.quality["reasons"][0]
    doc = json.loads((folder / "parameters.json").read_text())
    assert doc["quality"]["passed"] is False and doc["quality"]["reasons"] == results.quality["reasons"]
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
                        valid=valid, metadata=dict(rec.metadata))
    results = identify(load_config(path), {"sweep": damaged})
    rows = {r.name: r for r in results.parameter_rows()}
    assert rows["fv_zeta3"].step == "" and rows["fc_zeta3"].step == ""          # held
    assert rows["m_c"].step == "carriages" and rows["fv_zeta1"].step == "carriages"
    assert any(r.startswith("step carriages: fv_zeta3, fc_zeta3 not excited") for r in results.quality["reasons"])
