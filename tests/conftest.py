"""Test-suite wide pytest hooks.

``@pytest.mark.vcan`` tests need the Linux SocketCAN interface ``vcan0``; where it does not exist
they are skipped with the reason. ``tools/vcan-vm`` runs them in a guest that has it (``.ci/run``
does so after the host suite).
"""

from pathlib import Path

import pytest

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
