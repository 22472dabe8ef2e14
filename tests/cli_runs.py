"""``ident-hw`` as the tests run it: :func:`ident_hw.cli.main` in the test's own process.

A command run in a new process pays the imports of the whole pipeline again (NumPy, SciPy,
python-can, canopen, numba's cached functions, pinocchio: seconds each time), which the tests of
messages, exit codes and results folders do not need. :func:`ident_hw` runs the same ``main``
the ``ident-hw`` script runs, with the same arguments, in the given working directory, and
returns what a :func:`subprocess.run` would: the exit code and what the command printed. The
tests of what only a separate process shows (a signal, a killed run, the installed script) start
one themselves.
"""

from __future__ import annotations

import contextlib
import io
import os
from dataclasses import dataclass
from pathlib import Path

from ident_hw.cli import main


@dataclass(frozen=True)
class CliRun:
    """One ``ident-hw`` command: its arguments, exit code and output."""

    args: tuple[str, ...]
    returncode: int
    stdout: str
    stderr: str


def ident_hw(*args, cwd: Path | str | None = None) -> CliRun:
    """``ident-hw ARGS...`` run in ``cwd`` (this process's working directory restored after it).

    argparse's own exits (``--help``, an unknown option) give their exit code as the script's
    would: 0 and 2.
    """
    argv = [str(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    before = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(argv)
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        os.chdir(before)
    return CliRun(tuple(argv), int(code), out.getvalue(), err.getvalue())
