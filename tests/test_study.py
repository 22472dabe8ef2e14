"""Monte-Carlo studies (``ident-hw study``): each run is a pure function of its config and seed,
wherever it runs (a Dask LocalCluster of two worker processes on loopback, or this process); run 0
is the config's own campaign; a study continues where it stopped; the summary's statistics."""

from __future__ import annotations

import json
import logging
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from ident_hw.config import load_config
from ident_hw.experiment.study import RunTask, StudyError, run_file, run_study, run_yaml
from ident_hw.results.study import Estimate, ParameterSummary, RunOutcome, Study, summarize
from ident_hw.storage import from_json, to_json
from ident_hw.report.study import study_lines, verdict_line, write_study_report
from ident_hw.config.to_drivers import encoder_edge_counts

ROOT = Path(__file__).resolve().parents[1]
SIM = ROOT / "configs" / "sim-3prrr.yaml"


def short_config(folder: Path) -> Path:
    """One 6 cm square at 100 Hz on the in-process rig, the links' masses fitted on it (a run
    takes seconds)."""
    path = folder / "short.yaml"
    path.write_text(
        f"extends: {SIM}\n"
        f"bus: {{interface: virtual, channel: study-{os.getpid()}-{time.monotonic_ns()}, sync_rate: 100.0}}\n"
        "trajectories:\n  - {name: square, kind: square, size: 0.06, cycles: 1, speed_scale: 0.6}\n"
        "identification:\n"
        "  steps: [{name: links, trajectories: [square], parameters: [m_l2, m_ee, I_l1]}]\n"
        "  validation: []\n")
    return path


def outcome(folder: Path, i: int) -> dict:
    return json.loads(run_file(folder, i).read_text())


@pytest.mark.slow
def test_runs_on_two_worker_processes_equal_the_same_runs_in_this_process(tmp_path):
    pytest.importorskip("distributed")
    config = short_config(tmp_path)
    here = run_study(config, tmp_path / "here", runs=3, workers=0)
    there = run_study(config, tmp_path / "there", runs=3, workers=2)
    assert len(here.outcomes) == len(there.outcomes) == 3 and not here.failed and not there.failed
    for i in range(3):
        a, b = outcome(tmp_path / "here", i), outcome(tmp_path / "there", i)
        assert a["seed"] == b["seed"] == 1 + i           # sim.seed of sim-3prrr.yaml is 1
        assert a["estimates"] == b["estimates"] and a["status"] == b["status"]
        assert {e["name"] for e in a["estimates"] if e["kind"] == "physical"} == {"m_l2", "m_ee", "I_l1"}
    # the seeds differ, and so do the estimates
    assert outcome(tmp_path / "here", 0)["estimates"] != outcome(tmp_path / "here", 1)["estimates"]


@pytest.mark.slow
def test_run_zero_is_the_configs_own_campaign_and_a_study_continues_where_it_stopped(tmp_path, caplog):
    config = short_config(tmp_path)
    folder = tmp_path / "study"
    run_study(config, folder, runs=2, workers=0)
    # `ident-hw run` of the same config: the values of run 0 (the config's seed)
    out = tmp_path / "run"
    done = subprocess.run([sys.executable, "-m", "ident_hw.cli", "run", str(config), "--quiet", "--no-report", "--out", str(out)],
                          capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode in (0, 6), done.stderr          # 6: degraded (the short square's verdict)
    rows = {r["name"]: r for r in json.loads((out / "parameters.json").read_text())["parameters"]}
    for e in outcome(folder, 0)["estimates"]:
        if e["kind"] == "physical":
            assert e["value"] == rows[e["name"]]["identified"] and e["sigma"] == rows[e["name"]]["sigma"]
    # a run that raised (its machine's fault, say) and one more asked: only those two run, the
    # finished one is kept as it was
    kept, redone = outcome(folder, 0), outcome(folder, 1)
    run_file(folder, 1).write_text(json.dumps(dict(redone, estimates=[], error="OSError: disk full")))
    with caplog.at_level(logging.INFO, logger="ident_hw"):
        study = run_study(config, folder, runs=3, workers=0)
    ran = [int(r.getMessage().split()[1]) for r in caplog.records if r.getMessage().startswith("run ")]
    assert sorted(ran) == [1, 2] and outcome(folder, 0) == kept and len(study.outcomes) == 3
    assert outcome(folder, 1)["estimates"] == redone["estimates"] and outcome(folder, 1)["error"] is None
    assert json.loads((folder / "study.json").read_text())["runs_finished"] == 3
    lines = study_lines(study)
    assert lines[0].startswith("study of short.yaml: 3 of 3 runs finished")
    assert any(line.split()[:2] == ["physical", "m_l2"] for line in lines)
    page = write_study_report(study).read_text()
    assert "m_l2" in page and (folder / "plots" / "error_vs_sigma.png").is_file()


@pytest.mark.slow
def test_a_run_that_raises_keeps_its_folder_and_says_where(tmp_path, monkeypatch):
    """Nothing recorded is lost: a run stopped by a drive's fault (an EMCY injected on the rig)
    keeps its folder on the worker, with what it recorded before the stop, and its error names the
    host and the folder; a run that finished leaves nothing behind. (The runs' temporary folders go
    to a folder of this test's own: other tests make theirs meanwhile.)"""
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    config = short_config(tmp_path)
    faulty = tmp_path / "faulty.yaml"
    faulty.write_text(f"extends: {config}\n"
                      "sim: {fault: {trajectory: square, after: 0.3, node_id: 5, code: 0x2310}}\n")
    study = run_study(faulty, tmp_path / "study", runs=1, workers=0)
    (failed,) = study.failed
    assert failed.error.startswith("CampaignStopped") and f"kept on {failed.host}: " in failed.error
    kept = Path(failed.error.rsplit(": ", 1)[1].rstrip(")"))
    assert list(scratch.iterdir()) == [kept]
    assert list(kept.rglob("data/square.npz")), sorted(p.name for p in kept.rglob("*"))
    run_study(config, tmp_path / "fine", runs=1, workers=0)
    assert list(scratch.iterdir()) == [kept]


def test_a_folder_of_another_configs_study_and_a_hardware_config_are_refused(tmp_path):
    config = short_config(tmp_path)
    folder = tmp_path / "study"
    (folder).mkdir()
    (folder / "config.yaml").write_text("robot: {}\n")
    with pytest.raises(StudyError, match="holds a study of another config"):
        run_study(config, folder, runs=1, workers=0)
    hardware = tmp_path / "hw.yaml"
    hardware.write_text(f"extends: {ROOT / 'configs' / 'hil-3prrr-epos4.yaml'}\n")
    with pytest.raises(StudyError, match=r"hw\.yaml: a study runs the simulated rig"):
        run_study(hardware, tmp_path / "hw-study", runs=1, workers=0)


def test_the_summary_against_statistics_computed_by_hand():
    """Five runs of two parameters with known errors and sigmas: the mean and the sample standard
    deviation of the error, the mean sigma, the coverage of +-1.96 sigma and the mean z, each
    computed here term by term."""
    truth = {"a": 2.0, "b": -1.0}
    errors = {"a": [0.1, -0.2, 0.05, 0.3, -0.05], "b": [0.01, 0.02, 0.03, -0.01, 0.5]}
    sigmas = {"a": [0.1, 0.1, 0.2, 0.1, 0.1], "b": [0.02, 0.02, 0.02, 0.02, 0.02]}
    claimed = {"a": [True, True, True, False, True], "b": [False, False, True, False, False]}
    outcomes = [RunOutcome(i, i, "complete", 1.0, "here", tuple(
        Estimate("physical", n, truth[n] + errors[n][i], sigmas[n][i], truth[n], claimed[n][i]) for n in truth)) for i in range(5)]
    summary = {s.name: s for s in summarize(outcomes)}
    for n in truth:
        e, s = errors[n], sigmas[n]
        mean = sum(e) / 5
        std = math.sqrt(sum((x - mean) ** 2 for x in e) / 4)
        inside = sum(1 for x, y in zip(e, s) if abs(x) <= 1.959963984540054 * y)
        got = summary[n]
        assert got.runs == 5 and got.truth == truth[n]
        assert got.mean_error == pytest.approx(mean, abs=1e-15) and got.std_error == pytest.approx(std, rel=1e-12)
        assert got.mean_sigma == pytest.approx(sum(s) / 5) and got.coverage == inside / 5
        assert got.mean_z == pytest.approx(sum(x / y for x, y in zip(e, s)) / 5)
        assert got.claimed_share == sum(claimed[n]) / 5
    # a: claimed by 4 of 5 runs; -0.2 (2 sigma) and 0.3 (3 sigma) fall outside: 3 of 5 inside
    assert summary["a"].claimed and summary["a"].coverage == 0.6 and not summary["a"].honest
    # b: claimed by one run only; the 0.5 error (25 sigma) is outside
    assert not summary["b"].claimed and summary["b"].coverage == 0.8
    assert np.isclose(summary["b"].bias_sigmas, np.mean(errors["b"]) / 0.02)


def test_a_sigma_of_few_draws_covers_with_students_t():
    """An error of 2.2 σ is outside the normal 95 % interval (1.96σ) but inside Student's t of 7
    degrees of freedom (2.36σ: a σ wholly from 8 encoder draws), and a run file keeps the
    degrees of freedom (None: infinite)."""
    normal = Estimate("base", "x", 1.22, 0.1, 1.0, True)
    few = Estimate("base", "x", 1.22, 0.1, 1.0, True, dof=7.0)
    assert not normal.covered and few.covered
    assert not Estimate("base", "x", 1.24, 0.1, 1.0, True, dof=7.0).covered
    outcome = RunOutcome(0, 0, "complete", 1.0, "here", (normal, few))
    assert from_json(RunOutcome, json.loads(json.dumps(to_json(outcome)))) == outcome
    assert summarize([outcome])[0].coverage == 0.5


def _summary(name: str, covered: int, runs: int, bias_sigmas: float = 0.0) -> ParameterSummary:
    """A claimed parameter of ``runs`` runs whose interval held the truth ``covered`` times."""
    return ParameterSummary(kind="base", name=name, truth=1.0, runs=runs, claimed_share=1.0,
                            mean_error=bias_sigmas * 0.01, std_error=0.01, mean_sigma=0.01,
                            coverage=covered / runs, mean_z=bias_sigmas)


def test_coverage_chance_is_the_binomial_tail_and_the_verdict_tells_chance_from_a_narrow_sigma(tmp_path):
    """``coverage_chance``: P(at most k of n intervals hold the truth) for intervals that hold it
    with probability 0.95, summed here term by term. With 30 claimed parameters the verdict calls a
    coverage within chance when that tail is at least 0.05 / 30 (and its mean error within 0.5 σ)."""
    def tail(k, n):
        return sum(math.comb(n, j) * 0.95 ** j * 0.05 ** (n - j) for j in range(k + 1))
    for covered, runs in ((35, 40), (34, 40), (32, 40), (40, 40), (105, 120)):
        assert _summary("p", covered, runs).coverage_chance == pytest.approx(tail(covered, runs), rel=1e-9)
    honest = [_summary(f"h{i}", 38, 40) for i in range(26)]
    study = Study(tmp_path, "x.yaml", 40, (), tuple(honest + [
        _summary("by chance", 34, 40),             # tail 0.0139 >= 0.05 / 30
        _summary("narrow", 32, 40),                # tail 0.00071 < 0.05 / 30
        _summary("biased", 35, 40, bias_sigmas=0.8),
        _summary("fine", 37, 40), _summary("fine too", 36, 40)]))
    line = verdict_line(study)
    assert line.startswith("3 of 31 claimed parameters have a σ that does not tell the truth")
    assert line.split(": ")[1].startswith("by chance, narrow, biased;")
    within = line.split("within chance for calibrated σs (P cover ≥ 0.05/31): ")[1]
    assert within == "by chance (85.0 % of 40 runs, P cover 0.014)"


def test_how_often_calibrated_sigmas_fail_the_bar_against_the_binomial_by_hand(tmp_path):
    """A study's bar is one test per claimed parameter. For independent parameters the chance that
    calibrated σs fail it somewhere is ``1 - (1 - p)^m``, ``p`` one parameter's chance: fewer than
    36 of 40 intervals holding the truth (binomial, summed by hand) or a mean z beyond 0.5 (normal
    tail); for parameters whose errors move together it is ``p``. The simulated figure matches
    both; a study's own figure comes from the correlation of its runs' z-scores."""
    from ident_hw.results.study import calibrated_failure_rate
    runs = 40
    coverage_tail = sum(math.comb(runs, j) * 0.95 ** j * 0.05 ** (runs - j) for j in range(36))
    bias_tail = math.erfc(0.5 * math.sqrt(runs) / math.sqrt(2.0))
    p = 1.0 - (1.0 - coverage_tail) * (1.0 - bias_tail)          # 0.0496
    assert calibrated_failure_rate(np.eye(31), runs) == pytest.approx(1.0 - (1.0 - p) ** 31, abs=0.03)
    assert calibrated_failure_rate(np.ones((5, 5)), runs) == pytest.approx(p, abs=0.012)
    assert calibrated_failure_rate(np.eye(31), 160) < 0.1 < calibrated_failure_rate(np.eye(31), 40)

    rng = np.random.default_rng(5)
    z = rng.standard_normal((40, 3))
    z[:, 1] = z[:, 0]                                              # two parameters that move together
    outcomes = tuple(RunOutcome(i, i, "complete", 1.0, "here", tuple(
        Estimate("base", f"p{j}", 1.0 + 0.01 * z[i, j], 0.01, 1.0, True) for j in range(3))) for i in range(40))
    study = Study(tmp_path, "x.yaml", 40, outcomes, summarize(outcomes))
    rate = study.chance_of_failing
    assert rate == pytest.approx(1.0 - (1.0 - p) ** 2, abs=0.02)
    assert f"in {100 * rate:.0f} % of 40-run studies" in verdict_line(study)


def test_every_run_but_the_first_draws_where_its_encoders_count(tmp_path):
    """Run 0 is the config's own campaign; the others draw their count edges from their seed (what
    differs between two homings of a rig), else every run would read the same rounded positions."""
    (tmp_path / "config.yaml").write_text(f"extends: {ROOT / 'configs' / 'sim-3prrr.yaml'}\n")
    edges = []
    for index in range(3):
        path = tmp_path / f"run{index}.yaml"
        path.write_text(run_yaml(RunTask(index, 1 + index, "")))
        edges.append(encoder_edge_counts(load_config(path).sim, 6))
    assert load_config(tmp_path / "run0.yaml").sim.seed == 1 and not edges[0].any()
    assert edges[1].all() and edges[2].all() and not (edges[1] == edges[2]).any()


def test_a_perturbed_truth_scales_each_body_as_a_whole_and_spreads_as_asked(tmp_path):
    """``sim.perturb`` (a study's --perturb): on the Delta every body's ten parameters share one
    factor (a realisable body stays realisable) and each drive term has its own; the same seed
    gives the same truth; over many seeds the log-factors of the 3PRRR's parameters have the
    asked spread and no bias; runs 1.. of a study get it, run 0 keeps the config's truth."""
    from delta_scenarios import smallest_pseudo_inertia_eigenvalue
    from ident_hw.config.robots import model_of, true_parameters
    from ident_hw.model.delta import PARAM_NAMES

    def truth(base: Path, seed: int, perturb: float) -> np.ndarray:
        path = tmp_path / f"{base.stem}-{seed}-{perturb}.yaml"
        path.write_text(f"extends: {base}\nsim: {{seed: {seed}, perturb: {perturb}}}\n")
        return true_parameters(load_config(path))

    delta = ROOT / "configs" / "sim-delta.yaml"
    nominal, drawn = truth(delta, 5, 0.0), truth(delta, 5, 0.1)
    assert np.array_equal(drawn, truth(delta, 5, 0.1)) and not np.array_equal(drawn, truth(delta, 6, 0.1))
    ratio = {}
    for name, a, b in zip(PARAM_NAMES, nominal, drawn):
        if a != 0:
            ratio.setdefault(name.split(".")[0] if "." in name else name, set()).add(round(b / a, 12))
        else:
            assert b == 0, name
    assert all(len(r) == 1 for r in ratio.values()), ratio          # one factor per body
    assert len({r.pop() for r in ratio.values()}) == len(ratio)      # and a different one for each
    for k in range(7):
        assert smallest_pseudo_inertia_eigenvalue(drawn[10 * k:10 * k + 10]) >= -1e-12, PARAM_NAMES[10 * k]

    sim = ROOT / "configs" / "sim-3prrr.yaml"
    names = model_of(load_config(sim).robot).parameter_names
    base = truth(sim, 0, 0.0)
    logs = np.array([np.log(truth(sim, seed, 0.05)[base > 0] / base[base > 0]) for seed in range(100)])
    assert logs.shape[1] == sum(base > 0) and len(names) == len(base)
    assert abs(logs.std() / 0.05 - 1) < 0.1 and abs(logs.mean()) < 0.05 * 3 / math.sqrt(logs.size)

    (tmp_path / "config.yaml").write_text(f"extends: {sim}\n")
    for index in (0, 1):
        path = tmp_path / f"run{index}.yaml"
        path.write_text(run_yaml(RunTask(index, 1 + index, "", perturb=0.05)))
        assert load_config(path).sim.perturb == (0.05 if index else 0.0)


def test_a_study_continued_with_another_perturbation_is_refused(tmp_path):
    config = short_config(tmp_path)
    folder = tmp_path / "study"
    folder.mkdir()
    from ident_hw.experiment.study import study_task_source
    loaded = load_config(config)
    (folder / "config.yaml").write_text(study_task_source(loaded.source, loaded.robot, loaded.trajectories).config_yaml)
    (folder / "study.json").write_text(json.dumps({"config": "short.yaml", "runs_asked": 2, "perturb": 0.05}))
    with pytest.raises(StudyError, match=r"holds a study with --perturb 0\.05, not 0\.0"):
        run_study(config, folder, runs=2, workers=0)


def test_a_study_s_runs_carry_the_files_the_config_reads(tmp_path):
    """A worker on another machine gets the config as text and the files it names: the Stewart's
    description and its excitation's sines, under the names the text gives them; the config
    written with them into an empty folder loads and names those copies."""
    from ident_hw.experiment.study import study_task_source
    config = load_config(Path(__file__).parents[1] / "configs" / "sim-stewart.yaml")
    task = study_task_source(config.source, config.robot, config.trajectories)
    given = dict(task.files)
    excitation = config.trajectory("excitation")
    assert excitation is not None and excitation.path is not None and config.robot.description is not None
    assert given == {"description/stewart.xml": Path(config.robot.description).read_bytes(),
                     "trajectories/excitation.json": Path(excitation.path).read_bytes()}
    for relative, data in task.files:
        (tmp_path / relative).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / relative).write_bytes(data)
    (tmp_path / "config.yaml").write_text(task.config_yaml)
    copy = load_config(tmp_path / "config.yaml")
    copied = copy.trajectory("excitation")
    assert copied is not None and Path(str(copied.path)) == tmp_path / "trajectories" / "excitation.json"
    assert Path(str(copy.robot.description)) == tmp_path / "description" / "stewart.xml"
