"""Test-suite wide pytest hooks.

``@pytest.mark.vcan`` tests need the Linux SocketCAN interface ``vcan0``; where it does not exist
they are skipped with the reason. ``tools/vcan-vm`` runs them in a guest that has it (``.ci/run``
does so after the host suite).
"""

import subprocess
from pathlib import Path

import pytest

from processes import START_TIMEOUT, stop_process, wait_for_line

VCAN_CHANNEL = "vcan0"


def pytest_collection_modifyitems(config, items):
    if Path("/sys/class/net", VCAN_CHANNEL).exists():
        return
    skip = pytest.mark.skip(
        reason=f"no SocketCAN interface {VCAN_CHANNEL} (/sys/class/net/{VCAN_CHANNEL} missing); "
        f"run them with: tools/vcan-vm -- python -m pytest -m vcan tests/vcan"
    )
    for item in items:
        if item.get_closest_marker("vcan"):
            item.add_marker(skip)


@pytest.fixture
def start_process():
    """``start(argv, ready)`` runs ``argv`` as another process and returns it once it printed a line
    starting with ``ready`` (it is then on the bus); all are stopped after the test."""
    procs = []

    def start(argv: list, ready: str) -> subprocess.Popen:
        proc = subprocess.Popen([str(arg) for arg in argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        procs.append(proc)
        wait_for_line(proc, ready, START_TIMEOUT)
        return proc

    yield start
    for proc in procs:
        stop_process(proc)
