"""The suite's own scheduling (tests/conftest.py): on two workers the tests sharing a module
fixture run on one worker, so the fixture (a whole campaign, for the main job's tests) is built
once. pytest 9.2 with pytest-xdist 3.8 lost the groups silently (pytest-xdist issue 1386)."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parent

PROBE = '''
import os
import pytest


@pytest.fixture(scope="module")
def shared():
    with open(os.environ["SETUPS"], "a") as f:
        f.write(os.environ.get("PYTEST_XDIST_WORKER", "-") + "\\n")


@pytest.mark.parametrize("k", range(6))
def test_uses_it(shared, k):
    pass


@pytest.mark.parametrize("k", range(6))
def test_does_not(k):
    pass
'''


def test_a_module_fixture_is_built_once_on_two_workers(tmp_path):
    for helper in ("conftest.py", "cpus.py", "processes.py"):
        shutil.copy(TESTS / helper, tmp_path / helper)
    (tmp_path / "test_probe.py").write_text(PROBE)
    setups = tmp_path / "setups.txt"
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "2", "--dist", "loadgroup",
                          "--no-loadscope-reorder", "-p", "no:cacheprovider", str(tmp_path)],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path,
                         env={**os.environ, "SETUPS": str(setups)})
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    assert "12 passed" in run.stdout
    assert len(setups.read_text().split()) == 1, setups.read_text()
