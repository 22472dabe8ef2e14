"""Checks of an ``ident-hw run`` against the simulated rig served by another process (``ident-hw
sim`` on ``vcan0`` or on ``udp_multicast``): its identification against the simulated truth, and
against the same config run with the rig in the master's process. Lazy imports: the vcan tests
run in a guest where numpy alone takes seconds."""

import subprocess
from pathlib import Path


def parameter_rows(folder: Path) -> dict:
    """The physical parameters of a results folder's ``parameters.json``, by name."""
    import json
    return {r["name"]: r for r in json.loads((folder / "parameters.json").read_text())["parameters"]}


def assert_step_identified(config, rows: dict) -> None:
    """The config's one identification step fitted every one of its parameters within 2 % of the
    simulated truth, or within 3 sigma where the data excite it less (the sweep's viscous friction:
    %sigma ~3)."""
    (step,) = config.identification.steps
    truth = dict(zip(config.robot.to_model().parameter_names, config.true_parameters()))
    for name in step.parameters:
        row = rows[name]
        assert row["step"] == step.name, name
        error = abs(row["identified"] - truth[name])
        assert error <= max(0.02 * abs(truth[name]), 3 * row["sigma"]), (name, row["identified"], truth[name])


def assert_same_in_one_process(config, config_path: Path, rows: dict, folder: Path, timeout: float) -> None:
    """The step's values in ``rows`` are those of the same config run with the rig in the master's
    process (:func:`rows_in_one_process` into ``folder``), exactly: in lockstep the process
    boundary, the sockets and the host's speed reach no sample."""
    alone = rows_in_one_process(config_path, folder, timeout)
    (step,) = config.identification.steps
    assert {p: rows[p]["identified"] for p in step.parameters} == {p: alone[p]["identified"] for p in step.parameters}


def rows_in_one_process(config_path: Path, folder: Path, timeout: float) -> dict:
    """``ident-hw run`` of ``config_path`` with the rig in the master's process (``virtual`` bus)
    into ``folder``, without its report; its :func:`parameter_rows`."""
    local = folder.with_suffix(".yaml")
    local.write_text(f"extends: {config_path}\nbus: {{interface: virtual, channel: in-process}}\n"
                     "sim: {in_process: true}\n")
    alone = subprocess.run(["ident-hw", "run", local, "--quiet", "--no-report", "--out", folder], capture_output=True,
                           text=True, timeout=timeout)
    assert alone.returncode == 0, alone.stderr
    return parameter_rows(folder)
