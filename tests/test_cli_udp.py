"""The rig in its own process on a host without SocketCAN (``configs/udp-3prrr.yaml``): ``ident-hw sim``
and ``ident-hw run`` meet on python-can's ``udp_multicast`` bus, on an interface-local IPv6 group (loopback only, so a
bus that cannot reach hardware: lockstep, no --arm). UDP may drop a frame; lockstep asks the cycle
again, so the answer is the one of the same config with the rig in the master's process."""

import socket
import subprocess
from pathlib import Path

import pytest

from rig_runs import RunInOneProcess, assert_same_in_one_process, assert_step_identified, parameter_rows
from udp_groups import interface_local_group, loopback_multicast_works

pytest.importorskip("msgpack", reason="python-can's udp_multicast interface needs msgpack (pip install -e '.[test]')")

CONFIGS = Path(__file__).resolve().parent.parent / "configs"
RUN_TIMEOUT = 300.0  # s, bounds a hang


@pytest.mark.slow
def test_run_against_the_rig_in_another_process_over_udp_gives_the_in_process_answer(start_process, tmp_path):
    from drivers.recording import Recording
    from ident_hw.config import load_config

    group = interface_local_group()
    if not socket.has_ipv6 or not loopback_multicast_works(group):
        pytest.skip(f"this host does not loop IPv6 multicast back to its own sockets ({group})")
    config_path = tmp_path / "udp.yaml"     # the shipped config on a group of its own
    config_path.write_text(f"extends: {CONFIGS / 'udp-3prrr.yaml'}\nbus: {{channel: '{group}'}}\n")
    config = load_config(config_path)
    assert config.simulated and config.sync_mode == "lockstep"
    start_process(["ident-hw", "sim", config_path], ready="simulated rig:")
    run = subprocess.run(["ident-hw", "run", config_path, "--quiet", "--no-report", "--out", tmp_path / "udp"],
                         capture_output=True, text=True, timeout=RUN_TIMEOUT)
    print(f"$ ident-hw run (rig in another process, udp_multicast)\n{run.stdout}{run.stderr}")
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "udp" / "STATUS").read_text().strip() == "complete"
    (traj,) = config.trajectories
    recorded = Recording.load(tmp_path / "udp" / "data" / f"{traj.name}.npz")
    assert recorded.metadata.sync == "lockstep" and recorded.n_invalid == 0
    print(f"cycles asked again (frames UDP dropped, or a slow rig): {recorded.metadata.sync_report.lockstep_retries}")

    rows = parameter_rows(tmp_path / "udp")
    assert_step_identified(config, rows)
    assert_same_in_one_process(config, rows, RunInOneProcess(config_path, tmp_path / "alone").rows(RUN_TIMEOUT))
