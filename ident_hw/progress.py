"""How far a long step has come, reported through :mod:`logging`: the library logs, the command
line shows (``ident-hw`` turns these records into progress bars, :mod:`ident_hw.cli`).

A record of progress is a ``DEBUG`` record whose ``progress`` attribute is a :class:`Progress`;
a program that logs at ``DEBUG`` sees it as a line (``encoder draws: 3 of 8 draw``). Nothing is
reported to a logger no handler listens to (``logging``'s own test), so a library call costs
nothing when nobody watches.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass


@dataclass(frozen=True)
class Progress:
    """``done`` of ``total`` ``unit`` of the step ``what`` (``done == total``: it ended)."""

    what: str
    done: int
    total: int
    unit: str = ""

    @property
    def finished(self) -> bool:
        return self.done >= self.total


def report_progress(logger: logging.Logger, what: str, done: int, total: int, unit: str = "") -> None:
    """Report that ``done`` of ``total`` ``unit`` of ``what`` are done (a :class:`Progress` record)."""
    if logger.isEnabledFor(logging.DEBUG):
        logger.debug("%s: %d of %d %s", what, done, total, unit,
                     extra={"progress": Progress(what, int(done), int(total), unit)})
