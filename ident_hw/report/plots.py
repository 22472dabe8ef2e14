"""The report's PNG plots: forces measured against the model, residuals, motion, online estimates.

Each plot function takes the typed results (:mod:`ident_hw.results`), the robot's actuators
(:class:`Actuators`) where it draws one panel per actuator, and the plots folder, and returns the
PNG's path; :func:`render` draws several in parallel.
"""

from __future__ import annotations

import math
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ident_hw.model.interface import FORCE_UNITS, POSITION_UNITS
from ident_hw.results import OnlineTrace, ParameterTable, TrajectoryFit

#: units of the inertial parameters (masses, first moments, inertias): the online plot shows them
INERTIAL_UNITS = ("kg", "kg·m", "kg·m²")
#: most panels of the online plot (those a payload changes first)
ONLINE_PANELS = 8
#: s of a trajectory the forces plot shows (longer ones are unreadable at a page's width); the
#: residuals plot shows the whole trajectory
FORCES_WINDOW = 10.0


def _figure(height: float) -> Figure:
    """A figure 11 in wide with fixed margins (matplotlib's automatic layouts cost most of the
    report's time: they measure every tick label of every panel)."""
    fig = Figure(figsize=(11, height))
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.8 / height, top=1 - 0.55 / height,
                        wspace=0.25, hspace=0.3)
    return fig


@dataclass(frozen=True)
class Actuators:
    """The robot's actuators, in the column order of the fits: names and kinds (``revolute``, ``prismatic``)."""

    names: tuple[str, ...]
    kinds: tuple[str, ...]

    def label(self, j: int) -> str:
        """``theta1 [N·m]``: actuator ``j`` and the unit of its force."""
        return f"{self.names[j]} [{FORCE_UNITS[self.kinds[j]]}]"


def _panels(fig: Figure, n: int):
    """One panel per actuator, in columns of three (the 3PRRR: links left, carriages right)."""
    rows = min(n, 3)
    cols = math.ceil(n / rows)
    axes = np.atleast_2d(fig.subplots(rows, cols, sharex=True).reshape(rows, cols))
    return [axes[j % rows, j // rows] for j in range(n)], axes[-1]


def _every(n: int, at_most: int = 3000) -> slice:
    return slice(None, None, max(1, n // at_most))


def plot_forces(fit: TrajectoryFit, actuators: Actuators, plots: Path, model_label: str = "step by step") -> Path:
    """Measured forces against the step-by-step prediction (``model_label``: what it is made of,
    :attr:`ident_hw.results.Results.stepwise_label`) and the base fit's, over the first window."""
    fig = _figure(8)
    panels, bottom = _panels(fig, len(actuators.names))
    shown = int(np.searchsorted(fit.t, fit.t[0] + FORCES_WINDOW, side="right")) if len(fit.t) else 0
    s = slice(0, shown, _every(shown).step)
    for j, ax in enumerate(panels):
        ax.plot(fit.t[s], fit.tau[s, j], lw=0.8, label="measured")
        ax.plot(fit.t[s], fit.tau_model[s, j], lw=1.0, ls="--", label=model_label)
        if fit.tau_base is not None:
            ax.plot(fit.t[s], fit.tau_base[s, j], lw=1.0, ls=":", label="base fit")
        if fit.tau_compared is not None:
            ax.plot(fit.t[s], fit.tau_compared[s, j], lw=0.8, ls="-.", label="compared")
        ax.set_ylabel(actuators.label(j))
        ax.grid(alpha=0.3)
    panels[0].legend(loc="best", fontsize=8)
    for ax in bottom:
        ax.set_xlabel("t [s]")
    window = ""
    if shown < len(fit.t):
        window = f", first {FORCES_WINDOW:g} s of {fit.t[-1] - fit.t[0]:.0f} s (residuals: the whole trajectory)"
    fig.suptitle(f"{fit.name} ({fit.role}): measured vs model forces{window}")
    return _save(fig, plots / f"forces_{fit.name}.png")


def plot_compared(fit: TrajectoryFit, actuators: Actuators, plots: Path, label: str = "compared") -> Path:
    """The whole trajectory: measured forces, the identified parameters' prediction and the set
    from elsewhere's (``label``), the samples where each actuator is at rest shaded."""
    compared = fit.tau_compared
    if compared is None:
        raise ValueError(f"{fit.name}: no prediction of the compared set to plot")
    fig = _figure(9)
    panels, bottom = _panels(fig, len(actuators.names))
    s = _every(len(fit.t))
    for j, ax in enumerate(panels):
        ax.plot(fit.t[s], fit.tau[s, j], lw=0.9, color="k", label="measured")
        ax.plot(fit.t[s], fit.tau_fit[s, j], lw=0.9, color="C3", label="identified")
        ax.plot(fit.t[s], compared[s, j], lw=0.7, color="C0", label=label)
        if fit.at_rest is not None and fit.at_rest[:, j].any():
            low, high = ax.get_ylim()
            ax.fill_between(fit.t[s], low, high, where=fit.at_rest[s, j], color="0.85", lw=0, label="at rest")
            ax.set_ylim(low, high)
        ax.set_ylabel(actuators.label(j))
        ax.grid(alpha=0.3)
    panels[0].legend(loc="best", fontsize=8)
    for ax in bottom:
        ax.set_xlabel("t [s]")
    fig.suptitle(f"{fit.name} ({fit.role}): measured, identified and {label}")
    return _save(fig, plots / f"compared_{fit.name}.png")


def plot_residuals(fit: TrajectoryFit, actuators: Actuators, plots: Path) -> Path:
    fig = _figure(6)
    panels, bottom = _panels(fig, len(actuators.names))
    s = _every(len(fit.t))
    for j, ax in enumerate(panels):
        ax.plot(fit.t[s], (fit.tau - fit.tau_model)[s, j], lw=0.6, color="C3")
        ax.set_ylabel(actuators.label(j))
        ax.grid(alpha=0.3)
    for ax in bottom:
        ax.set_xlabel("t [s]")
    fig.suptitle(f"{fit.name}: residual measured − model")
    return _save(fig, plots / f"residuals_{fit.name}.png")


def plot_motion(fit: TrajectoryFit, actuators: Actuators, plots: Path) -> Path:
    """The end-effector's path seen from above (x, y) and the actuated coordinates, one panel per kind."""
    kinds = list(dict.fromkeys(actuators.kinds))
    fig = _figure(3.5)
    ax_xy, *ax_kinds = fig.subplots(1, 1 + len(kinds))
    s = _every(len(fit.t))
    if fit.X is not None:
        ax_xy.plot(fit.X[s, 0], fit.X[s, 1], lw=1.0)
        ax_xy.set_aspect("equal", adjustable="datalim")
    ax_xy.set_xlabel("x [m]")
    ax_xy.set_ylabel("y [m]")
    ax_xy.set_title("end-effector path" if fit.X is not None else "(no pose recorded)")
    for ax, kind in zip(ax_kinds, kinds):
        for j, name in enumerate(actuators.names):
            if actuators.kinds[j] == kind:
                ax.plot(fit.t[s], fit.Theta[s, j], lw=0.8, label=name)
        ax.set_ylabel(f"{kind} [{POSITION_UNITS[kind]}]")
    for ax in ax_kinds:
        ax.set_xlabel("t [s]")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.suptitle(f"{fit.name}: motion")
    return _save(fig, plots / f"motion_{fit.name}.png")


def plot_online(online: OnlineTrace, params: ParameterTable, plots: Path) -> Path:
    """The base parameters of the inertial parameters over time, every estimator, the truth
    (stepping at a payload change) and the change; at most :data:`ONLINE_PANELS`, those the
    payload changes first."""
    units = dict(zip(params.names, params.units))
    inertial = [j for j, n in enumerate(online.names) if units.get(n) in INERTIAL_UNITS]
    if online.H is None:           # an old trace: the physical masses and inertias of SVD-DLS
        shown = inertial
        values, labels, truth = next(iter(online.estimates.values())), list(online.names), None
        curves = {"SVD-DLS": values}
    else:
        shown = [i for i in range(online.H.shape[0]) if np.any(online.H[i, inertial] != 0)]
        labels = list(online.base_names)
        curves = {k: online.base(v) for k, v in online.estimates.items()}
        truth = online.base(online.truth) if online.truth is not None else None
    if truth is not None:     # stable: those the payload changes first, then those not zero
        shown.sort(key=lambda i: (np.ptp(truth[:, i]) == 0, not np.any(truth[:, i])))
    shown = shown[:ONLINE_PANELS]
    cols = 2
    rows = max(1, math.ceil(len(shown) / cols))
    fig = _figure(2.2 * rows)
    axes = np.atleast_1d(fig.subplots(rows, cols, sharex=True)).ravel()
    for ax, i in zip(axes, shown):
        for label, values in reversed(curves.items()):     # SVD-DLS (the first) drawn on top
            ax.plot(online.t, values[:, i], lw=1.3 if label == next(iter(curves)) else 0.8, label=label)
        if truth is not None:
            ax.plot(online.t, truth[:, i], color="k", ls=":", lw=0.9, label="truth")
            # around the truth (±15 % of it, or of its change): early transients would hide the
            # tracking; a true value of 0: the middle 90 % of the main estimator's values
            lo, hi = float(truth[:, i].min()), float(truth[:, i].max())
            margin = max(0.15 * max(abs(lo), abs(hi)), 0.5 * (hi - lo))
            if margin == 0:
                main = next(iter(curves.values()))[:, i]
                main = main[np.isfinite(main)]
                margin = float(np.percentile(np.abs(main), 90)) if main.size else 0.0
            if margin > 0:
                ax.set_ylim(lo - margin, hi + margin)
        if online.change_time is not None:
            ax.axvline(online.change_time, color="r", lw=0.7, ls="--")
        ax.set_ylabel(labels[i], fontsize=7)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=6)
    for ax in axes[len(shown):]:
        ax.set_visible(False)
    fig.suptitle("online estimates over time" + (" (payload added at the dashed line)" if online.change_time else ""))
    return _save(fig, plots / "online.png")


def render(jobs: list[tuple]) -> list[Path]:
    """Run the plot functions ``[(function, args), ...]``, on every CPU this process may run on
    where the platform forks (drawing the figures is most of a report's time); returns their paths
    in order. A process pinned to one CPU (``taskset``, a pytest-xdist worker of the suite) draws
    them itself: forked plotters would share its one CPU and only add the forks' cost."""
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    workers = min(len(jobs), cpus)
    if workers < 2 or "fork" not in multiprocessing.get_all_start_methods():
        return [function(*args) for function, args in jobs]
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork")) as pool:
        return list(pool.map(_call, jobs))


def _call(job: tuple) -> Path:
    function, args = job
    return function(*args)


def _save(fig: Figure, path: Path) -> Path:
    fig.savefig(path, dpi=90)
    return path
