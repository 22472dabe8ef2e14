"""SIGINT (Ctrl-C), SIGTERM and SIGHUP, all handled like Ctrl-C, once.

    with stop_on_signals():
        run_campaign(...)        # the first signal raises Interrupted in the main thread

The first signal raises :class:`Interrupted` (a :class:`KeyboardInterrupt`, so every path that
stops the drives on Ctrl-C stops them on it too). Any further signal while the context is
active is reported and otherwise ignored: the shutdown it would interrupt (quick stop, disable,
saving the recordings, writing STATUS and ``drives.json``) runs to its end, so the results
folder stays consistent. A first signal inside a :func:`shielded` block (stopping the drives,
reading their states) waits for the block's end. Only SIGKILL can end the process earlier.
"""

from __future__ import annotations

import signal
import sys
import threading
from contextlib import contextmanager
from typing import Callable, Iterator

#: the signals handled, and the name each gives to the stop
SIGNAL_NAMES = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM", signal.SIGHUP: "SIGHUP"}


class Interrupted(KeyboardInterrupt):
    """The process was asked to stop by ``signal_name`` (``Ctrl-C``, ``SIGTERM`` or ``SIGHUP``)."""

    def __init__(self, signal_name: str):
        super().__init__(f"interrupted ({signal_name})")   # what a recording stopped by it says
        self.signal_name = signal_name


def signal_name(exc: BaseException) -> str:
    """The name of the signal behind a KeyboardInterrupt (a plain one is Ctrl-C)."""
    return getattr(exc, "signal_name", "Ctrl-C")


def _to_stderr(message: str) -> None:
    try:
        print(message, file=sys.stderr, flush=True)
    except (OSError, ValueError):   # the terminal is gone (SIGHUP) or stderr closed
        pass


class _State:
    """The handler's memory while :func:`stop_on_signals` is active (main thread only)."""

    first: str | None = None      # the signal that stopped the process
    shield: int = 0               # depth of :func:`shielded` blocks being run
    pending: str | None = None    # a first signal that arrived inside a shielded block


@contextmanager
def stop_on_signals(say: Callable[[str], None] = _to_stderr, restore: bool = True) -> Iterator[None]:
    """Handle :data:`SIGNAL_NAMES` as described in the module docstring while active (main
    thread only; elsewhere a no-op); the previous handlers come back at the end, unless not
    ``restore``: a process that exits right after keeps them, so a second signal that comes
    while it exits is still reported and ignored, and does not kill it with its own exit status."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _State.first, _State.shield, _State.pending = None, 0, None

    def handler(signum, _frame) -> None:
        name = SIGNAL_NAMES.get(signum, f"signal {signum}")
        if _State.first is None:
            _State.first = name
            if _State.shield:
                _State.pending = name
                say(f"{name}: stopping once the drives are stopped and their states saved")
                return
            raise Interrupted(name)
        say(f"{name}: already stopping after {_State.first}: the drives are being stopped and the data saved")

    previous = {sig: signal.signal(sig, handler) for sig in SIGNAL_NAMES}
    try:
        yield
    finally:
        if restore:
            for sig, old in previous.items():
                signal.signal(sig, old)
            _State.first, _State.shield, _State.pending = None, 0, None


@contextmanager
def shielded() -> Iterator[None]:
    """A block the first signal does not interrupt (stopping and disabling the drives, writing
    their states): the signal is raised as :class:`Interrupted` when the block ends, unless an
    exception is already on its way out."""
    _State.shield += 1
    try:
        yield
    finally:
        _State.shield -= 1
        pending, _State.pending = _State.pending, None
    if pending is not None and not _State.shield:
        raise Interrupted(pending)
