"""The dynamic, power and energy models (the power-model paper, its Table 1) on a planar 2R arm
described by a URDF: exact model data (forces ``Y @ pi`` of a smooth multi-sine, friction and
rotor inertias known), the three models' base parameters, and their record in a results folder.

Errors on exact data come from the numerical ``dH/dt`` (power, fourth order) and the Simpson
integration (energy), both O(h⁴); the dynamic rows are exact, filtered in parallel."""

from __future__ import annotations

import dataclasses
import json
from types import SimpleNamespace

import numpy as np
import pytest

from ident_hw.config import load_config
from ident_hw.experiment.inputs import identification_plan
from ident_hw.experiment.preparation import Prepared, prepare
from ident_hw.experiment.steps import comparison, fit_base
from ident_hw.results.folder import ModelComparisonFile
from ident_hw.segments import Segments
from ident_hw.storage import from_json
from ident_hw.identification.model_comparison import (ModelComparison, ModelRows, compare_models, energy_columns,
                                                      power_energy_rows, supports_energy_models)
from ident_hw.identification.power import FrictionLayout, energy_rows_in_layout, power_rows_in_layout
from ident_hw.model.described import DescribedRobot
from ident_hw.report.html import render_html
from ident_hw.report.terminal import summary_lines
from ident_hw.results import ParameterTable, Results, load_results, mark_status, save_results
from ident_hw.filtering import FilterSettings, parallel_decimate

from drivers.errors import ConfigError
from drivers.recording import Recording
from drivers.recording_metadata import RecordingMetadata
from ident_scenarios import CONFIGS, ROBOT, TRUE, make_motion
from ident_hw.config.to_drivers import axis_scaling
from ident_hw.config.to_identification import filter_settings, step_parameters

#: a 2R arm in the horizontal plane (hinges along z): centres of mass off the links' axes, so
#: that every base parameter has a non-zero true value
URDF = """<?xml version="1.0"?>
<robot name="planar_2r_test">
  <link name="base"/>
  <joint name="joint1" type="revolute"><parent link="base"/><child link="link1"/>
    <origin xyz="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="100" velocity="10"/></joint>
  <link name="link1"><inertial><origin xyz="0.2 0.01 0"/><mass value="4.0"/>
    <inertia ixx="0.004" ixy="0" ixz="0" iyy="0.06" iyz="0" izz="0.06"/></inertial></link>
  <joint name="joint2" type="revolute"><parent link="link1"/><child link="link2"/>
    <origin xyz="0.4 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="50" velocity="10"/></joint>
  <link name="link2"><inertial><origin xyz="0.15 0.02 0"/><mass value="2.0"/>
    <inertia ixx="0.0005" ixy="0" ixz="0" iyy="0.015" iyz="0" izz="0.015"/></inertial></link>
</robot>
"""
#: (amplitude rad, frequency Hz, phase rad) per joint: a smooth excitation up to 1.1 Hz
SINES = ([(0.8, 0.15, 0.3), (0.4, 0.45, 1.0), (0.2, 0.9, 2.0)],
         [(1.0, 0.2, 0.7), (0.5, 0.55, 0.1), (0.25, 1.1, 1.3)])
FRICTION = {"fv_joint1": 0.3, "fv_joint2": 0.1, "fc_joint1": 0.5, "fc_joint2": 0.2,
            "Jm_joint1": 0.01, "Jm_joint2": 0.004}
#: a planar 2R without gravity: ZZ1R (link1.Izz + l1² link2.m + Jm1), MX2, MY2, ZZ2, Jm2 and the
#: four friction coefficients; link 1's first moments and every other inertia do no work
BASE_RANK = 9


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    path = tmp_path_factory.mktemp("robot") / "r2.urdf"
    path.write_text(URDF)
    return DescribedRobot(path, actuated=("joint1", "joint2"))


@pytest.fixture(scope="module")
def truth(robot):
    pi = robot.nominal_parameters()
    for name, value in FRICTION.items():
        pi[robot.parameter_names.index(name)] = value
    return pi


def motion(rate: float, duration: float = 20.0):
    """``t`` (N,) and the analytic ``Theta``, ``Thetad``, ``Thetadd`` (N, 2) of :data:`SINES`."""
    t = np.arange(int(round(duration * rate))) / rate
    out = np.zeros((3, t.size, 2))
    for j, terms in enumerate(SINES):
        for a, f, p in terms:
            w = 2 * np.pi * f
            out[:, :, j] += a * np.array([np.sin(w * t + p), w * np.cos(w * t + p), -w * w * np.sin(w * t + p)])
    return t, *out


def exact_rows(robot, truth, rate: float, noise: float = 0.0, seed: int = 0):
    """The three models' rows of one stretch of exact data at ``rate`` (Hz), as the offline
    identification makes them (parallel filter and decimation of a 1.1 Hz motion); ``noise``:
    Gaussian force noise, a fraction of each actuator's RMS force."""
    t, Theta, Thetad, Thetadd = motion(rate)
    Y, poses = robot.identification_regressor(Theta, Thetad, Thetadd, None)
    tau = Y @ truth
    tau = tau + noise * np.sqrt(np.mean(tau**2, axis=0)) * np.random.default_rng(seed).normal(size=tau.shape)
    settings = FilterSettings.for_sample_rate(rate, bandwidth_hz=1.1)
    Yd, taud = parallel_decimate(settings, Y, tau)
    power, energy = power_energy_rows(robot, t, Theta, Thetad, tau, poses, settings)
    return [ModelRows("dynamic", Yd, taud), power, energy]


def worst_relative_errors(robot, truth, rate: float) -> dict:
    result = compare_models(robot.parameter_names, exact_rows(robot, truth, rate), truth=truth,
                            basis=robot.readable_base())
    assert [f.model for f in result.fits] == ["dynamic", "power", "energy"]
    for fit in result.fits:
        assert fit.rank == BASE_RANK, (fit.model, fit.expressions)
        assert np.all(np.abs(fit.truth) > 1e-3)       # every base parameter's error is relative to a real value
    assert result.shared_expressions is not None      # the same base parameters, one table
    return {f.model: float(np.max(np.abs(f.coef / f.truth - 1))) for f in result.fits}


#: worst base parameter (relative) on exact 20 s of data at 250 Hz, measured: dynamic 5e-14,
#: power 6.3e-6, energy 2.8e-6; the bounds leave a factor of about 3 (the power model's error
#: falling as h⁴ is asserted separately; the energy model's falls faster, 67 times from 250 to
#: 500 Hz, its filtered integrands' edge transients decaying too)
BOUNDS_250_HZ = {"dynamic": 1e-10, "power": 2e-5, "energy": 1e-5}


def test_three_models_recover_the_base_parameters_of_exact_data(robot, truth):
    e250 = worst_relative_errors(robot, truth, 250.0)
    assert all(e250[m] <= BOUNDS_250_HZ[m] for m in BOUNDS_250_HZ), e250
    e500 = worst_relative_errors(robot, truth, 500.0)
    assert 10.0 < e250["power"] / e500["power"] < 25.0, (e250, e500)    # 16 for h⁴
    assert e500["energy"] < e250["energy"] / 10.0, (e250, e500)


def test_sigma_of_each_model_covers_its_error_on_noisy_forces(robot, truth):
    """5 % force noise: every base parameter of every model within 4 σ of its truth, and the
    models' %σ ordered as the paper finds them (the dynamic model, with n rows per sample,
    tighter than the scalar power model on the link-2 terms)."""
    result = compare_models(robot.parameter_names, exact_rows(robot, truth, 250.0, noise=0.05), truth=truth,
                            basis=robot.readable_base())
    for fit in result.fits:
        z = (fit.coef - fit.truth) / fit.sigma
        assert np.all(np.abs(z) < 4.0), (fit.model, np.round(z, 2))
        assert np.all(fit.sigma > 0)


def test_rows_place_friction_and_rotor_terms_at_the_models_own_parameters(robot, truth):
    names = robot.parameter_names
    layout = FrictionLayout.of(robot)
    assert [names[i] for i in layout.fv + layout.fc] == ["fv_joint1", "fv_joint2", "fc_joint1", "fc_joint2"]
    t, Theta, Thetad, Thetadd = motion(250.0, duration=4.0)
    H = energy_columns(robot, Theta, Thetad)
    # the energy is 1/2 Thetad^T M Thetad with the plant's mass matrix (rotors included)
    M = np.array([robot.plant_dynamics(q, qd, truth, None).M for q, qd in zip(Theta[::50], Thetad[::50])])
    np.testing.assert_allclose(H[::50] @ truth, 0.5 * np.einsum("ki,kij,kj->k", Thetad[::50], M, Thetad[::50]),
                               rtol=1e-12)
    tau = np.ones_like(Thetad)
    W, y = power_rows_in_layout(t, H, Thetad, tau, robot.coulomb_width, layout)
    inner = slice(2, t.size - 2)
    np.testing.assert_array_equal(W[:, names.index("fv_joint2")], Thetad[inner, 1] ** 2)
    np.testing.assert_array_equal(W[:, names.index("fc_joint1")],
                                  Thetad[inner, 0] * np.tanh(Thetad[inner, 0] / robot.coulomb_width))
    # d/dt (Jm qd² / 2) = Jm qd qdd, by fourth-order differences
    np.testing.assert_allclose(W[:, names.index("Jm_joint1")], (Thetad * Thetadd)[inner, 0], rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(y, Thetad[inner].sum(axis=1))
    We, ye = energy_rows_in_layout(t, H, Thetad, tau, robot.coulomb_width, layout, window=25)
    np.testing.assert_allclose(We[:, names.index("Jm_joint2")], np.diff(0.5 * Thetad[::25, 1] ** 2), rtol=1e-12)
    np.testing.assert_allclose(ye, np.diff(Theta[::25].sum(axis=1)), rtol=1e-6, atol=1e-9)   # ∫ qd dt


def test_the_3prrr_is_not_offered_the_power_and_energy_models():
    why = supports_energy_models(ROBOT)
    assert why is not None and "energy_regressor" in why

def test_a_config_asking_for_the_comparison_of_a_robot_without_it_is_refused_with_file_key_and_line(tmp_path):
    text = (CONFIGS / "sim-3prrr.yaml").read_text().replace("  validation: [triangle]\n",
                                                            "  validation: [triangle]\n  compare_models: true\n", 1)
    assert "compare_models" in text
    path = tmp_path / "sim.yaml"
    path.write_text(text.replace("extends: robot-3prrr.yaml", f"extends: {CONFIGS / 'robot-3prrr.yaml'}"))
    with pytest.raises(ConfigError) as info:
        load_config(path)
    err = info.value
    assert err.key == "identification.compare_models" and "energy_regressor" in str(err)
    assert err.file == str(path) and "compare_models: true" in text.splitlines()[err.line - 1]


class EnergyThreePRRR:
    """The 3PRRR with an energy regressor over its 19 parameters (kinetic energy of the 7
    inertial ones, zero friction columns) from the actuated motion: only to drive the offline
    preparation's power and energy rows through a config and recording the suite already has."""

    def __init__(self, robot):
        self._robot = robot

    def __getattr__(self, name):
        return getattr(self._robot, name)

    def energy_regressor(self, Theta, Thetad, guess):
        pose = self._robot.pose_motion(Theta, Thetad, np.zeros_like(Theta), guess)
        H = self._robot.energy_regressor(pose.q, pose.qd, Theta[:, 3:], Thetad[:, 3:])
        return np.concatenate([H, np.zeros((len(Theta), 12))], axis=1)


def test_prepare_gives_the_power_and_energy_models_the_least_squares_steps_stretches():
    """Through the offline preparation (position filter, stretches, parallel filter) of a
    recording: asking for the power and energy rows leaves the dynamic rows as they were, the
    power rows fall on the same decimated samples, and the comparison's dynamic model is the
    least-squares step's own base fit; the 3PRRR's three models find the same 18 of 19."""
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    rate = config.bus.sync_rate
    m = make_motion(rate=rate, duration=10.0)
    force_per_amp = np.array([axis_scaling(a).force_per_amp for a in config.robot.actuators])
    n = len(m.t)
    rec = Recording(t=m.t, cycle=np.arange(n), position=m.Theta, velocity=m.Thetad, current=m.tau / force_per_amp,
                    statusword=np.zeros((n, 6), np.int32), target=m.Theta, valid=np.ones((n, 6), bool),
                    metadata=RecordingMetadata(sync_period=1.0 / rate))
    robot = EnergyThreePRRR(ROBOT)
    plain = prepare(identification_plan(config), robot, "excitation", rec)
    both = prepare(identification_plan(config), robot, "excitation", rec, scalar_models=True)
    assert plain.power is None and plain.energy is None
    np.testing.assert_array_equal(both.Y, plain.Y)
    np.testing.assert_array_equal(both.tau_fit, plain.tau_fit)
    assert both.power.Y.shape == (len(both.t), 1, 19) and 0.8 * len(both.t) < len(both.energy.Y) < len(both.t)
    settings = filter_settings(config.identification.filter, rate, 1.0)
    assert both.energy.window == pytest.approx(settings.decimation / rate)
    step = next(s for s in config.identification.steps if s.method != "sqp")
    names, truth = ROBOT.parameter_names, TRUE.as_vector()
    free = step_parameters(step, names)
    result = comparison(step, free, names, both.Y, both.tau_fit, {"excitation": both}, truth, truth, True, 10.0)
    base_fit = fit_base(step, free, names, both.Y, both.tau_fit, truth, truth, truth, 10.0).fit
    dynamic = result.fit("dynamic")
    assert dynamic.expressions == base_fit.expressions and dynamic.method == "WLS"
    np.testing.assert_array_equal(dynamic.coef, base_fit.coef)
    assert [f.rank for f in result.fits] == [18, 18, 18] and result.shared_expressions is not None


@pytest.fixture(scope="module")
def folder(robot, truth, tmp_path_factory):
    """A results folder whose comparison the offline wiring made (:func:`comparison`) from
    prepared rows, ``Jm_joint2`` held at its true value."""
    names = robot.parameter_names
    dynamic, power, energy = exact_rows(robot, truth, 250.0)
    n = len(dynamic.Y)
    prepared = {"excite": Prepared("excite", np.zeros(n), np.zeros((n, 2)), np.zeros((n, 2)), dynamic.Y, dynamic.y,
                                   np.ones((n, 2), bool), Segments(np.zeros(n), [], 0, 0), np.zeros((n, 2)),
                                   power=power, energy=energy)}
    step = SimpleNamespace(name="base", trajectories=("excite",))
    free = tuple(p for p in names if p != "Jm_joint2")
    result = comparison(step, free, names, dynamic.Y, dynamic.y, prepared, truth, truth, True, 10.0,
                        robot.readable_base())
    table = ParameterTable(names=names, units=tuple(robot.unit_of(p) for p in names), initial=truth,
                           identified=truth, sigma=np.full(len(names), np.nan), lower=np.full(len(names), -np.inf),
                           upper=np.full(len(names), np.inf), step=("",) * len(names), method=("",) * len(names),
                           truth=truth)
    path = tmp_path_factory.mktemp("results")
    save_results(path, Results(parameters=table, actuators=robot.actuator_names, actuator_kinds=robot.actuator_kinds,
                               model_comparison=result))
    mark_status(path, "complete")
    return path


def test_comparison_with_a_held_parameter_is_stored_in_parameters_json(folder, robot, truth):
    doc = json.loads((folder / "parameters.json").read_text())
    stored = doc["model_comparison"]
    assert [m["model"] for m in stored["models"]] == ["dynamic", "power", "energy"]
    assert stored["held"] == ["Jm_joint2"] and stored["trajectories"] == ["excite"]
    for model, bound in BOUNDS_250_HZ.items():
        m = next(m for m in stored["models"] if m["model"] == model)
        assert m["rank"] == BASE_RANK - 1 and m["free"] == len(robot.parameter_names) - 1
        assert all("Jm_joint2" not in r["base_parameter"] for r in m["rows"])
        assert max(abs(r["error_percent"]) for r in m["rows"]) <= 100 * bound, (model, m["rows"])
    assert stored["models"][0]["method"] == "WLS" and stored["models"][1]["method"] == "OLS"
    back = load_results(folder).model_comparison
    assert isinstance(back, ModelComparison)
    for a, b in zip(back.fits, from_json(ModelComparisonFile, stored).comparison().fits):
        np.testing.assert_array_equal(a.coef, b.coef)
        np.testing.assert_array_equal(a.H, b.H)
    # the results of a run without the comparison have no such key
    plain = folder.parent / "plain"
    save_results(plain, dataclasses.replace(load_results(folder), model_comparison=None))
    assert "model_comparison" not in json.loads((plain / "parameters.json").read_text())
    mark_status(plain, "complete")
    assert not any(line.startswith("dynamic, power and energy") for line in summary_lines(plain))
    assert "Dynamic, power and energy models" not in render_html(plain, load_results(plain), {}, [])


def test_terminal_and_report_show_the_table(folder):
    lines = summary_lines(folder)
    start = next(i for i, line in enumerate(lines) if line.startswith("dynamic, power and energy models"))
    assert lines[start + 1].split()[0] == "dynamic" and "rank 8 of 25" in lines[start + 1]
    assert "windows of 0.036 s" in lines[start + 3]
    table = [line.split() for line in lines[start + 5:start + 5 + 3 * (BASE_RANK - 1)]]
    assert [row[0] for row in table] == ["dynamic"] * 8 + ["power"] * 8 + ["energy"] * 8
    assert all(abs(float(row[-1])) < 0.01 for row in table)           # error % column
    html = render_html(folder, load_results(folder), {}, [])
    section = html[html.index("<h2>Dynamic, power and energy models</h2>"):]
    section = section[:section.index("<h2>", 4)] if "<h2>" in section[4:] else section
    assert section.count("<tr><td>fv_joint1</td>") == 1              # one row per base parameter, models side by side
    assert section.count("<th>estimate</th>") == 3
