"""The rig of the vcan config served by ``ident-hw sim`` in one process (``vcan_rig``, started
once for this module), ``candump -L`` recording: can-utils' raw SDO upload against it, then the
CLI as a user runs it, ``ident-hw scan`` and a short ``ident-hw run`` (without the report, which the
host suite checks: matplotlib and eight plots cost minutes in the emulated guest) in other processes."""

import subprocess
import time

import pytest

from rig_runs import RunInOneProcess, assert_same_in_one_process, assert_step_identified, parameter_rows

from .conftest import VCAN_CHANNEL, VCAN_CONFIG as CONFIG
from ident_hw.config.to_drivers import axis_config

pytestmark = pytest.mark.vcan

NODE_ID = 1  # the first of the rig's six drives (theta1, an EPOS4)
SDO_TIMEOUT = 30.0  # s; the emulated drive answers from a Python thread in a slow guest
CLI_TIMEOUT = 600.0  # s; numpy/scipy/matplotlib alone take a minute to import in the emulated guest


def test_cansend_sdo_upload_of_vendor_id(vcan_rig, candump):
    # CiA 301 SDO initiate upload request (ccs=2 -> 0x40) for index 0x1018 (little endian), subindex 1
    subprocess.run(["cansend", VCAN_CHANNEL, f"{0x600 + NODE_ID:03X}#4018100100000000"], check=True, timeout=30)

    request = candump.wait_for(lambda m: m.arbitration_id == 0x600 + NODE_ID, SDO_TIMEOUT)
    reply = candump.wait_for(lambda m: m.arbitration_id == 0x580 + NODE_ID, SDO_TIMEOUT)
    assert request.channel == reply.channel == VCAN_CHANNEL
    assert not reply.is_extended_id and not reply.is_remote_frame
    assert reply.timestamp > request.timestamp
    assert reply.dlc == 8
    data = bytes(reply.data)
    # 0x43: scs=2 (initiate upload response), e=1 (expedited), s=1 (size indicated), n=0 (4 bytes)
    assert data[0] == 0x43
    assert data[1] == 0x18 and data[2] == 0x10  # index 0x1018, little endian
    assert data[3] == 0x01  # subindex
    assert data[4:8] == bytes([0xFB, 0x00, 0x00, 0x00])  # vendor ID 0x000000FB (maxon), little endian
    # and exactly as can-utils prints it
    assert any(line.endswith(f" {VCAN_CHANNEL} {0x580 + NODE_ID:03X}#43181001FB000000") for line in candump.lines())


def test_cli_run_against_rig_process_matches_candump(vcan_rig, candump, tmp_path, request):
    # imported here, not at collection: numpy/scipy cost ~25 s in the guest even when the test is skipped
    import numpy as np

    from drivers.acquisition import master_layouts
    from drivers.recording import Recording, decode_log
    from ident_hw.config import load_config

    config = load_config(CONFIG)
    actuators = config.robot.actuators
    # the same config with the rig in the master's process, meanwhile (the guest's second CPU)
    alone = RunInOneProcess(CONFIG, tmp_path / "alone")
    request.addfinalizer(alone.stop)

    started = time.monotonic()
    scan = subprocess.run(["ident-hw", "scan", CONFIG, "--wait", "3"], capture_output=True, text=True,
                          timeout=CLI_TIMEOUT)
    print(f"\n$ ident-hw scan  ({time.monotonic() - started:.0f} s)\n{scan.stdout}{scan.stderr}")
    assert scan.returncode == 0, scan.stderr
    for actuator in actuators:
        assert f"node {actuator.node_id:3d}: EPOS4" in scan.stdout, f"scan did not list node {actuator.node_id}"
    assert "matches the config" in scan.stdout and "PRE-OPERATIONAL" in scan.stdout

    out = tmp_path / "results"
    run = subprocess.run(["ident-hw", "run", CONFIG, "--quiet", "--no-report", "--out", out],
                         capture_output=True, text=True, timeout=CLI_TIMEOUT)
    print(f"$ ident-hw run  ({time.monotonic() - started:.0f} s since the scan began)\n{run.stdout}{run.stderr}")
    assert run.returncode == 0, run.stderr
    assert (out / "STATUS").read_text().strip() == "complete"
    (traj,) = config.trajectories
    recorded = Recording.load(out / "data" / f"{traj.name}.npz")
    n = recorded.metadata.n_cycles
    print(f"recorded {n} cycles at {config.bus.sync_rate:g} Hz in {recorded.metadata.sync}, "
          f"{recorded.n_invalid} incomplete, cycles asked again {recorded.metadata.sync_report.lockstep_retries}")
    assert recorded.metadata.sync == "lockstep" and recorded.n_invalid == 0
    # the identification is right, and it is the answer of the same config with the rig in the master's
    # process (lockstep: the process boundary, the kernel's sockets and the guest's speed reach no sample)
    rows = parameter_rows(out)
    assert_step_identified(config, rows)
    assert_same_in_one_process(config, rows, alone.rows(CLI_TIMEOUT))
    print(f"the same run with the rig in one process had ended {time.monotonic() - started:.0f} s after the scan began")

    # candump saw the same frames on the bus: the project's decoder gives the same samples from candump's log,
    # from where the run's own raw log starts (the master records from the start of the stream; the kernel
    # delivers frames in one order to every socket, so the run's first frames stand in candump as a block).
    import can

    own_log = out / "data" / f"{traj.name}{config.output.raw_log}"
    own = [(m.arbitration_id, bytes(m.data)) for m in can.LogReader(own_log)]
    whole = tmp_path / "candump-session.log"
    whole.write_text("\n".join(candump.lines()) + "\n")
    dumped_msgs = list(can.LogReader(whole))
    frames = [(m.arbitration_id, bytes(m.data)) for m in dumped_msgs]
    block = min(50, len(own))
    starts = [i for i, frame in enumerate(frames) if frame == own[0] and frames[i:i + block] == own[:block]]
    assert len(starts) == 1, f"the run's first {block} frames stand {len(starts)} times in candump's log"
    dumped = tmp_path / "candump-run.log"
    with can.Logger(dumped) as writer:
        for msg in dumped_msgs[starts[0]:]:
            writer.on_message_received(msg)
    # The frames are the same: per CAN-ID (one sender each, so FIFO) the run's frames stand in candump's log
    # as one unbroken run, byte for byte: nothing lost, nothing altered.
    def by_id(seq):
        out = {}
        for cob, data in seq:
            out.setdefault(cob, []).append(data)
        return out

    dumped_by_id = by_id(frames[starts[0]:])
    for cob, seq in by_id(own).items():
        full = dumped_by_id.get(cob, [])
        assert full[:len(seq)] == seq, f"0x{cob:03X}: the run's {len(seq)} frames are not candump's first ones"
    # The samples are the same wherever both observers assembled them. Which cycle a frame falls in depends
    # on where it stands against the SYNC frames; the master's socket gets its own SYNC and RPDO frames
    # looped back, so near a SYNC boundary its interleaving can differ from candump's: a cell one observer
    # assembled may be incomplete for the other, and a set-point may count from the neighbouring cycle.
    dumped_axes = [axis_config(a) for a in actuators]
    decoded = decode_log(dumped, dumped_axes, max_cycles=n, layouts=master_layouts(dumped_axes),
                         layout_source="the master's")
    np.testing.assert_array_equal(decoded.cycle, recorded.cycle)
    both = decoded.valid & recorded.valid
    # at least half of the master's cells are compared, so the comparison cannot pass on nothing
    assert both.sum() >= recorded.valid.sum() // 2, f"only {both.sum()} cells assembled by both observers"
    for name in ("position", "velocity", "current"):
        np.testing.assert_array_equal(getattr(decoded, name)[both], getattr(recorded, name)[both], err_msg=name)
    print(f"cells assembled: by the master {recorded.valid.sum()}, from candump {decoded.valid.sum()}, "
          f"by both {both.sum()} of {recorded.valid.size}")
    # and the run's own raw CAN log decodes to its recording as well
    replayed = decode_log(own_log, [axis_config(a) for a in actuators], max_cycles=n)
    for name in ("cycle", "position", "current", "statusword", "target", "valid"):
        np.testing.assert_array_equal(getattr(replayed, name), getattr(recorded, name), err_msg=name)
