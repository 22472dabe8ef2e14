"""can-utils against the simulated rig: a raw SDO upload of a drive's identity vendor ID."""

import subprocess
from pathlib import Path

import pytest

from .conftest import VCAN_CHANNEL

pytestmark = pytest.mark.vcan

CONFIG = Path(__file__).parents[2] / "configs" / "vcan-3prrr.yaml"
NODE_ID = 1  # the first of the rig's six drives (theta1, an EPOS4)
SDO_TIMEOUT = 30.0  # s; the emulated drive answers from a Python thread in a slow guest


def test_cansend_sdo_upload_of_vendor_id(start_process, candump):
    start_process(["ident-hw", "sim", str(CONFIG)], ready="simulated rig:")
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
