"""The ident-hw command line, driven as a user would (subprocess)."""

from __future__ import annotations

import dataclasses

import json
import subprocess
from pathlib import Path

import numpy as np
from scipy.stats import norm
import pytest
import yaml

from drivers.recording import Recording
from drivers.recording_metadata import RecordingMetadata
from ident_hw.config import load_config, to_model
from ident_hw.experiment.offline import identify
from ident_hw.experiment.plan import plan
from ident_hw.config.robots import model_of
from ident_hw.config.to_drivers import axis_scaling
from cli_runs import ident_hw

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"


def test_help_lists_the_commands():
    """Through the installed ``ident-hw`` script (the other tests call its ``main`` in-process)."""
    out = subprocess.run(["ident-hw", "--help"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0
    for name in ("check", "run", "identify", "report"):
        assert name in out.stdout
    assert "--arm" in ident_hw("run", "--help").stdout


@pytest.mark.parametrize("option, value, message", [("--runs", "0", "--runs: must be at least 1, got 0"),
                                                    ("--workers", "-1", "--workers: must be at least 0, got -1"),
                                                    ("--runs", "two", "--runs: not a whole number: 'two'")])
def test_study_refuses_a_count_out_of_range_before_anything_is_made(tmp_path, option, value, message):
    argv = {"--runs": "2", option: value}
    out = ident_hw("study", CONFIGS / "sim-3prrr.yaml", *[x for kv in argv.items() for x in kv],
                   "--out", tmp_path / "study")
    assert out.returncode == 2 and message in out.stderr
    assert "study folder" not in out.stderr and not (tmp_path / "study").exists()


def test_check_accepts_the_sim_campaign():
    out = ident_hw("check", CONFIGS / "sim-3prrr.yaml")
    assert out.returncode == 0, out.stdout + out.stderr
    assert "triangle: ok" in out.stdout and "everything would run" in out.stdout


def test_check_says_nothing_on_the_shipped_configs():
    """No note on a shipped config: the encoders' count per SYNC period, which the identification
    accounts for (its encoder draws), is said only where it does not (encoder_draws 0)."""
    for name in ("sim-3prrr.yaml", "sim-2r.yaml", "hil-3prrr-epos4.yaml"):
        out = ident_hw("check", CONFIGS / name)
        assert out.returncode == 0 and "note:" not in out.stdout, out.stdout


def test_check_says_the_encoder_note_where_the_draws_are_off(tmp_path):
    (tmp_path / "no-draws.yaml").write_text(f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n"
                                           "identification: {encoder_draws: 0}\n")
    out = ident_hw("check", tmp_path / "no-draws.yaml")
    assert out.returncode == 0 and "note: one encoder count per SYNC period" in out.stdout
    assert "with identification.encoder_draws 0 the sigma leave the encoders' resolution out" in out.stdout


@pytest.mark.parametrize("offset, expected", [
    (7.0, "robot.actuators[0] (theta1) homing.offset 7 rad is outside its position limits [-6.3, 6.3] rad: the drive "
          "would stop on its software position limit as soon as it is homed"),
    (-0.40, "robot.actuators[0] (theta1) homing.offset -0.4 rad: homing method 37 takes the current position as "
            "home, where the model puts theta1 at -0.485518 rad (+0.08552 rad apart, more than 10 encoder counts): "
            "set the offset to -0.485518")])
def test_check_refuses_a_homing_offset_off_the_limits_or_the_home(tmp_path, offset, expected):
    """A homing offset outside the axis's limits (the run would stop on an EMCY software position
    limit once homed), or, homing on the current position, away from the model's home: check
    and run refuse it, naming the file, the actuator and what to set, before anything moves."""
    config = tmp_path / "homing.yaml"
    base = yaml.safe_load((CONFIGS / "robot-3prrr.yaml").read_text())["robot"]["actuators"]
    actuators = [dict(a, homing=dict(a["homing"], offset=offset)) if a["name"] == "theta1" else a for a in base]
    config.write_text(f"extends: {CONFIGS / 'sim-3prrr.yaml'}\nrobot:\n  actuators: {json.dumps(actuators)}\n")
    out = ident_hw("check", config)
    assert out.returncode == 2 and f"{config}: {expected}" in out.stdout, out.stdout
    assert "NOT runnable" in out.stdout
    run = ident_hw("run", config, "--out", tmp_path / "res")
    assert run.returncode == 2 and expected in run.stderr and not (tmp_path / "res").exists()


def test_check_rejects_an_infeasible_trajectory(tmp_path):
    (tmp_path / "bad.yaml").write_text(
        f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n"
        "trajectories:\n  - {name: big, kind: square, size: 0.9}\n"
        "identification:\n  steps: [{name: s, trajectories: [big], parameters: [m_ee]}]\n  validation: []\n")
    out = ident_hw("check", tmp_path / "bad.yaml")
    assert out.returncode == 2   # the config cannot run
    assert "big:" in out.stdout and "NOT runnable" in out.stdout
    assert "INFEASIBLE" in out.stdout or "cannot build" in out.stdout


def test_bad_config_names_file_key_and_line(tmp_path):
    text = (CONFIGS / "robot-3prrr.yaml").read_text().replace("  stroke: 0.10", "  stroke: -0.10")
    (tmp_path / "robot.yaml").write_text(text)
    out = ident_hw("check", tmp_path / "robot.yaml")
    assert out.returncode == 2
    line = 1 + text.splitlines().index(next(s for s in text.splitlines() if "stroke: -0.10" in s))
    assert f"robot.yaml, line {line}: robot.stroke" in out.stderr and "positive" in out.stderr


def test_run_refuses_hardware_without_arm(tmp_path):
    out = ident_hw("run", CONFIGS / "hil-3prrr-epos4.yaml", "--out", tmp_path / "r")
    assert out.returncode == 2   # a command-line error: nothing opened, nothing moved
    assert "--arm" in out.stderr and "can0" in out.stderr
    assert not (tmp_path / "r").exists()


def synthetic_recordings(config, folder: Path) -> list[Path]:
    """Recordings of the campaign as the drives would report them for a perfectly tracked motion:
    true-parameter forces as whole mA plus noise, positions in encoder counts (model-made data)."""
    robot = model_of(config.robot)
    scal = [axis_scaling(a) for a in config.robot.actuators]
    fpa = np.array([s.force_per_amp for s in scal])
    cpu = np.array([s.counts_per_unit for s in scal])
    truth = to_model.inertial_params(config.sim.truth)
    rng = np.random.default_rng(3)
    paths = []
    for planned in plan(config):
        tr = planned.trajectory
        tau = robot.inverse_dynamics(tr.X, tr.Xd, tr.Xdd, tr.zeta, tr.zetad, tr.zetadd, truth)
        ma = np.rint(tau / fpa * 1e3 + rng.normal(0.0, config.sim.current_noise * 1e3, tau.shape))
        n = len(tr.t)
        rec = Recording(t=tr.t - tr.t[0], cycle=np.arange(n), position=np.rint(tr.Theta * cpu) / cpu,
                        velocity=tr.Thetad, current=ma * 1e-3, statusword=np.zeros((n, 6), np.int32),
                        target=tr.Theta, valid=np.ones((n, 6), bool), metadata=RecordingMetadata(trajectory=tr.name))
        paths.append(rec.save(folder / f"{tr.name}.npz"))
    return paths


SWEEP_ONLY = f"""extends: {CONFIGS / 'sim-3prrr.yaml'}
bus: {{interface: virtual, channel: unused, sync_rate: 100.0}}
trajectories: [{{name: sweep, kind: carriage_sweep, size: 0.03}}]
identification:
  steps: [{{name: carriages, trajectories: [sweep],
           parameters: [m_c, fv_zeta1, fv_zeta2, fv_zeta3, fc_zeta1, fc_zeta2, fc_zeta3]}}]
  validation: []
  filter: {{bandwidth: 1.0}}
"""


def test_identify_and_report_from_recordings(tmp_path):
    path = tmp_path / "sweep.yaml"
    path.write_text(SWEEP_ONLY)    # one short sweep at 100 Hz, m_c and the carriage friction
    config = load_config(path)
    paths = synthetic_recordings(config, tmp_path)
    out = ident_hw("identify", path, *paths, "--out", tmp_path / "res", "--quiet")
    assert out.returncode == 0, out.stderr
    res = tmp_path / "res"
    # the terminal table shows parameters.json's identified value (not only the truth column)
    shown = next(line.split() for line in out.stdout.splitlines() if line.split()[:1] == ["m_c"])
    identified = json.loads((res / "parameters.json").read_text())["parameters"][0]
    assert identified["name"] == "m_c" and float(shown[3]) == pytest.approx(identified["identified"], rel=1e-4)
    assert (res / "STATUS").read_text().strip() == "complete"
    # the folder's config names its copy of the description file, the same bytes
    kept = load_config(res / "config.yaml")
    assert Path(kept.robot.description).read_bytes() == Path(config.robot.description).read_bytes()
    assert dataclasses.replace(kept, robot=dataclasses.replace(kept.robot, description=config.robot.description)) == config
    rows = {r["name"]: r for r in json.loads((res / "parameters.json").read_text())["parameters"]}
    assert rows["m_c"]["identified"] == pytest.approx(603.62, rel=0.01)
    assert rows["m_c"]["step"] == "carriages" and rows["m_l2"]["step"] == ""

    # the same recordings through the library give the same numbers
    direct = identify(config, {p.stem: Recording.load(p) for p in paths})
    assert rows["m_c"]["identified"] == pytest.approx(direct.parameters.identified[0], rel=1e-12)

    (res / "report.html").unlink()
    out = ident_hw("report", res)
    assert out.returncode == 0 and (res / "report.html").is_file()


def test_identify_with_a_missing_trajectory_fails_clearly(tmp_path):
    out = ident_hw("identify", CONFIGS / "sim-3prrr.yaml", tmp_path / "absent.npz", "--out", tmp_path / "res")
    assert out.returncode == 5 and "absent.npz" in out.stderr     # a data error
    assert not (tmp_path / "res").exists()


BASE_STEP = f"""extends: {CONFIGS / 'sim-3prrr.yaml'}
bus: {{interface: virtual, channel: unused, sync_rate: 250.0}}
trajectories:
  - {{name: excitation, kind: fourier}}
  - {{name: triangle, kind: triangle}}
identification:
  steps:
    - {{name: base, trajectories: [excitation], method: wls,
       parameters: [m_c, m_l1, I_l1, m_l2, I_l2, m_ee, I_ee, fv_theta1, fv_theta2, fv_theta3,
                    fv_zeta1, fv_zeta2, fv_zeta3, fc_theta1, fc_theta2, fc_theta3, fc_zeta1, fc_zeta2, fc_zeta3]}}
  validation: [triangle]
"""


def test_base_parameter_step_on_the_optimised_excitation(tmp_path):
    """Model-made recordings (true forces in whole mA plus noise, positions in counts): the WLS
    base parameters match the same combinations of the truth, and their prediction of the
    held-out triangle matches its measured forces."""
    path = tmp_path / "base.yaml"
    path.write_text(BASE_STEP)
    config = load_config(path)
    paths = synthetic_recordings(config, tmp_path)
    out = ident_hw("identify", path, *paths, "--out", tmp_path / "res", "--quiet")
    assert out.returncode == 0, out.stderr
    doc = json.loads((tmp_path / "res" / "parameters.json").read_text())
    base = doc["base_fit"]
    assert len(base["rows"]) == 18 and base["held"] == [] and base["unexcited"] == []
    H = np.array(base["H"])
    truth = to_model.inertial_params(config.sim.truth).as_vector()
    # 18 rows from one noise draw: each row's bound is the z of a 1 % family-wise false alarm
    # (Bonferroni, two-sided), fixed before looking at the draw; the sigma are calibrated in
    # test_ident_noise (RMS z 1.08 over 12 draws)
    z = norm.isf(0.01 / 2 / len(base["rows"]))
    for row, h in zip(base["rows"], H):
        assert row["truth"] == pytest.approx(h @ truth, rel=1e-12)
        if row["well_identified"]:
            assert abs(row["identified"] - row["truth"]) <= min(z * row["sigma"], 0.05 * abs(row["truth"])), row
    assert sum(r["well_identified"] for r in base["rows"]) >= 15
    assert all(not r["well_identified"] for r in base["rows"] if r["rel_sigma_percent"] > 10.0)
    metrics = yaml.safe_load((tmp_path / "res" / "metrics.yaml").read_text())
    assert metrics["triangle"]["role"] == "validation" and metrics["triangle"]["base_fit"]["d_tau_percent"] < 2.0
    assert "base parameters, WLS on excitation" in out.stdout
    # the step-by-step table fitted nothing here: every physical parameter is held
    assert all(r["step"] == "" for r in doc["parameters"])
