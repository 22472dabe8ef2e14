"""The Delta's job end to end: ``ident-hw run configs/sim-delta.yaml`` (three emulated EPOS4
drives behind the Delta's dynamics, the SVD-DLS paper's training and verification paths, the
base parameters by least squares).

The base parameters are checked against the spec's readable set (``docs/delta-model.md``) and
their values against the config's true parameters through that set's ``H``, not against the
truth column the run writes."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np

from ident_hw.config import load_config
from ident_hw.identification.base_params import format_combination
from ident_hw.model.delta import PARAM_NAMES, base_parameters

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "sim-delta.yaml"
#: the accuracy claimed where the estimate's own statistics support it (%sigma at most 1 %)
ACCURATE = 2.0


def test_the_delta_job_identifies_the_specs_base_parameters(tmp_path):
    out = tmp_path / "delta"
    run = subprocess.run(["ident-hw", "run", str(CONFIG), "--quiet", "--out", str(out)],
                         capture_output=True, text=True, timeout=600)
    print(run.stdout[-3000:])
    assert run.returncode == 0, run.stderr + run.stdout[-2000:]
    assert (out / "STATUS").read_text().strip() == "complete"
    doc = json.loads((out / "parameters.json").read_text())
    assert [a["name"] for a in doc["actuators"]] == ["q1", "q2", "q3"]
    # the spec's 40 readable base parameters, in its basis
    spec = base_parameters(load_config(CONFIG).robot.delta.geometry.to_model(), drive_terms=True)
    rows = doc["base_fit"]["rows"]
    assert [r["base_parameter"] for r in rows] == [format_combination(h, PARAM_NAMES) for h in spec.H]
    # against the config's truth through the spec's H
    truth = spec.H @ load_config(CONFIG).true_parameters()
    accurate = 0
    for row, true in zip(rows, truth):
        if row["well_identified"] and row["rel_sigma_percent"] <= 1.0:
            accurate += 1
            error = 100 * (row["identified"] - true) / abs(true)
            assert abs(error) <= ACCURATE, (row["base_parameter"], row["identified"], true)
    assert accurate >= 15
    # every parameter the spec's regressor leaves out is reported as not excited
    assert set(doc["base_fit"]["unexcited"]) == {PARAM_NAMES[j] for j in np.flatnonzero(~spec.H.any(axis=0))}
