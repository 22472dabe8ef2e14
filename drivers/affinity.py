"""Keeping the threads of a lockstep cycle on one CPU.

A lockstep cycle with the rig in the same process hands the GIL from thread to thread several
times (the master's stream, its notifier, the rig's notifier, its clock): each hand-off wakes a
thread blocked on a lock. When the woken thread sits on another CPU that is idle, the wake-up
costs an inter-processor interrupt and the idle CPU's exit from its sleep state (on a virtual
machine, an exit to the hypervisor), paid by the waking thread while it holds the GIL. The GIL
lets only one of those threads run Python at a time anyway, so :func:`one_cpu` confines the
calling thread, and every thread it starts inside the section (Linux threads inherit their
creator's CPU set), to one CPU. What the threads compute does not change, only how fast. Linux
only (``os.sched_setaffinity``); elsewhere it does nothing.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from typing import Iterator


@contextmanager
def one_cpu() -> Iterator[int | None]:
    """Run the calling thread (and the threads it starts meanwhile) on one CPU of those it may use:
    the one it runs on now, where the kernel's load balancing put it (two runs started side by side
    then mostly end up on different CPUs; a fixed choice would put both on the same one).

    Yields that CPU's number, or ``None`` where affinity cannot be set (not Linux, a single CPU
    allowed, or the call refused); the previous CPU set is restored on exit.
    """
    try:
        allowed = os.sched_getaffinity(0)
    except (AttributeError, OSError):
        yield None
        return
    if len(allowed) < 2:
        yield None
        return
    cpu = _current_cpu()
    if cpu not in allowed:
        cpu = min(allowed)
    try:
        os.sched_setaffinity(0, {cpu})
    except OSError:
        yield None
        return
    try:
        yield cpu
    finally:
        os.sched_setaffinity(0, allowed)


def _current_cpu() -> int | None:
    """The CPU the calling thread last ran on (field 39 of ``/proc/thread-self/stat``), None if unknown."""
    try:
        with open("/proc/thread-self/stat") as stat:
            return int(stat.read().rsplit(")", 1)[1].split()[36])
    except (OSError, IndexError, ValueError):
        return None
