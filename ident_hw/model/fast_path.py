"""A hand-derived model used as the compiled fast path of a robot described by its file.

The 3PRRR and the Delta are configured by their description files (``configs/robots/``) like any
robot; their hand-derived models (:class:`~ident_hw.model.robot.ThreePRRR`,
:class:`~ident_hw.model.delta.Delta`) compute the same torques faster. A hand model is built from
the values read off the file (:mod:`ident_hw.model.prrr_file`, :mod:`ident_hw.model.delta_file`)
and used only after :func:`check_fast_path` has found its torques equal to the generic model's
(:class:`~ident_hw.model.described.DescribedRobot` of the same file) on a few states.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .delta import DeltaGeometry
from .described import DescriptionError
from .parameters import Geometry

#: relative agreement of the torques of the hand model and the generic model (each actuator's
#: largest difference over the states, over its largest torque)
FAST_PATH_TOLERANCE = 1e-9
#: states of the check, drawn about home
FAST_PATH_STATES = 6


@dataclass(frozen=True)
class FastPath:
    """A hand model's values read off a description file.

    Attributes:
        path: the description file.
        geometry: the hand model's geometry (``Geometry`` or ``DeltaGeometry``).
        parameters: (P,) the file's bodies and drive terms as the hand model's parameter vector.
        agreement: the largest relative torque difference found by :func:`check_fast_path` (NaN:
            values read, not checked yet).
        gravity: m/s², along ``-z``, the file's (``<option gravity>``; the planar 3PRRR has none).
    """

    path: Path
    geometry: Geometry | DeltaGeometry
    parameters: np.ndarray
    agreement: float = float("nan")
    gravity: float = 0.0


def check_fast_path(path: Path, what: str, tau_hand: np.ndarray, tau_described: np.ndarray) -> float:
    """The largest relative difference of two torque sets (N, n) of the same states: per
    actuator ``max |tau_hand - tau_described| / max |tau_described|``.

    Raises:
        DescriptionError: beyond :data:`FAST_PATH_TOLERANCE`, naming the file and ``what`` hand
            model does not describe it.
    """
    scale = np.maximum(np.abs(tau_described).max(axis=0), 1e-300)
    error = float((np.abs(tau_hand - tau_described).max(axis=0) / scale).max())
    if not error <= FAST_PATH_TOLERANCE:
        raise DescriptionError(f"{path}: the {what} model built from this file gives torques {error:.3g} (relative) "
                               f"away from the file's own (pinocchio) model, beyond {FAST_PATH_TOLERANCE:g}: the file "
                               f"is not a {what} as its hand model reads it (frames, joint names and bodies as the "
                               "shipped file's header says)")
    return error
