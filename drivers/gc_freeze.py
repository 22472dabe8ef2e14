"""Keeping Python's cyclic garbage collector out of the streaming loops.

A full (generation 2) collection walks every object the collector tracks and holds the GIL
meanwhile: with the 150k-230k objects of a campaign process it took 65-85 ms, during which no
thread runs: not the SYNC producer (python-can's periodic task then sends the missed SYNCs in a
burst), not the notifier that answers them. :func:`frozen_gc` collects once, then moves every
tracked object into the permanent generation (:func:`gc.freeze`), which later collections
ignore: inside the section they only walk the objects created in it, a few thousand at most as
long as the loops keep no per-cycle Python objects (see the bounded buffers of
:mod:`drivers.sim`). Cyclic garbage among the frozen objects is collected after the section.

:class:`GcPauses` measures the collections (``gc.callbacks``), for the run metadata, the tests and
the benchmarks.
"""

from __future__ import annotations

import gc
import threading
import time
from contextlib import contextmanager
from typing import Iterator

_lock = threading.Lock()
_depth = 0


@contextmanager
def frozen_gc() -> Iterator[None]:
    """Collect, freeze the tracked objects for the section, unfreeze after the outermost one.

    Nests (the in-process rig's serving and the master's streaming run): every entry collects
    and freezes what exists by then, only the last exit unfreezes. The entry's collection
    itself pauses the process (tens of ms): enter before the time-critical part starts.
    """
    global _depth
    with _lock:
        _depth += 1
        gc.collect()
        gc.freeze()
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                gc.unfreeze()


class GcPauses:
    """Durations of the garbage collections of the process while active (any thread).

    Use as a context manager; ``durations`` (s) and ``generations`` list the collections
    in order; ``longest`` is the longest one (0.0 when none).
    """

    def __init__(self) -> None:
        self.durations: list[float] = []
        self.generations: list[int] = []
        self._started: dict[int, float] = {}

    def _callback(self, phase: str, info: dict) -> None:
        now = time.perf_counter()
        thread = threading.get_ident()
        if phase == "start":
            self._started[thread] = now
        elif thread in self._started:
            self.durations.append(now - self._started.pop(thread))
            self.generations.append(info["generation"])

    @property
    def longest(self) -> float:
        return max(self.durations, default=0.0)

    def __enter__(self) -> "GcPauses":
        gc.callbacks.append(self._callback)
        return self

    def __exit__(self, *exc_info) -> None:
        gc.callbacks.remove(self._callback)
