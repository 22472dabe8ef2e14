"""A raw CAN log made lossy on purpose: frames of a seeded share of its SYNC cycles left out, as a
bus that loses frames would (a TPDO that never arrives), to test what the master and the
identification keep of such a run."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import can
import numpy as np

from drivers.acquisition import AxisLayout
from drivers.cia import SYNC_COB_ID
from drivers.recording import FlushingLogger


@dataclass(frozen=True)
class Dropped:
    """What :func:`drop_frames` left out: ``cycles`` (the cycles that lost a frame, sorted) and
    ``frames`` ((cycle, COB-ID) of every frame left out), and of those cycles the ones whose lost
    frame carried a position or a current (``measured``) or not (``others``: velocity,
    statusword)."""

    cycles: np.ndarray
    frames: tuple[tuple[int, int], ...]
    measured: np.ndarray
    others: np.ndarray


def drop_frames(source: Path, out: Path, layouts: Sequence[AxisLayout], fraction: float, n_cycles: int,
                seed: int = 0) -> Dropped:
    """Copy the raw log ``source`` to ``out`` (with its sidecar of ``layouts``) without one
    SYNC-triggered TPDO frame in each of ``round(fraction * n_cycles)`` cycles among the first
    ``n_cycles``, the cycles and the frames (any TPDO of any axis, alike) drawn with ``seed``.

    A cycle is what follows a SYNC up to the next SYNC with another counter (a lockstep retry
    repeats the counter: the same cycle).
    """
    tpdos = [(f.cob_id(a.node_id), {name for name, _ in f.entries})
             for a in layouts for f in a.frames if f.direction == "tpdo" and f.per_sync]
    rng = np.random.default_rng(seed)
    cycles = np.sort(rng.choice(n_cycles, round(fraction * n_cycles), replace=False))
    victims = {int(k): tpdos[int(rng.integers(len(tpdos)))] for k in cycles}
    dropped, measured, others = [], [], []
    logger = FlushingLogger(out, layouts=layouts)
    cycle, counter = -1, object()
    try:
        with can.LogReader(source) as reader:
            for msg in reader:
                if msg.arbitration_id == SYNC_COB_ID and not msg.is_remote_frame:
                    new = msg.data[0] if len(msg.data) else None
                    if new is None or new != counter:
                        cycle += 1
                    counter = new
                victim = victims.get(cycle)
                if victim is not None and msg.arbitration_id == victim[0]:
                    dropped.append((cycle, msg.arbitration_id))
                    (measured if victim[1] & {"position", "current"} else others).append(cycle)
                    del victims[cycle]     # one frame per cycle (a lockstep retry's copy stays)
                    continue
                logger.on_message_received(msg)
    finally:
        logger.stop()
    return Dropped(cycles, tuple(dropped), np.array(sorted(measured), dtype=int), np.array(sorted(others), dtype=int))
