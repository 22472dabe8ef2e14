"""Other processes of a test (the simulated rig served by ``ident-hw sim``, a peer on the bus):
started, waited for until they say they are ready, stopped. The time limits bound a hang, they
do not judge speed: they hold in the emulated guest of ``tools/vcan-vm`` too, where Python is
~25 times slower than on a host."""

import select
import subprocess
import time

import pytest

START_TIMEOUT = 600.0  # s until a started process is listening on the bus (the guest compiles the plant: minutes)
STOP_TIMEOUT = 30.0  # s for a process to end once asked to


def wait_for_line(proc: subprocess.Popen, prefix: str, timeout: float) -> None:
    """Read ``proc``'s stdout lines until one starts with ``prefix``; fail with its stderr otherwise."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        readable, _, _ = select.select([proc.stdout], [], [], 0.2)
        if readable:
            line = proc.stdout.readline()
            if line.startswith(prefix):
                return
            if not line:  # EOF: the process ended
                break
    proc.kill()
    _, err = proc.communicate()
    pytest.fail(f"{proc.args} did not print {prefix!r} within {timeout} s (exit code {proc.returncode}); "
                f"stderr:\n{err}")


def stop_process(proc: subprocess.Popen) -> None:
    """End ``proc`` with SIGTERM (killing it if it does not end within STOP_TIMEOUT) and reap it."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.communicate(timeout=STOP_TIMEOUT)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
