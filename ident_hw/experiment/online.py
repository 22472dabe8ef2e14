"""The SVD-DLS estimator (:class:`ident_hw.identification.SVDDLS`) run along a campaign.

Each recording, as soon as the runner has it, goes through the same preparation as the offline
identification (filter, derivatives, regressor, parallel decimation; samples near clipped
currents or late set-points left out) and then, sample by sample in time order, into the
estimator. The estimate starts at the CAD values with no information: directions the data have
not excited yet stay at CAD. The table of estimates is printed after each trajectory and the
whole trace goes into the results (``online.npz``, plot ``plots/online.png``).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from drivers.recording import Recording
from ident_hw.config import Config
from ident_hw.identification import SVDDLS
from ident_hw.model import InertialParams
from ident_hw.report import OnlineTrace, parameter_unit

from .offline import prepare
from .plan import robot_model

NAMES = InertialParams.NAMES


class CampaignEstimator:
    """SVD-DLS over the recordings of a campaign, in the order they are recorded.

    The outputs are normalised by one mA of motor current (the drives' resolution) and the
    parameters by their CAD magnitudes, so that ``identification.online.threshold`` reads as
    in :class:`ident_hw.identification.SVDDLS` (100 ⇔ 10 % relative standard deviation).
    """

    def __init__(self, config: Config, show: Callable[[str], None] | None = None):
        if config.identification is None:
            raise ValueError(f"{config.source}: identification: missing section")
        self.config = config
        self.robot = robot_model(config)
        self.show = show
        online = config.identification.online
        cad = config.robot.cad.to_model().as_vector()
        force_per_amp = np.array([a.scaling().force_per_amp for a in config.robot.actuators])
        self.estimator = SVDDLS(len(NAMES), forgetting=online.forgetting, threshold=online.threshold,
                                scale=np.maximum(np.abs(cad), 1e-3), output_std=force_per_amp * 1e-3)
        self.estimator.warm_start(cad, np.zeros((len(NAMES), len(NAMES))))
        self._t: list[np.ndarray] = []
        self._estimates: list[np.ndarray] = []
        self._elapsed = 0.0

    def update(self, name: str, rec: Recording) -> None:
        """Feed one recorded trajectory, sample by sample; print the table."""
        p = prepare(self.config, self.robot, name, rec)
        estimates = np.empty((len(p.t), len(NAMES)))
        for k in range(len(p.t)):
            self.estimator.partial_fit(p.Y[k], p.tau[k])
            estimates[k] = self.estimator.coef_
        self._t.append(self._elapsed + p.t)
        self._estimates.append(estimates)
        if len(rec.t):
            self._elapsed += float(rec.t[-1]) + float(np.median(np.diff(rec.t)) if len(rec.t) > 1 else 0.0)
        if self.show is not None:
            self.show(self.table(f"after {name}"))

    def table(self, title: str) -> str:
        """The current estimates (SVD-DLS), one line per parameter."""
        coef = self.estimator.coef_
        lines = [f"SVD-DLS estimates {title} (excited rank {self.estimator.rank_} of {len(NAMES)}):"]
        lines += [f"  {n:>10} = {v:12.6g} {parameter_unit(n)}" for n, v in zip(NAMES, coef)]
        return "\n".join(lines)

    def trace(self) -> OnlineTrace:
        """Estimates over the campaign's time (s, trajectories back to back)."""
        if not self._t:
            return OnlineTrace(NAMES, np.zeros(0), np.zeros((0, len(NAMES))))
        return OnlineTrace(NAMES, np.concatenate(self._t), np.concatenate(self._estimates))
