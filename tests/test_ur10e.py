"""A real robot's own recordings (issue 46): the UR10e of "Practical Aspects of Model-Based
Collision Detection" (Mamedov et al. 2020), its public dataset found through
``IDENT_HW_DATASETS`` (``.ci/run`` sets it; without it these tests skip, saying so).

Identified from the authors' excitation run, the tool predicts their held-out point-to-point run
better than their published parameters, joint by joint, measured as they measure it (rre); the
published set's prediction is computed here again by hand from their file and pinocchio's
regressor, so that the comparison does not rest on the tool's reading of it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ident_hw.config import load_config
from ident_hw.experiment.compared import compared_set, read_vectors
from ident_hw.experiment.export import export_description
from ident_hw.experiment.folders import new_results_folder
from ident_hw.experiment.offline import identify
from ident_hw.experiment.recordings import gather_recordings
from ident_hw.experiment.runner import identify_recordings
from ident_hw.report.terminal import gains_lines
from ident_hw.results import validation_figures

from recorded_data import dataset

CONFIGS = Path(__file__).resolve().parent.parent / "configs"


@pytest.fixture(scope="module")
def ur10e():
    return dataset("ur10e")


@pytest.fixture(scope="module")
def authors(ur10e, tmp_path_factory):
    """``configs/ur10e.yaml`` identified from the authors' run into a results folder (no report):
    ``(results, folder)``."""
    config = load_config(CONFIGS / "ur10e.yaml")
    gathered = gather_recordings(config, [])
    recordings, imported = gathered.recordings, gathered.imported
    folder = new_results_folder(config, tmp_path_factory.mktemp("ur10e") / "results", "identify")
    return identify_recordings(config, recordings, folder, report=False, imported=imported), folder


def rre(config, given=()):
    gathered = gather_recordings(config, list(given))
    recordings, imported = gathered.recordings, gathered.imported
    results = identify(config, recordings, imported=imported)
    figures = validation_figures(results)["validation"]
    return np.array(figures.rre_percent.fit, dtype=float), np.array(figures.rre_percent.compared, dtype=float), imported, results


def test_identified_from_the_authors_run_it_predicts_their_held_out_run_better_on_every_joint(authors):
    results, _ = authors
    figures = validation_figures(results)["validation"]
    ours, theirs = np.array(figures.rre_percent.fit, dtype=float), np.array(figures.rre_percent.compared, dtype=float)
    assert results.trajectories["excitation"].imported.window == "rows 635..3510"
    assert results.trajectories["validation"].imported.window == "rows 700..4200"
    assert np.all(ours <= theirs), (ours, theirs)
    assert ours.mean() <= 0.8 * theirs.mean(), (ours.mean(), theirs.mean())     # the aim: 20 % below
    # their published set as the issue measured it independently: about 12.9 5.7 5.7 12.4 15.9 55.6 %
    # against the unfiltered torques; here against the filtered ones, so a little lower where noise counts
    assert np.all(theirs <= np.array([12.9, 5.7, 5.7, 12.4, 15.9, 55.6]) * 1.2)
    assert results.friction.model == "dahl" and results.friction.presliding is not None


def test_another_excitation_run_given_on_the_command_line_is_taken_whole(ur10e):
    run = ur10e / "identification" / "ur-20_02_12-40sec_12harm.csv"
    ours, theirs, imported, _ = rre(load_config(CONFIGS / "ur10e.yaml"), [f"excitation={run}"])
    summary = imported["excitation"]
    assert summary.window is None and summary.idle_head_s > 1.0 and summary.idle_tail_s > 1.0
    assert np.all(ours <= theirs), (ours, theirs)
    assert ours.mean() <= 0.8 * theirs.mean()


def test_the_datasets_corrupted_file_has_each_bad_row_cut_with_its_reason(ur10e):
    """The second loaded run of the dataset starts with rows of garbage and ends mid-row."""
    run = ur10e / "identification" / "ur-20_02_19_15harm50secLoad.csv"
    config = load_config(CONFIGS / "ur10e.yaml")
    gathered = gather_recordings(config, [f"excitation={run}"])
    imported = gathered.imported
    cut = {c.reason: c for c in imported["excitation"].cut}
    assert cut["fields"].lines == (6107,)                 # the last line, cut short
    assert cut["absurd"].count == 8 and cut["absurd"].lines[:3] == (2, 3, 4)
    assert cut["time_back"].count == 2
    assert imported["excitation"].rows_used + sum(c.count for c in cut.values()) <= 6107


def test_the_published_parameters_are_read_into_the_models_order(ur10e):
    """The compared set's forces against pinocchio's regressor and the published vector placed
    by hand: per link [Ixx Ixy Ixz Iyy Iyz Izz mx my mz m] into pinocchio's [m mx my mz Ixx Ixy
    Iyy Ixz Iyz Izz], friction per joint Fv qd + Fc sign(qd) + F0, rotor inertias."""
    config = load_config(CONFIGS / "ur10e.yaml")
    spec = config.identification.compare_with
    published = compared_set(config.robot, spec)
    vectors = read_vectors(spec.path)
    model = pin.buildModelFromUrdf(str(ur10e / "ur10e.urdf"))
    data = model.createData()
    by_hand = []
    for link in vectors["pi_rgd"].reshape(6, 10):
        Ixx, Ixy, Ixz, Iyy, Iyz, Izz, mx, my, mz, m = link
        by_hand += [m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]
    rng = np.random.default_rng(3)
    q, qd, qdd = rng.uniform(-2, 2, (3, 20, 6))
    Y, _ = published.model.identification_regressor(q, qd, qdd, None)
    friction = vectors["pi_frcn"].reshape(6, 3)
    for k in range(20):
        expected = (pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k]) @ np.array(by_hand)
                    + friction[:, 0] * qd[k] + friction[:, 1] * np.sign(qd[k]) + friction[:, 2]
                    + vectors["pi_drvs"] * qdd[k])
        assert np.allclose(Y[k] @ published.values, expected, rtol=1e-9, atol=1e-9)
    assert np.allclose(published.gains, [10.0, 10.6956, 8.4566, 9.0029, 9.48, 10.1232])


def test_the_consistent_set_is_exported_as_a_urdf_that_pinocchio_and_mujoco_load(authors, tmp_path):
    mujoco = pytest.importorskip("mujoco")
    results, folder = authors
    assert results.consistent is not None
    written = export_description(folder, tmp_path / "ur10e_identified.urdf", for_mujoco=True)
    robot = pin.buildModelFromUrdf(str(written))
    masses = [robot.inertias[j].mass for j in range(1, robot.njoints)]
    consistent = dict(zip(results.consistent.names, results.consistent.values))
    bodies = ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link")
    assert np.allclose(masses, [consistent[f"{b}.m"] for b in bodies], rtol=1e-6)
    loaded = mujoco.MjModel.from_xml_path(str(written))
    assert np.allclose(loaded.body_mass[1:], masses, rtol=1e-6)


@pytest.mark.slow
def test_the_drive_gains_from_the_payload_pair_beside_the_published_ones(ur10e):
    config = load_config(CONFIGS / "ur10e-gains.yaml")
    gathered = gather_recordings(config, [])
    recordings, imported = gathered.recordings, gathered.imported
    results = identify(config, recordings, imported=imported)
    gains = next(s for s in results.steps if s.name == "gains").drive_gains
    found, sigma, published = (np.array(x) for x in (gains.gains, gains.sigma, gains.configured))
    assert np.allclose(published, [10.0, 10.6956, 8.4566, 9.0029, 9.48, 10.1232])
    assert np.all(np.isfinite(found)) and np.all(sigma > 0)
    # the report says, per joint, how far from the published gain and in how many sigma
    lines = gains_lines("gains", gains, results.actuators)
    for name, g, c in zip(results.actuators, found, published):
        row = next(line for line in lines if line.split()[:1] == [name])
        assert f"{100 * (g - c) / c:+.1f}" in row
    # within a quarter of the published gains, each; the identified set fits the pair better
    assert np.all(np.abs(found / published - 1) < 0.25)
    assert np.all(np.array(gains.residual_rms) <= np.array(gains.residual_rms_configured))


# ----------------------------------------------------------------------------- the verdict on real data
def test_the_verdict_passes_the_real_fit_and_says_what_it_could_not_judge_and_why(authors):
    """The UR10e's own data: no standstill (no noise floor), a serial arm whose axes' own
    parameters take any gain, a residual of model error (so the chi2 of the physical consistency,
    against a covariance of noise, is not judged: the consistent set's prediction is), the loaded
    joints' currents leading their links (an elastic joint: a small share of the residual, noted)."""
    quality = authors[0].quality
    assert quality.passed, quality.reasons
    assert set(quality.not_judged) == {"gain", "noise floor", "physical consistency chi2"}
    assert any("elasticity" in note for note in quality.notes)
    for name, axis in quality.axes.items():
        assert axis.rre_percent < 10 and axis.rre_consistent_percent < 10, (name, axis)


GARBAGE = {
    # the shoulder's current with the wrong sign
    "negated": ("current: [14, 15, 16, 17, 18, 19]", "current: [14, 15, 16, 17, 18, 19]\n  scale: {current: [1, -1, 1, 1, 1, 1]}",
                "shoulder"),
    # the shoulder's gain half as large again
    "gain": ("current: [14, 15, 16, 17, 18, 19]", "current: [14, 15, 16, 17, 18, 19]\n  scale: {current: [1, 1.5, 1, 1, 1, 1]}",
             "shoulder"),
    # the elbow's torque constant 20 % off
    "elbow": ("current: [14, 15, 16, 17, 18, 19]", "current: [14, 15, 16, 17, 18, 19]\n  scale: {current: [1, 1, 1.2, 1, 1, 1]}",
              "elbow"),
    # two wrists' current columns swapped
    "swapped": ("current: [14, 15, 16, 17, 18, 19]", "current: [14, 15, 16, 18, 17, 19]", "wrist1"),
    # currents of another moment than the positions (0.3 s apart)
    "shifted": ("current: [14, 15, 16, 17, 18, 19]", "current: [14, 15, 16, 17, 18, 19]\n  current_delay: 0.3", "base"),
    # the controller's commands taken for measured currents
    "commands": ("current: [14, 15, 16, 17, 18, 19]", "current: [20, 21, 22, 23, 24, 25]", "shoulder"),
}


#: the friction constants the real data chose (the friction choice is not what these tests test)
CHOSEN = "friction: {model: dahl, offset: true, presliding: 0.0001, stribeck: 2.0}"


@pytest.mark.parametrize("case", sorted(GARBAGE))
def test_the_verdict_fails_garbage_made_of_the_real_data_naming_the_axis(ur10e, tmp_path, case):
    old, new, axis = GARBAGE[case]
    text = (CONFIGS / "ur10e.yaml").read_text()
    shipped = "friction: {model: dahl, offset: true, presliding: auto, stribeck: auto}"
    assert old in text and shipped in text
    path = tmp_path / "garbage.yaml"
    path.write_text(text.replace(old, new).replace(shipped, CHOSEN))
    config = load_config(path)
    gathered = gather_recordings(config, [])
    recordings, imported = gathered.recordings, gathered.imported
    quality = identify(config, recordings, imported=imported).quality
    assert not quality.passed
    assert any(reason.startswith(f"{axis}:") for reason in quality.reasons), quality.reasons


def test_a_friction_order_the_compared_model_has_no_place_for_names_the_key(ur10e, tmp_path):
    """``fs`` (a Stribeck term) is a friction value a file may hold, but the compared model of a
    ``coulomb`` set has none: a CompareError naming the file, the key and the value, not a bare
    ValueError from deep inside."""
    import dataclasses

    from ident_hw.experiment.compared import CompareError

    config = load_config(CONFIGS / "ur10e.yaml")
    spec = config.identification.compare_with
    vectors = read_vectors(spec.path)
    with_fs = tmp_path / "with_fs.txt"
    text = Path(spec.path).read_text(encoding="utf-8")
    four = np.column_stack([vectors["pi_frcn"].reshape(6, 3), np.ones(6)]).ravel()
    with_fs.write_text(text + "\npi_frcn4 = [" + " ".join(repr(float(v)) for v in four) + "]\n", encoding="utf-8")
    friction = dataclasses.replace(spec.friction, vector="pi_frcn4", order=("fv", "fc", "f0", "fs"))
    bad = dataclasses.replace(spec, path=str(with_fs), friction=friction)
    with pytest.raises(CompareError, match=r"with_fs\.txt: identification\.compare_with\.friction\.order: "
                                           r"'fs' has no place in the compared model \(it holds \['f0', 'fc', 'fv'\]"):
        compared_set(config.robot, bad)
