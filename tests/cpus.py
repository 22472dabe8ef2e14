"""The CPUs this test process may use, read before ``conftest`` pins a pytest-xdist worker to one of
them (see ``conftest.pytest_configure``): the affinity tests widen a pinned worker back to these."""

from __future__ import annotations

import os
from contextlib import contextmanager
from typing import Iterator

#: the CPU set the test process started with (empty where the platform cannot tell)
ALL_CPUS: frozenset[int] = frozenset(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else frozenset()


def pin_worker(worker: str) -> int | None:
    """Pin this pytest-xdist worker (``gw0``, ``gw1``, ...) to one CPU of :data:`ALL_CPUS`, worker
    ``gwN`` to the N-th (modulo their number), and return it; None where it cannot be done.

    Why: a lockstep cycle's threads run on one CPU (``drivers.affinity.one_cpu`` pins them to the
    CPU they run on). Two workers left to the kernel may both pin their lockstep runs to the same
    CPU while the other idles; pinned apart, each worker and every process it starts (Linux
    processes inherit the set) keeps a CPU of its own."""
    if len(ALL_CPUS) < 2 or not worker.startswith("gw"):
        return None
    cpu = sorted(ALL_CPUS)[int(worker[2:]) % len(ALL_CPUS)]
    os.sched_setaffinity(0, {cpu})
    return cpu


@contextmanager
def all_cpus() -> Iterator[None]:
    """Widen the calling thread to :data:`ALL_CPUS` for the section (a pinned worker's affinity
    tests need more than one CPU), then restore its set."""
    before = os.sched_getaffinity(0)
    os.sched_setaffinity(0, ALL_CPUS)
    try:
        yield
    finally:
        os.sched_setaffinity(0, before)
