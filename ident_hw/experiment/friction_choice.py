"""The friction model's one non-linear constant, chosen on the data: Dahl's presliding distance
where the config says ``robot.friction.presliding: auto``.

The presliding distance sets how far a joint travels before its Coulomb force has turned; the
force is linear in the friction coefficients for any distance, not in the distance. So each
distance of a grid (:data:`PRESLIDING_GRID`) is tried: the identification trajectories are
prepared with it and every parameter fitted by least squares; of the distances whose fit leaves a
residual within :data:`TOLERANCE` of the smallest, the longest wins (a profile likelihood over one
variable, read with parsimony: ``_parsimonious``). The residual of each actuator
counts relative to its own forces (the sum over actuators of ``||tau - Y pi||^2 / ||tau||^2``):
the big joints do not decide alone. Only identification data take part: the validation
trajectories judge the choice, they do not make it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from drivers.recording import Recording
from ident_hw.config import RobotConfig
from ident_hw.config.to_model import friction_model
from ident_hw.identification.least_squares import check_regression_data, stack
from ident_hw.model.interface import RobotModel
from ident_hw.progress import report_progress
from ident_hw.records import FrictionChoice, Tried

logger = logging.getLogger(__name__)

#: rad | m, the presliding distances tried (a lab's joints: 10 µrad to a few mrad behind a gear)
PRESLIDING_GRID = (2e-5, 5e-5, 1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3)
#: a grid value whose residual is within this fraction of the least one fits as well
#: (``_parsimonious``)
TOLERANCE = 0.1
#: rad/s | m/s, the Stribeck velocities tried
STRIBECK_GRID = (0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0)


@dataclass(frozen=True)
class FrictionRobot:
    """The robot model to identify with, and its friction model (None: the default Coulomb and
    viscous terms, nothing to say)."""

    robot: RobotModel
    choice: FrictionChoice | None


#: prepares one recording for a robot model: ``(robot, trajectory name, recording) -> Prepared``
Preparer = Callable[[RobotModel, str, Recording], object]


def friction_robot(robot_config: RobotConfig, base: RobotModel, recordings: Mapping[str, Recording],
                   names: Sequence[str], prepare: Preparer) -> FrictionRobot:
    """The robot model to identify with (``base``: the config's robot section ``robot_config``'s
    model, whose copies share the tree's regressor of each motion), and its friction model. The
    constants the config leaves ``auto`` (a Dahl presliding distance, a Stribeck velocity) are
    chosen per actuator on the recordings ``names`` (each through ``prepare(robot, name,
    recording)``): each constant in turn over its grid, the same value for every actuator in one
    fit, each actuator then taking the value that left its own residual smallest (its friction acts
    on its own force only); the presliding distance first and again after the Stribeck velocity
    (coordinate descent)."""
    friction = robot_config.friction
    if friction.default:
        return FrictionRobot(base, None)
    from ident_hw.model.described import DescribedRobot      # pinocchio: described robots only
    if not isinstance(base, DescribedRobot):    # the config's check: other friction models are a described robot's
        raise ValueError(f"robot.friction: a {friction.model} friction model needs a described robot's model")
    free = {"presliding": PRESLIDING_GRID if friction.model == "dahl" and friction.presliding == "auto" else None,
            "stribeck": STRIBECK_GRID if friction.stribeck == "auto" else None}
    chosen: dict[str, tuple[float, ...] | None] = {"presliding": None, "stribeck": None}
    tried: dict[str, Tried] = {}
    order = [k for k in ("presliding", "stribeck", "presliding") if free[k] is not None]
    if len(order) == 2:             # one constant alone: once is enough
        order = order[:1]
    total, done = sum(len(free[k] or ()) for k in order), 0
    for key in order:
        grid = free[key] or ()
        residuals = []              # per value of the grid, per actuator
        for value in grid:
            report_progress(logger, "friction constants", done, total, "fit")
            done += 1
            robot = base.with_friction(friction_model(robot_config, **{**chosen, key: value}))
            residuals.append(_relative_residuals([prepare(robot, n, recordings[n]) for n in names]))
        best = _parsimonious(np.array(residuals))
        chosen[key] = tuple(float(grid[i]) for i in best)
        tried[key] = Tried(tuple(grid), tuple(tuple(float(x) for x in r) for r in residuals))
    if total:
        report_progress(logger, "friction constants", total, total, "fit")
    robot = base.with_friction(friction_model(robot_config, **chosen))
    model = robot.friction
    choice = FrictionChoice(friction.model, friction.offset, _per_actuator(model.presliding, robot)
                            if friction.model == "dahl" else None, _per_actuator(model.stribeck_velocity, robot),
                            tried=tried, trajectories=tuple(names) if tried else ())
    logger.info(choice.describe())
    return FrictionRobot(robot, choice)


def _parsimonious(residuals: np.ndarray) -> np.ndarray:
    """(a,) per actuator the index of the grid value to take from ``residuals`` (values, a): of
    those within :data:`TOLERANCE` of the smallest, the largest (the grids run from sharp to
    smooth: a longer presliding distance, a higher Stribeck velocity, moves the friction least
    with the micro-motions of a stop, which an excitation that never stops cannot show)."""
    within = residuals <= (1.0 + TOLERANCE) * residuals.min(axis=0)
    return residuals.shape[0] - 1 - np.argmax(within[::-1], axis=0)


def _per_actuator(value, robot: RobotModel) -> tuple[float, ...] | None:
    """A friction constant (one, or one per actuator) as one per actuator; None stays None."""
    if value is None:
        return None
    return tuple(float(v) for v in np.broadcast_to(np.asarray(value, dtype=float), (len(robot.actuator_names),)))


def _relative_residuals(prepared: Sequence) -> np.ndarray:
    """(a,) per actuator ``||tau - Y pi||^2 / ||tau||^2`` of the least-squares fit of every
    parameter on the rows the fits use (columns scaled to unit norm; the numerical rank only)."""
    Y, tau = check_regression_data(np.concatenate([p.Y for p in prepared]),
                                   np.concatenate([p.tau_fit for p in prepared]))    # rows left out: 0
    A, b = stack(Y, tau)
    norms = np.linalg.norm(A, axis=0)
    used = norms > 1e-12 * norms.max()
    coef = np.linalg.lstsq(A[:, used] / norms[used], b, rcond=1e-10)[0]
    residual = (b - (A[:, used] / norms[used]) @ coef).reshape(Y.shape[1], -1)      # (a, N), output-major
    return np.sum(residual ** 2, axis=1) / np.sum(tau.T ** 2, axis=1)
