"""The main job end to end: the paper's campaign on the simulated rig (``configs/sim-3prrr.yaml``,
250 Hz lockstep), identified values against the simulated truth, and the same check failing on a
deliberately wrong identification (currents 5 % off: a torque constant 5 % wrong).

The truth here comes from the config, and a base parameter's truth from its readable expression
(``m_c - 0.5 m_l2``) evaluated on the config's values: neither from the code's own truth column.
Bound per parameter: ``3 σ`` (its own standard deviation) plus a bias budget of
:data:`BIAS_BUDGET` of its value: the set-point quantisation of the links at 250 Hz (1 count per
period, 7.4 rad/s² of acceleration noise) and the plant's integration leave biases of up to
about 1 % that σ does not cover.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
import re
import shutil
import warnings
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
from scipy import stats
import pytest

from drivers.recording import Recording, sidecar_path
from ident_hw.config import load_config, to_model
from ident_hw.experiment import runner
from ident_hw.experiment.campaign_estimator import CampaignEstimator
from ident_hw.experiment.offline import identify
from ident_hw.experiment.session import HostSettings
from ident_hw.experiment.folders import new_results_folder
from ident_hw.model.described import DescribedRobot, MasslessBodyWarning
from ident_hw.model.parameters import ACTUATOR_NAMES, FRICTION_NAMES, INERTIAL_NAMES, InertialParams
from ident_hw.results import save_results, settling_time, tracked
import described_hand as dh
import nominal
from cli_runs import ident_hw
from ident_scenarios import CONFIGS, SWEEP_CAMPAIGN, without_draws
from ident_hw.config.to_drivers import axis_config

#: bias allowed beyond 3 sigma, as a fraction of the true value
BIAS_BUDGET = 0.01
#: the campaign identifies at least this many parameters well (physical step by step and base)
MIN_WELL_IDENTIFIED = 25


def evaluate(expression: str, values: dict[str, float]) -> float:
    """Value of a readable base parameter such as ``m_c - 0.5 m_l2`` or ``0.0216 m_l2 + I_ee``."""
    total = 0.0
    parts = re.split(r"\s+([+-])\s+", expression.strip())       # term, sign, term, sign, ...
    for sign, term in zip(["+"] + parts[1::2], parts[0::2]):
        words = term.split()
        factor = float(words[0]) if len(words) == 2 else (-1.0 if words[0].startswith("-") else 1.0)
        name = words[-1].lstrip("-")
        total += (-factor if sign == "-" else factor) * values[name]
    return total


def accuracy_failures(doc: dict, truth: dict[str, float]) -> list[str]:
    """The well-identified parameters of a ``parameters.json`` farther from the truth than
    ``3 σ + BIAS_BUDGET × |truth|``, and too few well-identified ones."""
    threshold = doc["rel_sigma_threshold_percent"]
    failures, well = [], 0
    rows = [(r["name"], r["identified"], r["sigma"], r["rel_sigma_percent"], truth[r["name"]])
            for r in doc["parameters"] if r["step"]]
    rows += [(r["base_parameter"], r["identified"], r["sigma"], r["rel_sigma_percent"],
              evaluate(r["base_parameter"], truth)) for r in doc["base_fit"]["rows"]]
    for name, value, sigma, rel, true in rows:
        if rel is None or rel > threshold:
            continue
        well += 1
        if abs(value - true) > 3 * sigma + BIAS_BUDGET * abs(true):
            failures.append(f"{name}: {value:.6g} against {true:.6g} ({100 * (value / true - 1):+.2f} %, "
                            f"sigma {sigma:.3g})")
    if well < MIN_WELL_IDENTIFIED:
        failures.append(f"{well} well identified (< {MIN_WELL_IDENTIFIED})")
    return failures


class _Cells(HTMLParser):
    """The text of every table cell of an HTML page, row by row."""

    def __init__(self):
        super().__init__()
        self.rows, self._row, self._cell = [], None, None

    def handle_starttag(self, tag, attrs):
        if tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell = ""

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._row is not None and self._cell is not None:
            self._row.append(self._cell.strip())
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.rows.append(self._row)
            self._row = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data


@pytest.fixture(scope="module")
def main_job(tmp_path_factory):
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    folder = new_results_folder(config, tmp_path_factory.mktemp("main") / "res", "run")
    runner.run_campaign(config, folder,
                                host=HostSettings.for_command(config))
    return config, folder


def test_the_main_job_identifies_the_simulated_truth(main_job):
    config, folder = main_job
    truth = dict(zip(to_model.inertial_params(config.sim.truth).NAMES, to_model.inertial_params(config.sim.truth).as_vector()))
    doc = json.loads((folder / "parameters.json").read_text())
    assert accuracy_failures(doc, truth) == []
    assert doc["quality"]["passed"] and (folder / "STATUS").read_text().startswith("complete")
    for name, used in doc["trajectories"].items():
        assert used["valid_fraction"] == 1.0 and used["cycles"] == used["cycles_planned"], name
    # each mass fit's estimates carry the shift of their held values, a part of their sigma
    sigma = {row["name"]: row["sigma"] for row in doc["parameters"]}
    mass_fits = [step for step in doc["steps"] if "eliminated" not in step and "skipped" not in step]
    assert [step["name"] for step in mass_fits] == ["carriages", "links", "platform"]
    for step in mass_fits:
        assert len(step["held_sigma"]) == len(step["free"]), step["name"]
        assert all(0.0 <= h <= sigma[p] for p, h in zip(step["free"], step["held_sigma"])), step["name"]
    assert dict(zip(mass_fits[0]["free"], mass_fits[0]["held_sigma"]))["m_c"] > 0.0



def test_the_main_job_s_robot_exports_to_a_file_pinocchio_and_mujoco_load(main_job, tmp_path):
    """``ident-hw export`` of the main job (the 3PRRR identified on its hand model): the written
    MJCF, read by pinocchio as a new robot (no massless body), has the torques of the nominal hand
    model (``tests/nominal.py``) with the consistent parameters, on states about home; MuJoCo loads it."""
    _, folder = main_job
    exported = tmp_path / "3prrr-identified.xml"
    values = dh.export_for_mujoco(folder, exported)
    pi = np.array([values[name] for name in InertialParams.NAMES])
    hand = nominal.ROBOT
    X0 = np.zeros((1, 3))
    theta, beta = hand.inverse_kinematics(X0, X0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MasslessBodyWarning)
        robot = DescribedRobot(exported, ACTUATOR_NAMES, home=dict(zip(dh.PRRR_JOINTS, dh.prrr_tree(X0, theta, beta, X0)[0])),
                               coulomb_width=hand.coulomb_width)
    rng = np.random.default_rng(5)
    Theta = hand.home_actuated() + np.concatenate([rng.uniform(-0.05, 0.05, (8, 3)), rng.uniform(-0.03, 0.03, (8, 3))], 1)
    Thetad, Thetadd = rng.normal(0, 0.3, (8, 6)), rng.normal(0, 3.0, (8, 6))
    motion = hand.motion_from_actuated(Theta, Thetad, Thetadd, np.zeros((8, 3)))
    guess = dh.prrr_tree(motion.X, motion.theta, motion.beta, motion.zeta)
    dh.torques_agree(robot.identification_regressor(Theta, Thetad, Thetadd, guess)[0] @ robot.nominal_parameters(),
                     hand.regressor_of(motion) @ pi)
    dh.mujoco_loads(exported, len(robot.body_names))


def test_the_main_job_gives_physical_link_masses_and_inertias_that_keep_the_base_parameters(main_job):
    """The consistent step after the base fit: every mass and inertia of the 3PRRR non-negative
    (its planar bodies have their centres of mass where the geometry puts them), friction
    non-negative, each parameter marked data- or prior-decided, and every identified base
    parameter given back (within a tenth of its σ) by its readable combination of them."""
    _, folder = main_job
    doc = json.loads((folder / "parameters.json").read_text())
    consistent = doc["consistent"]
    values = {p["name"]: p["value"] for p in consistent["parameters"]}
    assert set(values) == set(INERTIAL_NAMES + FRICTION_NAMES)
    assert all(value >= 0 for value in values.values())
    assert {p["decided_by"] for p in consistent["parameters"]} <= {"data", "prior", "data and prior"}
    for row in doc["base_fit"]["rows"]:
        implied = evaluate(row["base_parameter"], values)
        assert abs(implied - row["identified"]) <= 0.1 * row["sigma"], row["base_parameter"]
    assert consistent["physical"] and consistent["reproduces_base"]


def test_a_torque_constant_5_percent_wrong_fails_the_accuracy_check(main_job, tmp_path):
    """The run's recordings with every current 5 % high (what a torque constant 5 % low in the
    drive data gives): the masses and frictions come out 5 % high, with the same small σ."""
    config, folder = main_job
    truth = dict(zip(to_model.inertial_params(config.sim.truth).NAMES, to_model.inertial_params(config.sim.truth).as_vector()))
    recordings = {}
    for path in sorted((folder / "data").glob("*.npz")):
        rec = Recording.load(path)
        recordings[path.stem] = Recording(**{k: getattr(rec, k) for k in (
            "t", "cycle", "position", "velocity", "statusword", "target", "valid")},
            current=rec.current * 1.05, metadata=rec.metadata)
    save_results(tmp_path / "wrong", identify(config, recordings))
    doc = json.loads((tmp_path / "wrong" / "parameters.json").read_text())
    failures = accuracy_failures(doc, truth)
    assert len(failures) >= 10 and any(f.startswith("m_c") for f in failures), failures


def with_torque_constant(config, axis: str, factor: float):
    """``config`` with ``axis``'s torque constant times ``factor`` (the rig unchanged)."""
    actuators = tuple(dataclasses.replace(a, torque_constant=a.torque_constant * factor) if a.name == axis else a
                      for a in config.robot.actuators)
    return dataclasses.replace(config, robot=dataclasses.replace(config.robot, actuators=actuators))


def named_axes(quality, config) -> set[str]:
    """The actuators the reasons of a verdict start with (``theta3: ...``)."""
    return {reason.split(":")[0] for reason in quality.reasons} & {a.name for a in config.robot.actuators}


@pytest.mark.parametrize("axis", ["theta1", "theta2", "theta3", "zeta1", "zeta2", "zeta3"])
@pytest.mark.parametrize("factor", [1.03, 0.97])
def test_one_torque_constant_3_percent_wrong_in_the_config_fails_the_verdict_naming_it(main_job, axis, factor):
    """The run's recordings identified with one actuator's torque constant 3 % off in the config
    (the rig unchanged): the quality verdict fails and names that actuator, and only it, by its
    gain against its own model refitted (without the encoder draws: no noise floor, the gain
    alone); the gain it reports is the 3 % to within a tenth of it (a first-order refit)."""
    config, folder = main_job
    wrong = without_draws(with_torque_constant(config, axis, factor))
    recordings = {path.stem: Recording.load(path) for path in sorted((folder / "data").glob("*.npz"))}
    quality = identify(wrong, recordings).quality
    assert not quality.passed and named_axes(quality, config) == {axis}, quality.reasons
    assert quality.axes[axis].failed == ("gain",)
    # a force per ampere 3 % high makes the measured forces 3 % high
    assert quality.axes[axis].gain_percent == pytest.approx(100 * (factor - 1), rel=0.1)


def test_a_torque_constant_off_on_one_link_is_named_once_with_what_it_spreads(main_job):
    """theta3's torque constant 3 % low, identified as the run does (encoder draws, noise floor):
    the fit spreads its error over the links sharing its parameters, leaving theta1 above its
    noise floor, but the verdict's one reason names theta3 (its gain) and gives theta1's figure
    as what follows from it."""
    config, folder = main_job
    recordings = {path.stem: Recording.load(path) for path in sorted((folder / "data").glob("*.npz"))}
    quality = identify(with_torque_constant(config, "theta3", 0.97), recordings).quality
    (reason,) = quality.reasons
    assert reason.startswith("theta3: forces -3.") and "left above the noise floor with it: theta1" in reason, reason
    assert quality.axes["theta3"].failed == ("gain",) and quality.axes["theta1"].failed == ("noise floor",)


def test_unequal_current_noise_per_axis_still_passes(main_job):
    """The run's recordings with more current noise on some drives than others (the standstill
    included, as a real rig's drives differ): 0, 4, 1, 0, 3 and 0 mA more, Gaussian, reported in
    whole mA as the drives do. Each axis is judged against its own noise floor and its own model,
    so the verdict passes, every axis within its limits."""
    config, folder = main_job
    extra = np.array([0.0, 4e-3, 1e-3, 0.0, 3e-3, 0.0])
    rng = np.random.default_rng(47)
    recordings = {}
    for path in sorted((folder / "data").glob("*.npz")):
        rec = Recording.load(path)
        noisy = np.round((rec.current + extra * rng.normal(size=rec.current.shape)) * 1e3) * 1e-3
        recordings[path.stem] = Recording(**{k: getattr(rec, k) for k in (
            "t", "cycle", "position", "velocity", "statusword", "target", "valid")}, current=noisy,
            metadata=rec.metadata)
    quality = identify(config, recordings).quality
    assert quality.passed, quality.reasons
    limits = quality.thresholds
    assert all(abs(f.gain_percent) <= limits.max_axis_gain and f.residual_over_floor <= limits.max_residual_over_floor
               for f in quality.axes.values()), quality.axes


@pytest.mark.slow
@pytest.mark.parametrize("truth", ["f_c: [0.05, 0.10, 0.05, 5.0, 5.0, 5.0]",
                                   "f_v: [0.02, 0.02, 0.02, 80.0, 40.0, 40.0]"],
                         ids=["theta2-coulomb-doubled", "zeta1-viscous-doubled"])
def test_the_main_job_with_one_axis_s_friction_doubled_passes(tmp_path, truth):
    """The main job on a rig whose second link has twice the Coulomb friction of the others (or
    whose first carriage has twice the viscous friction): a correct model of an unequal robot.
    Each axis is judged against its own model (its own friction identified) and its own noise
    floor, so the verdict passes, and every axis stays within its limits."""
    path = tmp_path / "unequal.yaml"
    path.write_text(f"extends: {CONFIGS / 'sim-3prrr.yaml'}\nsim:\n  truth:\n    {truth}\n")
    config = load_config(path)
    folder = new_results_folder(config, tmp_path / "res", "run")
    results = runner.run_campaign(config, folder, host=HostSettings.for_command(config),
                                  report=False)
    quality = results.quality
    assert quality.passed and (folder / "STATUS").read_text().strip() == "complete", quality.reasons
    limits = quality.thresholds
    for name, f in quality.axes.items():
        assert abs(f.gain_percent) <= limits.max_axis_gain and f.residual_over_floor <= limits.max_residual_over_floor, \
            (name, f)


def test_identify_on_a_finished_run_s_folder_gives_its_parameters(main_job, tmp_path):
    """``ident-hw identify CONFIG RESULTS_FOLDER``: the recordings of the run's data/ (each
    trajectory's .npz, its raw log, sidecar and drives.json left), identified as the run did:
    the same parameters.json, key for key, but where each recording came from (``file``: the
    run identified them from memory, identify from the folder's files). The same with the
    folder's own config.yaml, and from the files of data/ by a shell glob (drives.json and the
    raw logs' sidecars skipped, and said). An identify folder keeps no recordings: refused."""
    config, folder = main_job
    run = json.loads((folder / "parameters.json").read_text())
    for config_path in (CONFIGS / "sim-3prrr.yaml", folder / "config.yaml"):
        out = tmp_path / f"identify-{config_path.parent.name}"
        done = ident_hw("identify", config_path, folder, "--out", out, "--no-report", "--quiet")
        assert done.returncode == 0, done.stderr
        assert f"the recordings in {folder / 'data'}: excitation.npz, square1.npz" in done.stderr
        again = json.loads((out / "parameters.json").read_text())
        files = {name: used.pop("file") for name, used in again["trajectories"].items()}
        assert files == {name: str(folder / "data" / f"{name}.npz") for name in files}
        assert all(used.pop("file") is None for used in run["trajectories"].values())
        assert again == run
        run = json.loads((folder / "parameters.json").read_text())
    globbed = ident_hw("identify", CONFIGS / "sim-3prrr.yaml", *sorted((folder / "data").glob("*.npz")),
                       folder / "data" / "drives.json", folder / "data" / "triangle.log.json",
                       "--out", tmp_path / "globbed", "--no-report", "--quiet")
    assert globbed.returncode == 0 and "skipped, not recordings: " in globbed.stderr
    assert json.loads((tmp_path / "globbed" / "parameters.json").read_text())["quality"] == run["quality"]
    refused = ident_hw("identify", CONFIGS / "sim-3prrr.yaml", tmp_path / "globbed", "--out", tmp_path / "none")
    assert refused.returncode == 5 and "no recordings in" in refused.stderr and not (tmp_path / "none").exists()


def test_the_report_shows_the_numbers_of_parameters_json(main_job):
    """Every identified value in ``report.html``'s parameter table equals ``parameters.json``'s to
    the digits shown, and so does its error in units of its sigma."""
    _, folder = main_job
    doc = json.loads((folder / "parameters.json").read_text())
    cells = _Cells()
    cells.feed((folder / "report.html").read_text())
    by_name = {r["name"]: r for r in doc["parameters"]}
    header = next(row for row in cells.rows if row and row[0] == "parameter")
    z_column, interval_column = header.index("error / σ"), header.index("95 % ±")
    widened = []
    shown = {}
    for row in cells.rows:           # the first table naming them: the physical parameters
        if row and row[0] in by_name and len(row) > 3:
            shown.setdefault(row[0], row)
    assert set(shown) == set(by_name)
    for name, row in shown.items():
        r = by_name[name]
        if not r["step"]:
            assert row[3] == "(held)"
            continue
        value = float(row[3])
        digits = len(row[3].replace("-", "").replace(".", "").lstrip("0")) or 1
        assert value == pytest.approx(r["identified"], rel=10 ** (1 - digits)), (name, row[3], r["identified"])
        # the error in units of its own sigma, from parameters.json's numbers
        z = (r["identified"] - r["truth"]) / r["sigma"]
        assert float(row[z_column]) == pytest.approx(z, abs=0.0051), (name, row[z_column], z)
        # the 95 % interval: Student's t of the Welch-Satterthwaite degrees of freedom of a sigma
        # whose encoder part is the spread of the step's draws (the rest exact)
        step = next(s for s in doc["steps"] if s["name"] == r["step"])
        part = step["encoder_sigma"][step["free"].index(name)]
        dof = r["sigma"] ** 4 * (step["encoder_draws"] - 1) / part ** 4
        half = stats.t.ppf(0.975, dof) * r["sigma"]
        assert float(row[interval_column]) == pytest.approx(half, rel=0.01), (name, row[interval_column], half)
        widened.append(half / r["sigma"])
    assert max(widened) > 2.0 and min(widened) < 1.97     # a σ mostly of draws, one mostly of least squares


@pytest.mark.slow
def test_an_epos2_rig_identifies_the_carriages(tmp_path):
    """The same rig on EPOS2 drives (16-bit current, position mode -1 with set-points in 0x2062,
    homing method 35), through ``run``: the paper's carriage sweep at 250 Hz identifies ``m_c``
    and the carriage friction within the same bounds."""
    robot = tmp_path / "robot-epos2.yaml"
    text = (CONFIGS / "robot-3prrr.yaml").read_text()
    assert text.count("profile: epos4") == 2 and "method: 37" in text and "description: robots/3prrr.xml" in text
    robot.write_text(text.replace("profile: epos4", "profile: epos2").replace("method: 37", "method: 35")
                     .replace("description: robots/3prrr.xml", f"description: {CONFIGS / 'robots' / '3prrr.xml'}"))
    sim = tmp_path / "sim-epos2.yaml"
    sim.write_text((CONFIGS / "sim-3prrr.yaml").read_text().replace("extends: robot-3prrr.yaml", f"extends: {robot}"))
    path = tmp_path / "sweep.yaml"
    path.write_text(f"extends: {sim}\n" + SWEEP_CAMPAIGN)
    config = load_config(path)
    assert {a.profile for a in config.robot.actuators} == {"epos2"}
    folder = new_results_folder(config, tmp_path / "res", "run")
    runner.run_campaign(config, folder, report=False,
                        host=HostSettings.for_command(config))
    doc = json.loads((folder / "parameters.json").read_text())
    truth = dict(zip(to_model.inertial_params(config.sim.truth).NAMES, to_model.inertial_params(config.sim.truth).as_vector()))
    rows = {r["name"]: r for r in doc["parameters"] if r["step"]}
    assert set(rows) == {"m_c", "fv_zeta1", "fv_zeta2", "fv_zeta3", "fc_zeta1", "fc_zeta2", "fc_zeta3"}
    well = {n: r for n, r in rows.items() if r["rel_sigma_percent"] <= doc["rel_sigma_threshold_percent"]}
    assert "m_c" in well and len(well) >= 4, rows
    for name, r in well.items():
        assert abs(r["identified"] - truth[name]) <= 3 * r["sigma"] + BIAS_BUDGET * abs(truth[name]), (name, r)
    rec = Recording.load(folder / "data" / "sweep.npz")
    assert [a.profile for a in rec.metadata.axes] == ["EPOS2"] * 6


def test_the_online_estimate_at_the_end_agrees_with_the_offline_base_fit(main_job):
    """SVD-DLS fed the campaign's recordings in order (as ``ident-hw online`` does): at the end
    it has excited the same 18 directions as the offline base fit, and every base parameter the
    offline fit identifies well is within 2 % of the truth and of the offline value."""
    config, folder = main_job
    doc = json.loads((folder / "parameters.json").read_text())
    truth = dict(zip(to_model.inertial_params(config.sim.truth).NAMES, to_model.inertial_params(config.sim.truth).as_vector()))
    online = CampaignEstimator(config)
    for name in [t.name for t in config.trajectories if not t.online_only]:
        online.update(name, Recording.load(folder / "data" / f"{name}.npz"))
    svd = online.estimators["SVD-DLS"]
    rows = doc["base_fit"]["rows"]
    assert svd.rank_ == len(rows) == 18
    estimate = np.array(doc["base_fit"]["H"]) @ svd.coef_
    for row, value in zip(rows, estimate):
        if not row["well_identified"]:
            continue
        true = evaluate(row["base_parameter"], truth)
        assert abs(value - true) <= 0.02 * abs(true), (row["base_parameter"], value, true)
        assert abs(value - row["identified"]) <= 0.02 * abs(row["identified"]), (row["base_parameter"], value)
    # the one direction the symmetric rig never excites is named
    (held,) = online.unexcited()
    assert "I_l1" in held and "I_l2" in held


@pytest.mark.slow
def test_svd_dls_tracks_a_payload_added_mid_run(tmp_path):
    """The optimised excitation at 100 Hz with 0.3 kg and 5e-4 kg·m² put on the end-effector
    10 s in: the SVD-DLS estimates of the two base parameters holding m_ee and I_ee settle within
    2 % of their new true values before the end; the report says how long it took and which
    direction stayed unexcited; RLS and damped RLS ran beside it on the same data."""
    path = tmp_path / "payload.yaml"
    path.write_text(
        f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n"
        "bus: {interface: virtual, channel: payload-test, sync_rate: 100.0}\n"
        "trajectories: [{name: excitation, kind: fourier, cycles: 18,\n"
        "                payload: {after: 10.0, mass: 0.3, inertia: 0.0005}}]\n"
        "identification:\n"
        "  steps: [{name: base, trajectories: [excitation], method: wls, parameters: [m_c, m_l1, I_l1, m_l2,\n"
        "           I_l2, m_ee, I_ee, fv_theta1, fv_theta2, fv_theta3, fv_zeta1, fv_zeta2, fv_zeta3,\n"
        "           fc_theta1, fc_theta2, fc_theta3, fc_zeta1, fc_zeta2, fc_zeta3]}]\n"
        "  validation: []\n")
    config = load_config(path)
    folder = new_results_folder(config, tmp_path / "res", "online")
    results = runner.run_campaign(config, folder, online=CampaignEstimator(config),
                                  host=HostSettings.for_command(config))
    trace = results.online
    names = [trace.base_names[i] for i in tracked(trace)]
    assert names == ["1.5 m_l2 + m_ee", "0.0216 m_l2 + I_ee"]
    assert trace.change_time == pytest.approx(10.0, abs=0.05)
    end = trace.t[-1] - trace.change_time
    for i in tracked(trace):
        settle = settling_time(trace, "SVD-DLS", i)
        assert settle is not None and settle < end, (trace.base_names[i], settle, end)
        new = trace.base(trace.truth)[-1, i]
        assert abs(trace.base(trace.estimates["SVD-DLS"])[-1, i] / new - 1) <= 0.02
    assert set(trace.estimates) == {"SVD-DLS", "RLS", "damped RLS"} and trace.unexcited
    html = (folder / "report.html").read_text()
    assert "Online estimation" in html and "settling of 1.5 m_l2 + m_ee" in html
    assert (folder / "plots" / "online.png").is_file()


@functools.cache
def raw_log(path: Path) -> tuple:
    """The frames of a raw CAN log, read once for the tests that disturb them (never changed)."""
    import can

    with can.LogReader(path) as reader:
        return tuple(reader)


@pytest.mark.slow
@pytest.mark.parametrize("rate", [0.0002, 0.002])
def test_identify_from_raw_logs_with_late_and_lost_frames_is_right_or_degraded(main_job, tmp_path, rate):
    """The run's raw CAN logs with frames disturbed as a busy bus would: a share ``rate`` of the
    drives' TPDOs lost and as many late past the next SYNC. ``identify`` decodes them, places no
    frame in another cycle, leaves the disturbed cycles out, and either every well-identified
    parameter is within the bounds of the clean run or the verdict says degraded (at 0.2 % the
    short squares keep no stretch long enough to filter)."""
    import can

    from ident_hw.experiment.recordings import RecordingChecks, load_recording

    config, folder = main_job
    rng = np.random.default_rng(7)
    recordings = {}
    disturbed = {"lost": 0, "late": 0}
    for name in ("sweep", "square1", "square2", "square3", "square4", "square5", "excitation", "triangle"):
        messages = raw_log(folder / "data" / f"{name}.log")
        out, held = [], []
        for msg in messages:
            if msg.arbitration_id == 0x80:            # a SYNC: the held frames go out after it
                out.append(msg)
                out.extend(held)
                held = []
                continue
            if msg.arbitration_id >> 7 in (3, 5):      # TPDO1 (0x18x) / TPDO2 (0x28x) of the drives
                draw = rng.random()
                if draw < rate:
                    disturbed["lost"] += 1
                    continue
                if draw < 2 * rate:
                    disturbed["late"] += 1
                    held.append(msg)
                    continue
            out.append(msg)
        path = tmp_path / f"{name}.log"
        with can.Logger(path) as logger:
            for msg in out:
                logger.on_message_received(msg)
        shutil.copy(sidecar_path(folder / "data" / f"{name}.log"), sidecar_path(path))   # the run's PDO layout
        # the run's metadata (SYNC period, targets) from its .npz, the samples from the log
        rec_name, rec = load_recording(path, RecordingChecks.of(config))
        recordings[name] = rec
    assert disturbed["lost"] > 20000 * rate and disturbed["late"] > 20000 * rate
    results = identify(without_draws(config), recordings)
    save_results(tmp_path / "res", results)
    doc = json.loads((tmp_path / "res" / "parameters.json").read_text())
    truth = dict(zip(to_model.inertial_params(config.sim.truth).NAMES, to_model.inertial_params(config.sim.truth).as_vector()))
    late = sum(r.metadata.books.late_frames for r in recordings.values())
    logging.getLogger(__name__).warning(
        "disturbed logs: %s; late frames placed %d; verdict %s %s", disturbed, late,
        doc["quality"]["passed"], doc["quality"]["reasons"][:4])
    assert late > 0 and all(r.metadata.books.unplaced_frames == 0 for r in recordings.values())
    if doc["quality"]["passed"]:
        assert accuracy_failures(doc, truth) == [], doc["quality"]
    else:
        assert doc["quality"]["reasons"]


@pytest.mark.slow
def test_a_run_with_one_percent_of_cycles_incomplete_keeps_its_rows_and_its_accuracy(main_job, tmp_path):
    """The excitation's raw log with one TPDO frame lost in a seeded 1 % of its SYNC cycles, any
    TPDO of any drive alike (so lone velocity frames and lone position + current frames), decoded
    and identified alone (the base step). A lost velocity frame costs no row; a lost position and
    current cuts the run, which loses only the filters' main lobe on each side of the cut: at
    least 80 % of the excitation's rows are used, and every base parameter is well identified and
    within the main job's bounds of the truth (``3 σ + BIAS_BUDGET``, truth from the config)."""
    from drivers.acquisition import master_layouts
    from ident_hw.experiment.recordings import RecordingChecks, load_recording
    from lossy_logs import drop_frames

    config, folder = main_job
    path = tmp_path / "base-only.yaml"
    path.write_text(f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n"
                    "identification:\n  steps:\n"
                    "    - {name: base, trajectories: [excitation], parameters: [all], method: wls}\n"
                    "  validation: []\n")
    base_only = load_config(path)
    axes = [axis_config(a) for a in base_only.robot.actuators]
    cycles = len(Recording.load(folder / "data" / "excitation.npz").t)
    dropped = drop_frames(folder / "data" / "excitation.log", tmp_path / "excitation.log",
                          master_layouts(axes), 0.01, cycles, seed=0)
    name, rec = load_recording(tmp_path / "excitation.log", RecordingChecks.of(base_only))
    assert rec.n_invalid == len(dropped.cycles) == round(0.01 * cycles)
    assert len(dropped.measured) > 20 and len(dropped.others) > 20
    # the rows of a lost velocity frame keep their positions and currents
    assert rec.position_valid[dropped.others].all() and rec.current_valid[dropped.others].all()
    assert not rec.velocity_valid[dropped.others].all(axis=1).any()

    results = identify(without_draws(base_only), {name: rec})
    used = results.trajectories["excitation"]
    assert used.rows_left_out["incomplete"] == len(dropped.measured)
    kept = used.cycles - sum(used.rows_left_out.values())
    assert kept >= 0.8 * used.cycles, used
    truth = dict(zip(to_model.inertial_params(config.sim.truth).NAMES, to_model.inertial_params(config.sim.truth).as_vector()))
    fit = results.base_fit
    assert len(fit.expressions) == 18
    for expression, value, sigma in zip(fit.expressions, fit.coef, fit.sigma):
        true = evaluate(expression, truth)
        assert 100 * sigma / abs(true) <= results.rel_sigma_threshold, (expression, sigma, true)
        assert abs(value - true) <= 3 * sigma + BIAS_BUDGET * abs(true), (expression, value, true, sigma)
