"""The suite's own scheduling and measuring (tests/conftest.py): on two workers the tests sharing a module
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


CPU_PROBE = '''
import subprocess
import sys
import time

BURN = "import time\\nt = time.process_time()\\nwhile time.process_time() - t < 0.6: pass"


def test_burns_in_a_child():
    subprocess.run([sys.executable, "-c", BURN], check=True)


def test_sleeps():
    time.sleep(0.6)
'''


def test_cpu_durations_count_the_child_processes_cpu_and_not_sleep(tmp_path):
    """``--cpu-durations`` on two workers: a test whose child process burns 0.6 s of CPU is listed
    with at least that (the child's own CPU clock), one that sleeps 0.6 s with less than half."""
    for helper in ("conftest.py", "cpus.py", "processes.py"):
        shutil.copy(TESTS / helper, tmp_path / helper)
    (tmp_path / "test_cpu_probe.py").write_text(CPU_PROBE)
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "2", "--cpu-durations=5", "-p", "no:cacheprovider",
                          str(tmp_path)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    listed = {line.split()[1].split("::")[-1]: float(line.split()[0].rstrip("s"))
              for line in run.stdout.splitlines() if "::test_" in line and line.split()[0].endswith("s")}
    assert listed["test_burns_in_a_child"] >= 0.6, run.stdout
    assert listed["test_sleeps"] < 0.3, run.stdout
    assert "s  in all (user + system, child processes included)" in run.stdout
