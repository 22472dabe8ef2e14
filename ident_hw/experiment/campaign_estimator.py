"""The online estimators run along a campaign: SVD-DLS, with RLS and damped RLS beside it on
the same data (the comparison of the SVD-DLS paper).

Each recording, as soon as the runner has it, goes through the same preparation as the offline
identification (stretches cut at gaps, filter, derivatives, regressor, parallel decimation)
and then, sample by sample in time order, into the three estimators. The rows of an axis near
rest are left out, as in the offline fits (``identification.min_speed``): the smoothed Coulomb
term does not describe friction there. Parameters are scaled by
:func:`ident_hw.config.to_identification.online_scales` (CAD magnitudes, friction magnitudes by
kind) and forces by ``identification.online.output_noise`` times each axis' force per ampere,
so that the SVD-DLS threshold reads as a relative standard deviation. The estimates start at
the CAD values with no information: a direction the data have not excited yet stays there.

After each trajectory the SVD-DLS estimates, their %σ and the excited rank are printed; the
whole trace (all three estimators, the simulated truth over time with a payload change of
a trajectory's ``payload``, the base parameters) goes into the results (``online.npz``,
``plots/online.png``, the report's online section).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from drivers.recording import Recording
from ident_hw.config import Config
from ident_hw.config.to_identification import online_scales
from ident_hw.identification import RLS, SVDDLS, DampedRLS, base_parameters
from ident_hw.identification.base_params import on_kept
from ident_hw.model.combinations import format_combination
from ident_hw.results import BaseFit, OnlineTrace

from .inputs import identification_plan
from .preparation import prepare

#: the estimator whose estimates are printed and judged; the others are baselines
MAIN = "SVD-DLS"


class CampaignEstimator:
    """The online estimators over the recordings of a campaign, in the order they are recorded."""

    def __init__(self, config: Config, show: Callable[[str], None] | None = None):
        self.plan = plan = identification_plan(config)
        self.payloads = {t.name: t.payload for t in config.trajectories if t.payload is not None}
        self.robot = plan.model
        self.show = show
        online = plan.identification.online
        physical = self.robot.parameter_names
        cad = np.array(plan.initial)
        scale = np.array(online_scales(online, physical, cad))
        basis = self.robot.readable_base()
        if basis is None:      # the physical parameters (their base ones follow from the data)
            self._kept, self._columns, self._H = None, None, None
            self.names, self.units, self.cad, self.scale = physical, tuple(map(self.robot.parameter_unit, physical)), cad, scale
        else:                  # the model's base parameters: no structurally unidentifiable direction enters
            self._kept, self._H = basis.kept, basis.on_columns(physical)
            self._columns = [physical.index(k) for k in self._kept]
            self.names = tuple(format_combination(h, physical) for h in self._H)
            self.units = tuple(map(self.robot.parameter_unit, self._kept))
            self.cad, self.scale = self._H @ cad, np.abs(self._H) @ scale
        self.output_std = online.output_noise * plan.axes.force_per_amp
        n = len(self.names)
        common = {"forgetting": online.forgetting, "scale": self.scale, "output_std": self.output_std}
        self.estimators = {
            MAIN: SVDDLS(n, threshold=online.threshold, **common),
            "RLS": RLS(n, **common),
            "damped RLS": DampedRLS(n, damping=online.damping, prior=self.cad, **common),
        }
        nothing = np.zeros((n, n))
        self.estimators[MAIN].warm_start(self.cad, nothing)
        self.estimators["RLS"].warm_start(self.cad, 1e-6 * np.diag(1.0 / self.scale**2))   # P0 = 1e6 (scaled)
        self._t: list[np.ndarray] = []
        self._coef: dict[str, list[np.ndarray]] = {k: [] for k in self.estimators}
        self._sq_error: dict[str, float] = dict.fromkeys(self.estimators, 0.0)
        self._rank: list[np.ndarray] = []
        self._truth: list[np.ndarray] = []
        self._Y: list[np.ndarray] = []
        self._entries = 0
        self._elapsed = 0.0
        self.change_time: float | None = None
        self.diverged: dict[str, float] = {}     # estimator -> campaign time (s) it failed at

    def _truth_at(self, name: str, t: np.ndarray) -> np.ndarray | None:
        """(M, n) the simulated truth at the trajectory's times ``t`` (s from its start)."""
        true = self.plan.truth
        if true is None:
            return None
        truth = np.tile(true, (len(t), 1))
        payload = self.payloads.get(name)
        if payload is not None:
            after = t >= payload.after
            truth[after] = self.robot.with_payload(true, payload.mass, payload.inertia)
            self.change_time = self._elapsed + payload.after
        return truth

    def update(self, name: str, rec: Recording) -> None:
        """Feed one recorded trajectory, sample by sample, to every estimator; print the table."""
        p = prepare(self.plan, self.robot, name, rec)
        Y = p.Y if self._columns is None else p.Y[:, :, self._columns]
        Y = np.where(p.moving[:, :, None], Y, 0.0)      # rows of axes near rest: no information
        tau = np.where(p.moving, p.tau, 0.0)
        m = len(p.t)
        for label, est in self.estimators.items():
            coef = np.full((m, len(self.names)), np.nan)
            rank = np.zeros(m, dtype=int)
            sq = 0.0
            for k in range(m if label not in self.diverged else 0):
                error = (tau[k] - Y[k] @ est.coef_) / self.output_std      # a-priori, in noise units
                sq += float(error[p.moving[k]] @ error[p.moving[k]])
                try:
                    est.partial_fit(Y[k], tau[k])
                except np.linalg.LinAlgError:    # e.g. RLS wound up in a direction never excited
                    self.diverged[label] = float(self._elapsed + p.t[k])
                    break
                coef[k] = est.coef_
                rank[k] = getattr(est, "rank_", len(self.names))
            self._coef[label].append(coef)
            self._sq_error[label] += sq
            if label == MAIN:
                self._rank.append(rank)
        self._entries += int(p.moving.sum())
        self._Y.append(Y)
        truth = self._truth_at(name, p.t)
        if truth is not None:
            self._truth.append(truth)
        self._t.append(self._elapsed + p.t)
        if len(rec.t):
            self._elapsed += float(rec.t[-1]) + (float(np.median(np.diff(rec.t))) if len(rec.t) > 1 else 0.0)
        if self.show is not None:
            self.show(self.table(f"after {name}"))

    def _physical(self, coef: np.ndarray) -> np.ndarray:
        """Estimates (M, r) of the estimators as physical vectors (M, n): each base parameter on
        its kept parameter, the others 0 (``H`` of the basis gives the base values back)."""
        if self._columns is None:
            return coef
        return on_kept(self.robot.parameter_names, self._kept, coef)

    def relative_std(self) -> np.ndarray:
        """(n,) %σ of the SVD-DLS estimates (NaN in the unexcited directions' parameters)."""
        est = self.estimators[MAIN]
        std = np.sqrt(np.clip(np.diag(est.covariance_), 0.0, None))
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = 100.0 * std / np.abs(est.coef_)
        return np.where(std > 0, rel, np.nan)

    def unexcited(self) -> list[str]:
        """The directions SVD-DLS holds (eigenvalues below the threshold), each as its main
        parameters: ``0.83 m_l2 - 0.55 m_ee`` (scaled units)."""
        out = []
        for v in self.estimators[MAIN].held_directions().T:
            order = np.argsort(-np.abs(v))[:3]
            out.append(" ".join(f"{v[i]:+.2f} {self.names[i]}" for i in order if abs(v[i]) >= 0.1).lstrip("+"))
        return out

    def table(self, title: str) -> str:
        """The current SVD-DLS estimates with their %σ, one line per parameter."""
        est = self.estimators[MAIN]
        rel = self.relative_std()
        lines = [f"{MAIN} estimates {title} (excited rank {est.rank_} of {len(self.names)}):"]
        lines += [f"  {n:>10} = {v:12.6g} {u:<10}" + ("" if np.isnan(r) else f" %sigma {r:7.2f}")
                  for n, u, v, r in zip(self.names, self.units, est.coef_, rel)]
        held = self.unexcited()
        if held:
            lines.append(f"  held (not excited): {'; '.join(held)}")
        return "\n".join(lines)

    def trace(self, base_fit: BaseFit | None = None) -> OnlineTrace:
        """The estimates of every estimator over the campaign's time (trajectories back to back),
        with the base parameters of the offline ``base_fit`` (the same combinations as the
        report's), else those of the data fed here. Estimates of base parameters (a model with
        a readable basis) are written as physical vectors: each base value on its kept parameter."""
        physical = self.robot.parameter_names
        n = len(physical)
        if not self._t:
            return OnlineTrace(physical, np.zeros(0), {k: np.zeros((0, n)) for k in self.estimators})
        if self._H is not None:
            H, expressions = self._H, self.names
        elif base_fit is not None and not base_fit.held:
            H, expressions = base_fit.H, base_fit.expressions
        else:
            base = base_parameters(np.concatenate(self._Y), self.names, scale=np.maximum(np.abs(self.cad), 1e-3))
            H, expressions = base.H, base.expressions
        rms = {k: float("nan") if k in self.diverged else float(np.sqrt(v / max(self._entries, 1)))
               for k, v in self._sq_error.items()}
        return OnlineTrace(
            names=physical, t=np.concatenate(self._t),
            estimates={k: self._physical(np.concatenate(v)) for k, v in self._coef.items()},
            rank=np.concatenate(self._rank), j_rmse=rms, base_names=expressions, H=H,
            truth=np.concatenate(self._truth) if self._truth else None, change_time=self.change_time,
            unexcited=tuple(self.unexcited()), diverged=dict(self.diverged))
