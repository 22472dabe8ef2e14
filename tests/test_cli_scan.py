"""``ident-hw scan``'s view of the NMT state, on a real python-can virtual bus with the emulated
drives: boot-up messages, heartbeats and SDO answers, never node guarding."""

from __future__ import annotations

import os
import threading
import time

from pathlib import Path

import canopen

from drivers.bus import open_network
from ident_hw.config import load_config
from ident_hw.experiment.inspection import nmt_state, read_node, scan
from ident_hw.experiment.session import simulated_rig
from ident_hw.config.to_drivers import bus_settings

SIM = Path(__file__).resolve().parent.parent / "configs" / "sim-3prrr.yaml"


def rig_config(tmp_path):
    path = tmp_path / "scan.yaml"
    path.write_text(f"extends: {SIM}\nbus: {{interface: virtual, channel: scan-{os.getpid()}-{time.monotonic_ns()}}}\n")
    return load_config(path)


def test_nmt_state_rules():
    assert nmt_state(0x7F, True, 100) == "PRE-OPERATIONAL"
    assert nmt_state(0x85, True, 100) == "OPERATIONAL"          # toggle bit masked
    assert nmt_state(0x00, True, 0) == "PRE-OPERATIONAL (boot-up seen)"
    assert nmt_state(None, True, 0) == "PRE-OPERATIONAL or OPERATIONAL (answers SDO; heartbeat off: 0x1017 = 0)"
    assert nmt_state(None, True, None).endswith("no heartbeat seen)")
    assert nmt_state(None, False, None).startswith("unknown")


def test_scan_sees_boot_ups_sdo_answers_and_a_stopped_node(tmp_path):
    config = rig_config(tmp_path)
    network = open_network(bus_settings(config.bus))
    rig = simulated_rig(config)
    try:
        # 1. the drives power up during the scan: found by their boot-up messages, which give the state
        boot = threading.Timer(0.2, rig.start)
        boot.start()
        heard = scan(network, wait=3.0)     # long enough for a loaded host (two test workers)
        boot.join()
        assert heard == {i: 0 for i in range(1, 7)}
        info = read_node(network, 4, heard[4], sdo_timeout=1.0)
        assert info.nmt_state == "PRE-OPERATIONAL (boot-up seen)" and info.vendor_id == 0xFB

        # 2. later (no boot-up seen, heartbeats off as after power-up): SDO answers say PRE-OP or OP
        heard = scan(network, wait=1.0)
        assert set(heard) == {1, 2, 3, 4, 5, 6} and set(heard.values()) == {None}
        info = read_node(network, 2, heard[2], sdo_timeout=1.0)
        assert info.nmt_state.startswith("PRE-OPERATIONAL or OPERATIONAL (answers SDO; heartbeat off")
        assert info.cia402_state == "SWITCH ON DISABLED"

        # 3. node 5 with a 50 ms heartbeat, then STOPPED: it no longer answers SDO, its heartbeat says so
        node = canopen.RemoteNode(5, canopen.ObjectDictionary())
        network.add_node(node)
        node.sdo.download(0x1017, 0, (50).to_bytes(2, "little"))
        node.nmt.send_command(0x02)
        time.sleep(0.2)
        heard = scan(network, wait=1.0)
        assert heard[5] == 4 and heard[1] is None
        info = read_node(network, 5, heard[5], sdo_timeout=0.2)
        assert info.nmt_state == "STOPPED" and info.device_name is None
    finally:
        network.disconnect()
        rig.stop()


def test_the_monitor_s_table_shows_a_drive_that_gave_no_answer_without_values():
    """A drive whose SDO reads failed shows its state text (why) and no values; one that answered
    shows them in SI, rounded as the header's columns say."""
    from ident_hw.experiment.inspection import DriveSnapshot, format_snapshot
    table = format_snapshot([DriveSnapshot("zeta1 (node 1)", "OPERATIONAL", "OPERATION ENABLED", 0.1234567, -0.5, 1.25),
                             DriveSnapshot("theta1 (node 4)", "PRE-OPERATIONAL", "no answer (SDO timeout)")])
    header, answered, silent = table.splitlines()
    assert header.split()[:4] == ["drive", "NMT", "CiA", "402"]
    assert answered.split()[-3:] == ["0.123457", "-0.50000", "1.250"] and "OPERATION ENABLED" in answered
    assert silent.endswith("PRE-OPERATIONAL                no answer (SDO timeout)") and "0." not in silent
