"""A results folder's ``STATUS``: one line saying where its run is, written atomically.

``running``, ``identifying``, then ``complete`` (the quality verdict passed), ``degraded:
<reasons>`` (it did not), ``partial: <why>`` after a fault or a signal, ``failed: <why>`` when
nothing could be identified. The runner (:mod:`ident_hw.experiment.runner`) is the one writer.
"""

from __future__ import annotations

from pathlib import Path

from ident_hw.storage import write_atomically

from .objects import Results

STATUS_FILE = "STATUS"


def mark_status(folder: str | Path, status: str) -> None:
    """Write STATUS (see the module docstring), atomically: a reader never sees half of it."""
    write_atomically(Path(folder, STATUS_FILE), status.strip() + "\n")


def final_status(results: Results) -> str:
    """``complete`` when the quality verdict passed (or there is none), else ``degraded: <reasons>``."""
    if results.quality is None or results.quality.passed:
        return "complete"
    return "degraded: " + "; ".join(results.quality.reasons)


def read_status(folder: str | Path) -> str:
    """The STATUS line of ``folder`` (``unknown (no STATUS file)`` without one)."""
    path = Path(folder, STATUS_FILE)
    return path.read_text().strip() if path.is_file() else "unknown (no STATUS file)"
