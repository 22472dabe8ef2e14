"""Errors raised by the model: never a silent NaN."""

from __future__ import annotations

import numpy as np


class KinematicsError(ValueError):
    """A pose the robot cannot take. ``chain`` is 1-based, ``sample`` the index in the batch."""

    def __init__(self, message: str, chain: int | None = None, sample: int | None = None):
        super().__init__(message)
        self.chain = chain
        self.sample = sample


class SingularityError(KinematicsError):
    """A serial (chain stretched or folded) or parallel (type II) singular configuration."""


def raise_at_first(bad: np.ndarray, error: type[KinematicsError], what: str, X: np.ndarray | None = None) -> None:
    """Raise ``error`` for the first ``True`` of ``bad`` (shape (N,) or (N, 3) per chain)."""
    if not bad.any():
        return
    if bad.ndim == 1:
        sample, chain = int(np.argmax(bad)), None
    else:
        row, col = np.unravel_index(int(np.argmax(bad)), bad.shape)
        sample, chain = int(row), int(col) + 1
    where = f"chain {chain}, " if chain else ""
    pose = ""
    if X is not None:
        x, y, alpha = X[sample]
        pose = f" at pose x={x:.6g} m, y={y:.6g} m, alpha={np.degrees(alpha):.6g} deg"
    raise error(f"{what}: {where}sample {sample}{pose}", chain=chain, sample=sample)
