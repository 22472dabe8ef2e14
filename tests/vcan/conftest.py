"""Fixtures of the vcan tests: other processes on the SocketCAN bus, and a ``candump -L`` recording.

Everything here runs inside the emulated guest of ``tools/vcan-vm``, where Python is ~25 times
slower than on a host (``import can, canopen`` ~7 s, ``numpy``+``scipy`` ~25 s): hence the generous
time limits (:mod:`processes`). They bound a hang, they do not judge speed.
"""

import subprocess
import sys
import time
from pathlib import Path

import can
import pytest

from processes import START_TIMEOUT, STOP_TIMEOUT, stop_process, wait_for_line

VCAN_CHANNEL = "vcan0"
VCAN_CONFIG = Path(__file__).parents[2] / "configs" / "vcan-3prrr.yaml"
PEERS = Path(__file__).with_name("peers.py")
MARKER_ID = 0x7FF  # frame the candump fixture sends until it sees it, to know candump is listening


def start_peer(start_process, *args: str) -> subprocess.Popen:
    """Start ``peers.py ARGS...`` with ``start_process``."""
    return start_process([sys.executable, PEERS, *args], "ready")


class CandumpLog:
    """``candump -L`` of ``vcan0`` running into a file, read back with python-can's log reader."""

    def __init__(self, path: Path):
        self.path = path
        self._file = open(path, "w")
        self._proc = subprocess.Popen(["candump", "-L", VCAN_CHANNEL], stdout=self._file,
                                      stderr=subprocess.PIPE, text=True)

    def messages(self) -> list:
        """The frames logged so far (``can.Message``, ``channel`` = interface name), marker frames left out."""
        return [msg for msg in can.CanutilsLogReader(self.path) if msg.arbitration_id != MARKER_ID]

    def lines(self) -> list:
        """The raw lines logged so far."""
        return self.path.read_text().splitlines()

    def wait_for(self, predicate, timeout: float) -> can.Message:
        """The first logged frame for which ``predicate(msg)`` holds, waiting up to ``timeout`` s for it."""
        deadline = time.monotonic() + timeout
        while True:
            found = [msg for msg in self.messages() if predicate(msg)]
            if found:
                return found[0]
            if time.monotonic() > deadline:
                pytest.fail(f"no such frame in candump's log within {timeout} s; log:\n" + "\n".join(self.lines()))
            time.sleep(0.2)

    def wait_listening(self, timeout: float) -> None:
        """Send marker frames until candump has logged one (it is then listening)."""
        deadline = time.monotonic() + timeout
        with can.Bus(interface="socketcan", channel=VCAN_CHANNEL) as bus:
            while f"{MARKER_ID:03X}#" not in self.path.read_text():
                if self._proc.poll() is not None or time.monotonic() > deadline:
                    self.stop()
                    pytest.fail(f"candump did not log on {VCAN_CHANNEL} within {timeout} s "
                                f"(exit code {self._proc.returncode}): {self._proc.stderr.read()}")
                bus.send(can.Message(arbitration_id=MARKER_ID, is_extended_id=False, data=b""))
                time.sleep(0.2)

    def stop(self) -> None:
        if self._proc.poll() is None:
            self._proc.terminate()
            self._proc.wait(STOP_TIMEOUT)
        self._file.close()


@pytest.fixture
def candump(tmp_path):
    """A running ``candump -L vcan0`` (started before the test's other processes) and its log."""
    log = CandumpLog(tmp_path / "candump.log")
    try:
        log.wait_listening(START_TIMEOUT)
        yield log
    finally:
        log.stop()


@pytest.fixture(scope="module")
def vcan_rig():
    """``ident-hw sim configs/vcan-3prrr.yaml``: the simulated rig of the vcan config (lockstep) on
    vcan0, started once for a module's tests (a start takes minutes in the guest: the plant's
    imports) and stopped after them (another module's rig has the same node-IDs). Yields the
    config's path. The tests leave its plant where it was: an SDO
    upload moves nothing, and one lockstep run steps it."""
    proc = subprocess.Popen(["ident-hw", "sim", str(VCAN_CONFIG)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        wait_for_line(proc, "simulated rig:", START_TIMEOUT)
        yield VCAN_CONFIG
    finally:
        stop_process(proc)
