"""Checks of an ``ident-hw run`` against the simulated rig served by another process (``ident-hw
sim`` on ``vcan0`` or on ``udp_multicast``): its identification against the simulated truth, and
against the same config run with the rig in the master's process. Lazy imports: the vcan tests
run in a guest where numpy alone takes seconds."""

import subprocess
from pathlib import Path
from ident_hw.config.robots import model_of, true_parameters


def parameter_rows(folder: Path) -> dict:
    """The physical parameters of a results folder's ``parameters.json``, by name."""
    import json
    return {r["name"]: r for r in json.loads((folder / "parameters.json").read_text())["parameters"]}


def assert_step_identified(config, rows: dict) -> None:
    """The config's one identification step fitted every one of its parameters within 2 % of the
    simulated truth, or within 3 sigma where the data excite it less (the sweep's viscous friction:
    %sigma ~3)."""
    (step,) = config.identification.steps
    truth = dict(zip(model_of(config.robot).parameter_names, true_parameters(config)))
    for name in step.parameters:
        row = rows[name]
        assert row["step"] == step.name, name
        error = abs(row["identified"] - truth[name])
        assert error <= max(0.02 * abs(truth[name]), 3 * row["sigma"]), (name, row["identified"], truth[name])


class RunInOneProcess:
    """``ident-hw run`` of ``config_path`` with the rig in the master's process (``virtual`` bus)
    into ``folder``, without its report, started at once in the background (:meth:`rows` waits
    for it): a test starts it before its own run, which it overlaps (the vcan guest has two CPUs
    and a lockstep run keeps about one busy)."""

    def __init__(self, config_path: Path, folder: Path):
        self.folder = folder
        local = folder.with_suffix(".yaml")
        local.write_text(f"extends: {config_path}\nbus: {{interface: virtual, channel: in-process}}\n"
                         "sim: {in_process: true}\n")
        self.process = subprocess.Popen(["ident-hw", "run", local, "--quiet", "--no-report", "--out", folder],
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def stop(self) -> None:
        """End it if it still runs (a test's finalizer: the test failed before :meth:`rows`)."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.communicate()

    def rows(self, timeout: float) -> dict:
        """Its :func:`parameter_rows`, once it has ended (and passed)."""
        try:
            _, err = self.process.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            raise
        assert self.process.returncode == 0, err
        return parameter_rows(self.folder)


def assert_same_in_one_process(config, rows: dict, alone: dict) -> None:
    """The step's values in ``rows`` are those of the same config run with the rig in the master's
    process (``alone``, :class:`RunInOneProcess`), exactly: in lockstep the process boundary, the
    sockets and the host's speed reach no sample."""
    (step,) = config.identification.steps
    assert {p: rows[p]["identified"] for p in step.parameters} == {p: alone[p]["identified"] for p in step.parameters}
