"""The results folder of a campaign and its report (tables, PNG plots, HTML, MATLAB export).

A results folder holds::

    STATUS               "running", "identifying", then "complete" (the quality verdict passed),
                         "degraded: <reasons>" (it did not), "partial: <why>" after a fault or a
                         signal, "failed: <why>" when nothing could be identified
    config.yaml          the config used, with every ``extends:`` merged in
    parameters.json/.yaml  Table-1-like rows: initial, identified, truth, sigma, %sigma, bounds, step;
                         the base-parameter least-squares fit (``base_fit``) when a step made one;
                         ``trajectories``: what each recording covered and how much of it the fit
                         used; ``quality``: the verdict, its figures, thresholds and reasons
    fits/<name>.npz      measured and model forces along each trajectory (t, tau, tau_model, Theta, X,
                         tau_base = the base fit's prediction)
    online.npz           estimates over time of an online run (optional)
    data/                the recordings (raw CAN log + decoded samples), written by the runner
    metrics.yaml         per trajectory and actuator: RMS, NRMS, d_tau, J_RMSE   (built)
    plots/*.png          forces, residuals, trajectories, online estimates        (built)
    report.html          everything above on one page                             (built)
    results.mat          parameters and fits for MATLAB (scipy.io.savemat)        (built)

:func:`save_results` writes the first part and calls :func:`build_report`, which reads only
files of the folder: ``ident-hw report RESULTS`` rebuilds the built part from them.
"""

from __future__ import annotations

import html
import json
import math
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.io
import yaml
from matplotlib.figure import Figure

from ident_hw.identification.least_squares import POORLY_IDENTIFIED_PERCENT
from ident_hw.identification.metrics import validation_metrics
from ident_hw.model import ACTUATOR_NAMES

FORCE_UNITS = ("N·m",) * 3 + ("N",) * 3
POSITION_UNITS = ("rad",) * 3 + ("m",) * 3
STATUS_FILE = "STATUS"


def parameter_unit(name: str) -> str:
    """SI unit of a parameter of :attr:`ident_hw.model.InertialParams.NAMES`."""
    if name.startswith("m_"):
        return "kg"
    if name.startswith("I_"):
        return "kg·m²"
    revolute = "theta" in name
    if name.startswith("fv_"):
        return "N·m·s/rad" if revolute else "N·s/m"
    return "N·m" if revolute else "N"


@dataclass
class ParameterTable:
    """One row per parameter (n of them), arrays of shape (n,).

    ``sigma`` is NaN where no standard deviation is known; ``truth`` is None outside simulation;
    ``step`` names the identification step that estimated the parameter ("" = held at ``initial``).
    """

    names: tuple[str, ...]
    initial: np.ndarray
    identified: np.ndarray
    sigma: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    step: tuple[str, ...]
    method: tuple[str, ...]
    truth: np.ndarray | None = None

    def rows(self) -> list[dict]:
        out = []
        for i, name in enumerate(self.names):
            ident, sigma = float(self.identified[i]), float(self.sigma[i])
            rel = 100.0 * sigma / abs(ident) if ident and math.isfinite(sigma) else None
            row = {
                "name": name, "unit": parameter_unit(name), "initial": float(self.initial[i]),
                "identified": ident, "sigma": sigma if math.isfinite(sigma) else None,
                "rel_sigma_percent": rel, "bounds": [_num(self.lower[i]), _num(self.upper[i])],
                "step": self.step[i], "method": self.method[i],
            }
            if self.truth is not None:
                true = float(self.truth[i])
                row["truth"] = true
                row["error_percent"] = 100.0 * (ident - true) / abs(true) if true else None
            out.append(row)
        return out

    @classmethod
    def from_rows(cls, rows: list[dict]) -> ParameterTable:
        def col(key, default=math.nan):
            return np.array([default if r.get(key) is None else r[key] for r in rows], dtype=float)
        has_truth = all("truth" in r for r in rows)
        return cls(names=tuple(r["name"] for r in rows), initial=col("initial"), identified=col("identified"),
                   sigma=col("sigma"), lower=np.array([_num_in(r["bounds"][0], -np.inf) for r in rows]),
                   upper=np.array([_num_in(r["bounds"][1], np.inf) for r in rows]),
                   step=tuple(r["step"] for r in rows), method=tuple(r["method"] for r in rows),
                   truth=col("truth") if has_truth else None)


@dataclass
class BaseFit:
    """Least-squares estimate of base parameters (the SVD-DLS paper) with statistics (the power-model paper).

    ``r`` base parameters ``pi_b = H pi`` of the ``n`` physical ones: ``expressions`` (r,) read
    them (e.g. ``"m_c + 0.5 m_l2"``); ``coef``, ``sigma`` (r,) estimate and standard deviation;
    ``initial``, ``truth`` (r,) the same combinations of the CAD and true values (truth None
    outside simulation). ``held``: physical parameters held at known values during the fit;
    ``unexcited``: free ones the data says nothing of. A base parameter whose %σ exceeds
    ``threshold`` is poorly identified on its data.
    """

    step: str
    method: str
    trajectories: tuple[str, ...]
    expressions: tuple[str, ...]
    H: np.ndarray
    coef: np.ndarray
    sigma: np.ndarray
    initial: np.ndarray
    truth: np.ndarray | None
    held: tuple[str, ...]
    unexcited: tuple[str, ...]
    threshold: float

    @property
    def rel_sigma_percent(self) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return 100.0 * self.sigma / np.abs(self.coef)

    @property
    def identified(self) -> np.ndarray:
        """(r,) bool: %σ at most ``threshold``."""
        return self.rel_sigma_percent <= self.threshold

    def rows(self) -> list[dict]:
        out = []
        for i, expr in enumerate(self.expressions):
            rel = float(self.rel_sigma_percent[i])
            row = {"base_parameter": expr, "initial": float(self.initial[i]), "identified": float(self.coef[i]),
                   "sigma": float(self.sigma[i]), "rel_sigma_percent": rel if math.isfinite(rel) else None,
                   "well_identified": bool(self.identified[i])}
            if self.truth is not None:
                true = float(self.truth[i])
                row["truth"] = true
                row["error_percent"] = 100.0 * (self.coef[i] - true) / abs(true) if true else None
            out.append(row)
        return out

    def to_dict(self) -> dict:
        return {"step": self.step, "method": self.method, "trajectories": list(self.trajectories),
                "threshold_rel_sigma_percent": self.threshold, "held": list(self.held),
                "unexcited": list(self.unexcited), "H": self.H.tolist(), "rows": self.rows()}

    @classmethod
    def from_dict(cls, doc: dict) -> BaseFit:
        rows = doc["rows"]
        def col(key):
            return np.array([math.nan if r.get(key) is None else r[key] for r in rows], dtype=float)
        has_truth = all("truth" in r for r in rows)
        return cls(step=doc["step"], method=doc["method"], trajectories=tuple(doc["trajectories"]),
                   expressions=tuple(r["base_parameter"] for r in rows), H=np.array(doc["H"], dtype=float),
                   coef=col("identified"), sigma=col("sigma"), initial=col("initial"),
                   truth=col("truth") if has_truth else None, held=tuple(doc["held"]),
                   unexcited=tuple(doc["unexcited"]), threshold=float(doc["threshold_rel_sigma_percent"]))


@dataclass
class TrajectoryFit:
    """Measured and model forces along one trajectory (SI, after filtering/decimation).

    Attributes:
        name: trajectory name; role: ``"identification"`` or ``"validation"``.
        t: (N,) s; tau, tau_model: (N, 6) N·m / N; Theta: (N, 6) rad / m;
        X: (N, 3) end-effector pose [x m, y m, alpha rad], or None.
        tau_base: (N, 6) the forces the base-parameter fit (:class:`BaseFit`) predicts, or None.
    """

    name: str
    role: str
    t: np.ndarray
    tau: np.ndarray
    tau_model: np.ndarray
    Theta: np.ndarray
    X: np.ndarray | None = None
    tau_base: np.ndarray | None = None

    def save(self, path: Path) -> None:
        arrays = {k: getattr(self, k) for k in ("t", "tau", "tau_model", "Theta", "X", "tau_base")
                  if getattr(self, k) is not None}
        np.savez_compressed(path, name=self.name, role=self.role, **arrays)

    @classmethod
    def load(cls, path: Path) -> TrajectoryFit:
        with np.load(path) as f:
            return cls(name=str(f["name"]), role=str(f["role"]), t=f["t"], tau=f["tau"],
                       tau_model=f["tau_model"], Theta=f["Theta"], X=f["X"] if "X" in f else None,
                       tau_base=f["tau_base"] if "tau_base" in f else None)


#: an online estimate has settled when it stays within this fraction of the true value
SETTLED = 0.02


@dataclass
class OnlineTrace:
    """Estimates of an online run (:mod:`ident_hw.experiment.online`).

    Attributes:
        names: (n,) parameter names. t: (M,) campaign time of each sample, s.
        estimates: per estimator (the first is SVD-DLS), (M, n) in the units of ``names``.
        rank: (M,) excited directions of SVD-DLS after each sample (None: not recorded).
        j_rmse: per estimator, RMS a-priori prediction error over the campaign, in units of the
            output noise (``identification.online.output_noise``).
        base_names, H: the base parameters of the data, ``pi_b = H @ pi`` (b, n).
        truth: (M, n) the simulated truth at each sample (None on hardware).
        change_time: campaign time of the payload change (s), None without one.
        unexcited: the directions SVD-DLS holds at the end, readable.
        diverged: per estimator that failed numerically, the campaign time (s) it stopped at.
    """

    names: tuple[str, ...]
    t: np.ndarray
    estimates: dict[str, np.ndarray]
    rank: np.ndarray | None = None
    j_rmse: dict[str, float] = field(default_factory=dict)
    base_names: tuple[str, ...] = ()
    H: np.ndarray | None = None
    truth: np.ndarray | None = None
    change_time: float | None = None
    unexcited: tuple[str, ...] = ()
    diverged: dict[str, float] = field(default_factory=dict)

    def base(self, estimates: np.ndarray) -> np.ndarray:
        """(M, b) the base parameters of ``estimates`` (M, n)."""
        return estimates @ self.H.T

    def tracked(self) -> list[int]:
        """The base parameters whose truth changes at the payload change."""
        if self.truth is None or self.change_time is None or self.H is None:
            return []
        b = self.base(self.truth)
        return [i for i in range(b.shape[1]) if np.ptp(b[:, i]) > 1e-12 * max(np.abs(b[:, i]).max(), 1e-300)]

    def settling_time(self, estimator: str, i: int) -> float | None:
        """s from the payload change until base parameter ``i`` of ``estimator`` stays within
        :data:`SETTLED` of its new true value (None: it does not, by the end)."""
        after = self.t >= self.change_time
        est = self.base(self.estimates[estimator])[after, i]
        true = self.base(self.truth)[after, i]
        off = ~(np.abs(est - true) <= SETTLED * np.abs(true))      # NaN (a diverged estimator) is off
        if not len(off) or off[-1]:
            return None
        last_off = np.nonzero(off)[0]
        k = last_off[-1] + 1 if len(last_off) else 0
        return float(self.t[after][k] - self.change_time)

    def save(self, path: Path) -> None:
        labels = list(self.estimates)
        arrays = {f"estimates_{i}": self.estimates[k] for i, k in enumerate(labels)}
        np.savez_compressed(path, names=np.array(self.names), t=self.t, estimators=np.array(labels),
                            j_rmse=np.array([self.j_rmse.get(k, np.nan) for k in labels]),
                            rank=self.rank if self.rank is not None else np.zeros(0),
                            base_names=np.array(self.base_names), H=self.H if self.H is not None else np.zeros((0, 0)),
                            truth=self.truth if self.truth is not None else np.zeros((0, 0)),
                            change_time=np.nan if self.change_time is None else self.change_time,
                            unexcited=np.array(self.unexcited),
                            diverged=np.array([self.diverged.get(k, np.nan) for k in labels]), **arrays)

    @classmethod
    def load(cls, path: Path) -> "OnlineTrace":
        with np.load(path) as f:
            names = tuple(str(n) for n in f["names"])
            if "estimators" not in f:                  # written before the baselines were traced
                return cls(names, f["t"], {"SVD-DLS": f["estimates"]})
            labels = [str(k) for k in f["estimators"]]
            change = float(f["change_time"])
            return cls(names, f["t"], {k: f[f"estimates_{i}"] for i, k in enumerate(labels)},
                       rank=f["rank"] if f["rank"].size else None,
                       j_rmse=dict(zip(labels, (float(v) for v in f["j_rmse"]))),
                       base_names=tuple(str(n) for n in f["base_names"]), H=f["H"] if f["H"].size else None,
                       truth=f["truth"] if f["truth"].size else None,
                       change_time=None if np.isnan(change) else change,
                       unexcited=tuple(str(u) for u in f["unexcited"]),
                       diverged={k: float(v) for k, v in zip(labels, f["diverged"]) if not np.isnan(v)})


@dataclass
class Results:
    """Everything a results folder records about one campaign."""

    parameters: ParameterTable
    fits: list[TrajectoryFit] = field(default_factory=list)
    steps: list[dict] = field(default_factory=list)
    base_parameters: dict | None = None
    online: OnlineTrace | None = None
    base_fit: BaseFit | None = None
    rel_sigma_threshold: float = POORLY_IDENTIFIED_PERCENT
    #: per trajectory: what its recording covered and what the fit used (``offline.coverage``)
    trajectories: dict = field(default_factory=dict)
    #: the quality verdict (``ident_hw.experiment.quality.verdict``); None: not judged
    quality: dict | None = None


# ----------------------------------------------------------------------------- status
def mark_status(folder: str | Path, status: str) -> None:
    """Write STATUS (see the module docstring), atomically: a reader never sees half of it."""
    path = Path(folder, STATUS_FILE)
    tmp = path.with_name(STATUS_FILE + ".tmp")
    tmp.write_text(status.strip() + "\n")
    tmp.replace(path)


def final_status(results: Results) -> str:
    """``complete`` when the quality verdict passed (or there is none), else ``degraded: <reasons>``."""
    if results.quality is None or results.quality["passed"]:
        return "complete"
    return "degraded: " + "; ".join(results.quality["reasons"])


def read_status(folder: str | Path) -> str:
    path = Path(folder, STATUS_FILE)
    return path.read_text().strip() if path.is_file() else "unknown (no STATUS file)"


# ----------------------------------------------------------------------------- saving
def save_results(folder: str | Path, results: Results) -> Path:
    """Write the parameters, fits and online trace into ``folder``, then :func:`build_report`."""
    folder = Path(folder)
    (folder / "fits").mkdir(parents=True, exist_ok=True)
    doc = {"parameters": results.parameters.rows(), "rel_sigma_threshold_percent": results.rel_sigma_threshold,
           "base_fit": None if results.base_fit is None else results.base_fit.to_dict(),
           "steps": results.steps, "base_parameters": results.base_parameters,
           "trajectories": results.trajectories, "quality": results.quality}
    (folder / "parameters.json").write_text(json.dumps(doc, indent=2, default=_jsonable))
    (folder / "parameters.yaml").write_text(yaml.safe_dump(json.loads(json.dumps(doc, default=_jsonable)),
                                                           sort_keys=False))
    for fit in results.fits:
        fit.save(folder / "fits" / f"{fit.name}.npz")
    if results.online is not None:
        results.online.save(folder / "online.npz")
    return build_report(folder)


def load_results(folder: str | Path) -> Results:
    """Read back what :func:`save_results` wrote."""
    folder = Path(folder)
    path = folder / "parameters.json"
    if not path.is_file():
        raise FileNotFoundError(f"{folder} is not a results folder: no parameters.json")
    doc = json.loads(path.read_text())
    fits = [TrajectoryFit.load(p) for p in sorted((folder / "fits").glob("*.npz"))]
    fits.sort(key=lambda f: f.role != "identification")
    online = None
    if (folder / "online.npz").is_file():
        online = OnlineTrace.load(folder / "online.npz")
    base_fit = BaseFit.from_dict(doc["base_fit"]) if doc.get("base_fit") else None
    return Results(parameters=ParameterTable.from_rows(doc["parameters"]), fits=fits,
                   steps=doc.get("steps") or [], base_parameters=doc.get("base_parameters"), online=online,
                   base_fit=base_fit, rel_sigma_threshold=doc.get("rel_sigma_threshold_percent", POORLY_IDENTIFIED_PERCENT),
                   trajectories=doc.get("trajectories") or {}, quality=doc.get("quality"))


# ----------------------------------------------------------------------------- building
def metrics(results: Results) -> dict:
    """Per trajectory: role and the validation metrics per actuator (``identification.metrics``)
    of the physical parameters, and under ``base_fit`` those of the base-parameter fit."""
    out = {}
    for fit in results.fits:
        out[fit.name] = {"role": fit.role, "samples": int(len(fit.t)), **_metrics(fit.tau, fit.tau_model)}
        if fit.tau_base is not None:
            out[fit.name]["base_fit"] = _metrics(fit.tau, fit.tau_base)
    return out


def _metrics(tau: np.ndarray, tau_model: np.ndarray) -> dict:
    if not len(tau):                # nothing of the trajectory could be fitted (the verdict says why)
        nan = dict.fromkeys(ACTUATOR_NAMES, float("nan"))
        return {"rms": nan, "nrms_percent": dict(nan), "d_tau_percent": float("nan"), "j_rmse": float("nan")}
    m = validation_metrics(tau, tau_model)
    return {"rms": dict(zip(ACTUATOR_NAMES, m.rms.tolist())),
            "nrms_percent": dict(zip(ACTUATOR_NAMES, m.nrms_percent.tolist())),
            "d_tau_percent": m.d_tau_percent, "j_rmse": m.j_rmse}


def build_report(folder: str | Path) -> Path:
    """(Re)build metrics.yaml, plots, report.html and results.mat from the folder's files."""
    folder = Path(folder)
    results = load_results(folder)
    table = metrics(results)
    (folder / "metrics.yaml").write_text(yaml.safe_dump(table, sort_keys=False))
    plots = folder / "plots"
    plots.mkdir(exist_ok=True)
    jobs = []
    for fit in results.fits:
        jobs.append((f"{fit.role}: {fit.name} — measured vs model", _plot_forces, (fit, plots)))
        jobs.append((f"{fit.name}: residuals", _plot_residuals, (fit, plots)))
        jobs.append((f"{fit.name}: motion", _plot_motion, (fit, plots)))
    if results.online is not None:
        jobs.append(("online estimates", _plot_online, (results.online, results.parameters, plots)))
    images = list(zip([title for title, _, _ in jobs], _render([(f, a) for _, f, a in jobs])))
    _save_mat(folder / "results.mat", results)
    page = folder / "report.html"
    page.write_text(_html(folder, results, table, images))
    return page


def summary_lines(folder: str | Path) -> list[str]:
    """The numbers printed at the end of a run: a Table-1-like table of the fitted parameters
    (initial, identified, truth, %sigma, error vs truth), the held ones, the validation errors."""
    results = load_results(folder)
    rows = results.parameters.rows()
    truth = results.parameters.truth is not None
    head = f"  {'parameter':>10} {'unit':>9} {'initial':>11} {'identified':>11} {'%sigma':>7}"
    if truth:
        head += f" {'truth':>11} {'error %':>8}"
    lines = [f"status: {read_status(folder)}"]
    if results.trajectories:
        lines.append("recordings used:")
        lines += [f"  {name}: {coverage_text(u)}" for name, u in results.trajectories.items()]
    if any(r["step"] for r in rows):
        lines.append("physical parameters, step by step (SQP mass fit of the 3PRRR paper):")
    lines.append(head + "  step")
    for row in rows:
        if not row["step"]:
            continue
        sig = row["rel_sigma_percent"]
        text = (f"  {row['name']:>10} {row['unit']:>9} {row['initial']:>11.5g} {row['identified']:>11.5g} "
                f"{_percent(sig):>7}")
        if truth:
            err = row.get("error_percent")
            text += f" {row['truth']:>11.5g} {err if err is not None else float('nan'):>+8.2f}"
        lines.append(text + f"  {row['step']}" + ("  poorly identified" if _poorly_identified(row, results) else ""))
    held = [r["name"] for r in rows if not r["step"]]
    if held:
        lines.append(f"  held at their initial values (not fitted by any step): {', '.join(held)}")
    if results.base_fit is not None:
        lines += _base_fit_lines(results.base_fit)
    if truth:
        lines.append(_accuracy_line(rows, results))
    for name, m in metrics(results).items():
        text = f"  {m['role']:>14} {name}: d_tau = {m['d_tau_percent']:.2f} %, J_RMSE = {m['j_rmse']:.4g}"
        if "base_fit" in m:
            text += f"; base fit: d_tau = {m['base_fit']['d_tau_percent']:.2f} %"
        lines.append(text)
    if results.quality is not None:
        lines += _verdict_lines(results.quality)
    return lines


def coverage_text(used: dict) -> str:
    """``107 of 266 cycles (40 % of the trajectory), 99.1 % complete, ...`` for one recording."""
    planned = used.get("cycles_planned")
    text = f"{used['cycles']} of {planned} cycles" if planned else f"{used['cycles']} cycles"
    if used.get("coverage") is not None and used["coverage"] < 1.0:
        text += f" ({100 * used['coverage']:.0f} % of the trajectory)"
    text += f", {100 * used['valid_fraction']:.1f} % complete"
    if used.get("longest_gap_s"):
        text += f", longest gap {used['longest_gap_s']:.3g} s"
    if used.get("skipped_slots"):
        text += f", {used['skipped_slots']} SYNC slots skipped"
    if "samples_used" in used:
        text += f"; {used['samples_used']} samples after decimation fitted"
        if used.get("stretches", 1) > 1:
            text += f" from {used['stretches']} stretches"
        out = [f"{n} {rule.replace('_', ' ')}" for rule, n in (used.get("rows_left_out") or {}).items() if n]
        if out:
            text += f" (rows left out: {', '.join(out)})"
    status = str(used.get("recording_status", ""))
    if status.startswith("stopped"):
        text += f"; partial recording ({status})"
    elif status.startswith("running"):
        text += "; checkpoint of a run that did not end (its process died): partial recording"
    elif status not in ("complete", ""):
        text += f"; {status}"
    return text


def _verdict_lines(quality: dict) -> list[str]:
    """The quality verdict for the terminal: passed, or DEGRADED with one line per reason."""
    if quality["passed"]:
        return ["quality verdict: passed (identification.quality thresholds)"]
    return ["quality verdict: DEGRADED (identification.quality thresholds):"] + [f"  {r}" for r in quality["reasons"]]


def _percent(value: float | None) -> str:
    """A %σ for the terminal tables: two decimals, ``>1e4`` beyond, ``nan`` when undefined."""
    if value is None or not np.isfinite(value):
        return "nan"
    return f"{value:.2f}" if value < 1e4 else ">1e4"


def _accuracy_line(rows: list[dict], results: Results) -> str:
    """Against the simulated truth: the largest error among the well-identified estimates."""
    def largest(errors: list[tuple[float, str]], what: str) -> str:
        text = f"{len(errors)} {what}"
        if errors:
            worst = max(errors)
            text += f" (largest error {worst[0]:.2f} %, {worst[1]})"
        return text

    text = "accuracy vs truth, well identified only: " + largest(
        [(abs(r["error_percent"]), r["name"]) for r in rows
         if r["step"] and not _poorly_identified(r, results) and r.get("error_percent") is not None],
        "physical parameters")
    if results.base_fit is not None:
        text += ", " + largest([(abs(r["error_percent"]), r["base_parameter"]) for r in results.base_fit.rows()
                                if r["well_identified"] and r.get("error_percent") is not None], "base parameters")
    return text


def _poorly_identified(row: dict, results: Results) -> bool:
    """A fitted parameter whose %σ is above the threshold or undefined (an estimate of 0, at its
    bound, or without statistics)."""
    rel = row["rel_sigma_percent"]
    return bool(row["step"]) and (rel is None or not rel <= results.rel_sigma_threshold)


def _base_fit_lines(fit: BaseFit) -> list[str]:
    """The base-parameter table of :func:`summary_lines`."""
    lines = [f"base parameters, {fit.method} on {', '.join(fit.trajectories)} (step {fit.step}; "
             f"well identified: %sigma <= {fit.threshold:g}):"]
    width = max(len(e) for e in fit.expressions) if fit.expressions else 10
    head = f"  {'base parameter':<{width}} {'initial':>11} {'identified':>11} {'%sigma':>7}"
    lines.append(head + (f" {'truth':>11} {'error %':>8}" if fit.truth is not None else ""))
    for row in fit.rows():
        sig = row["rel_sigma_percent"]
        text = (f"  {row['base_parameter']:<{width}} {row['initial']:>11.5g} {row['identified']:>11.5g} "
                f"{_percent(sig):>7}")
        if fit.truth is not None:
            err = row.get("error_percent")
            text += f" {row['truth']:>11.5g} {err if err is not None else float('nan'):>+8.2f}"
        lines.append(text + ("" if row["well_identified"] else "  poorly identified"))
    if fit.held:
        lines.append(f"  held at known values during this fit: {', '.join(fit.held)}")
    if fit.unexcited:
        lines.append(f"  not excited by {', '.join(fit.trajectories)}: {', '.join(fit.unexcited)}")
    return lines


# ----------------------------------------------------------------------------- plots
def _figure(height: float) -> Figure:
    """A figure 11 in wide with fixed margins (matplotlib's automatic layouts cost most of the
    report's time: they measure every tick label of every panel)."""
    fig = Figure(figsize=(11, height))
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.8 / height, top=1 - 0.55 / height,
                        wspace=0.25, hspace=0.3)
    return fig


def _every(n: int, at_most: int = 3000) -> slice:
    return slice(None, None, max(1, n // at_most))


def _plot_forces(fit: TrajectoryFit, plots: Path) -> Path:
    fig = _figure(8)
    axes = fig.subplots(3, 2, sharex=True)
    s = _every(len(fit.t))
    for j in range(6):
        ax = axes[j % 3, j // 3]
        ax.plot(fit.t[s], fit.tau[s, j], lw=0.8, label="measured")
        ax.plot(fit.t[s], fit.tau_model[s, j], lw=1.0, ls="--", label="model")
        if fit.tau_base is not None:
            ax.plot(fit.t[s], fit.tau_base[s, j], lw=1.0, ls=":", label="base fit")
        ax.set_ylabel(f"{ACTUATOR_NAMES[j]} [{FORCE_UNITS[j]}]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    fig.suptitle(f"{fit.name} ({fit.role}): measured vs model forces")
    return _save(fig, plots / f"forces_{fit.name}.png")


def _plot_residuals(fit: TrajectoryFit, plots: Path) -> Path:
    fig = _figure(6)
    axes = fig.subplots(3, 2, sharex=True)
    s = _every(len(fit.t))
    for j in range(6):
        ax = axes[j % 3, j // 3]
        ax.plot(fit.t[s], (fit.tau - fit.tau_model)[s, j], lw=0.6, color="C3")
        ax.set_ylabel(f"{ACTUATOR_NAMES[j]} [{FORCE_UNITS[j]}]")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    fig.suptitle(f"{fit.name}: residual measured − model")
    return _save(fig, plots / f"residuals_{fit.name}.png")


def _plot_motion(fit: TrajectoryFit, plots: Path) -> Path:
    fig = _figure(3.5)
    ax_xy, ax_rev, ax_pri = fig.subplots(1, 3)
    s = _every(len(fit.t))
    if fit.X is not None:
        ax_xy.plot(fit.X[s, 0], fit.X[s, 1], lw=1.0)
        ax_xy.set_aspect("equal", adjustable="datalim")
    ax_xy.set_xlabel("x [m]")
    ax_xy.set_ylabel("y [m]")
    ax_xy.set_title("end-effector path" if fit.X is not None else "(no pose recorded)")
    for j in range(3):
        ax_rev.plot(fit.t[s], fit.Theta[s, j], lw=0.8, label=ACTUATOR_NAMES[j])
        ax_pri.plot(fit.t[s], fit.Theta[s, 3 + j], lw=0.8, label=ACTUATOR_NAMES[3 + j])
    ax_rev.set_ylabel("theta [rad]")
    ax_pri.set_ylabel("zeta [m]")
    for ax in (ax_rev, ax_pri):
        ax.set_xlabel("t [s]")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.suptitle(f"{fit.name}: motion")
    return _save(fig, plots / f"motion_{fit.name}.png")


def _plot_online(online: OnlineTrace, params: ParameterTable, plots: Path) -> Path:
    """The base parameters of the inertial parameters over time, every estimator, the truth
    (stepping at a payload change) and the change."""
    if online.H is None:           # an old trace: the physical masses and inertias of SVD-DLS
        shown = [i for i, n in enumerate(online.names) if n.startswith(("m_", "I_"))]
        values, labels, truth = next(iter(online.estimates.values())), list(online.names), None
        curves = {"SVD-DLS": values}
    else:
        inertial = [j for j, n in enumerate(online.names) if n.startswith(("m_", "I_"))]
        shown = [i for i in range(online.H.shape[0]) if np.any(online.H[i, inertial] != 0)]
        labels = list(online.base_names)
        curves = {k: online.base(v) for k, v in online.estimates.items()}
        truth = online.base(online.truth) if online.truth is not None else None
    cols = 2
    rows = max(1, math.ceil(len(shown) / cols))
    fig = _figure(2.2 * rows)
    axes = np.atleast_1d(fig.subplots(rows, cols, sharex=True)).ravel()
    for ax, i in zip(axes, shown):
        for label, values in reversed(curves.items()):     # SVD-DLS (the first) drawn on top
            ax.plot(online.t, values[:, i], lw=1.3 if label == next(iter(curves)) else 0.8, label=label)
        if truth is not None:
            ax.plot(online.t, truth[:, i], color="k", ls=":", lw=0.9, label="truth")
            # around the truth (±15 % of it, or of its change): early transients would hide the tracking
            lo, hi = float(truth[:, i].min()), float(truth[:, i].max())
            margin = max(0.15 * max(abs(lo), abs(hi)), 0.5 * (hi - lo), 1e-12)
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


def online_lines(online: OnlineTrace) -> list[str]:
    """The comparison of the online estimators, for the terminal: J_RMSE and, after a payload
    change, the settling time of each tracked base parameter."""
    tracked = online.tracked()
    lines = ["online estimators (J_RMSE: a-priori prediction error in units of the output noise"
             + (f"; settling to within {100 * SETTLED:g} % after the payload change at {online.change_time:.1f} s"
                if tracked else "") + "):"]
    for label in online.estimates:
        text = f"  {label:>10}: J_RMSE {online.j_rmse.get(label, float('nan')):8.3g}"
        if label in online.diverged:
            text += f" (diverged at {online.diverged[label]:.1f} s)"
        for i in tracked:
            settle = online.settling_time(label, i)
            text += f"; {online.base_names[i]}: " + ("not settled" if settle is None else f"{settle:.1f} s")
        lines.append(text)
    if online.unexcited:
        lines.append(f"  SVD-DLS held (not excited at the end): {'; '.join(online.unexcited)}")
    return lines


def _html_online(online: OnlineTrace) -> str:
    esc = html.escape
    tracked = online.tracked()
    head = "<tr><th>estimator</th><th>J_RMSE (noise units)</th>" + "".join(
        f"<th>settling of {esc(online.base_names[i])} (s)</th>" for i in tracked) + "</tr>"
    rows = []
    for label in online.estimates:
        cells = [label, f"diverged at {online.diverged[label]:.1f} s" if label in online.diverged
                 else _fmt(online.j_rmse.get(label), ".4g")]
        cells += ["not settled" if (s := online.settling_time(label, i)) is None else f"{s:.1f}" for i in tracked]
        rows.append("<tr>" + "".join(f"<td>{esc(str(c))}</td>" for c in cells) + "</tr>")
    change = (f"<p>Payload added at {online.change_time:.1f} s of the campaign; settled = within "
              f"{100 * SETTLED:g} % of the new true value to the end.</p>" if online.change_time is not None else "")
    held = (f"<p>SVD-DLS holds, not excited at the end: {esc('; '.join(online.unexcited))}.</p>"
            if online.unexcited else "")
    return f"<h2>Online estimation</h2>{change}<table>{head}{''.join(rows)}</table>{held}"


def _render(jobs: list[tuple]) -> list[Path]:
    """Run the plot functions ``[(function, args), ...]``, on every core where the platform forks
    (drawing the figures is most of a report's time); returns their paths in order."""
    workers = min(len(jobs), os.cpu_count() or 1)
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


# ----------------------------------------------------------------------------- exports
def _save_mat(path: Path, results: Results) -> None:
    p = results.parameters
    doc = {
        "parameter_names": np.array(p.names, dtype=object),
        "initial": p.initial, "identified": p.identified, "sigma": p.sigma,
        "lower": p.lower, "upper": p.upper,
        "fits": {f.name.replace("-", "_"): {"role": f.role, "t": f.t, "tau": f.tau, "tau_model": f.tau_model,
                                             "Theta": f.Theta, **({"X": f.X} if f.X is not None else {}),
                                             **({"tau_base": f.tau_base} if f.tau_base is not None else {})}
                 for f in results.fits},
    }
    if results.base_fit is not None:
        b = results.base_fit
        doc["base_fit"] = {"expressions": np.array(b.expressions, dtype=object), "H": b.H, "identified": b.coef,
                           "sigma": b.sigma, "initial": b.initial, **({"truth": b.truth} if b.truth is not None else {})}
    if p.truth is not None:
        doc["truth"] = p.truth
    if results.online is not None:
        doc["online"] = {"names": np.array(results.online.names, dtype=object), "t": results.online.t,
                         **{f"estimates_{k.replace(' ', '_').replace('-', '_')}": v
                            for k, v in results.online.estimates.items()}}
    scipy.io.savemat(path, doc, do_compression=True, long_field_names=True)


def _html(folder: Path, results: Results, table: dict, images: list[tuple[str, Path]]) -> str:
    esc = html.escape
    status = read_status(folder)
    p = results.parameters
    has_truth = p.truth is not None
    head = ["parameter", "unit", "initial (CAD)", "identified", "σ", "%σ"]
    head += ["truth", "error %"] if has_truth else []
    head += ["bounds", "step / method", "on this data"]
    rows, poor = [], []
    for r in p.rows():
        rel = r["rel_sigma_percent"]
        flagged = _poorly_identified(r, results)
        if flagged:
            poor.append(r["name"])
        cells = [r["name"], r["unit"], _fmt(r["initial"]), _fmt(r["identified"]) if r["step"] else "(held)",
                 _fmt(r["sigma"]), _fmt_rel(rel)]
        if has_truth:
            cells += [_fmt(r.get("truth")), _fmt(r.get("error_percent"), "+.2f")]
        cells += [f"[{_fmt(r['bounds'][0])}, {_fmt(r['bounds'][1])}]", f"{r['step']} / {r['method']}" if r["step"] else ""]
        cells.append("" if not r["step"] else
                     f"poorly identified (%σ > {results.rel_sigma_threshold:g})" if flagged else "identified")
        rows.append(("<tr class='poor'>" if flagged else "<tr>")
                    + "".join(f"<td>{esc(str(c))}</td>" for c in cells) + "</tr>")
    metric_rows = []
    for name, m in table.items():
        for label, mm in [("step by step", m)] + ([("base fit", m["base_fit"])] if "base_fit" in m else []):
            cells = [name, m["role"], label, *(_fmt(mm["nrms_percent"][a], ".2f") for a in ACTUATOR_NAMES),
                     _fmt(mm["d_tau_percent"], ".2f"), _fmt(mm["j_rmse"], ".4g")]
            metric_rows.append("<tr>" + "".join(f"<td>{esc(str(c))}</td>" for c in cells) + "</tr>")
    notes = []
    if poor:
        notes.append(f"Poorly identified on their data (%σ > {results.rel_sigma_threshold:g} %): {', '.join(poor)}.")
    base = results.base_parameters or {}
    if base.get("base_parameters") and results.base_fit is None:     # else the base-fit table shows them
        items = "".join(f"<li><code>{esc(e)}</code></li>" for e in base["base_parameters"])
        unexcited = ", ".join(base.get("unexcited") or []) or "none"
        notes.append(f"Base parameters (rank {base.get('rank')} of {base.get('n_params')}):<ul>{items}</ul>"
                     f"Not excited by the data: {esc(unexcited)}.")
    steps = "".join(f"<li>{esc(s.get('name', ''))}: {esc(str(s.get('method', '')))}; "
                    f"{esc(', '.join(s.get('free', [])))}</li>" for s in results.steps)
    figures = "".join(f"<figure><img src='{esc(str(img.relative_to(folder)))}' alt='{esc(title)}'>"
                      f"<figcaption>{esc(title)}</figcaption></figure>" for title, img in images)
    status_class = "ok" if status == "complete" else "partial"
    verdict = _html_verdict(results)
    return f"""<!doctype html>
<html><head><meta charset="utf-8"><title>ident_hw report</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:auto}} table{{border-collapse:collapse}}
td,th{{border:1px solid #bbb;padding:2px 6px;text-align:right}} td:first-child{{text-align:left}}
.partial{{color:#b00;font-weight:bold}} .ok{{color:#070}} img{{max-width:100%}} tr.poor td{{color:#b00}}</style></head>
<body><h1>3PRRR dynamic identification</h1>
<p>Status: <span class="{status_class}">{esc(status)}</span></p>
{verdict}
<h2>Parameters (like the paper's Table 1)</h2>
<table><tr>{''.join(f'<th>{esc(h)}</th>' for h in head)}</tr>{''.join(rows)}</table>
<h2>Identification steps</h2><ul>{steps}</ul>
{_html_base_fit(results.base_fit) if results.base_fit is not None else ''}
{''.join(f'<p>{n}</p>' for n in notes)}
{_html_online(results.online) if results.online is not None else ''}
<h2>Force prediction per trajectory</h2>
<p>NRMS per actuator = 100·RMS(τ − τ̂)/RMS(τ); d_τ = 100·mean(‖τ − τ̂‖/‖τ‖); J_RMSE = sqrt(mean ‖τ̂ − τ‖²) (mixed units).</p>
<table><tr><th>trajectory</th><th>role</th><th>parameters</th>{''.join(f'<th>NRMS {a} %</th>' for a in ACTUATOR_NAMES)}
<th>d_τ %</th><th>J_RMSE</th></tr>{''.join(metric_rows)}</table>
<h2>Plots</h2>{figures}
<p>Files: parameters.json/.yaml, metrics.yaml, results.mat, config.yaml, data/ (raw CAN log and decoded samples).</p>
</body></html>
"""


def _html_verdict(results: Results) -> str:
    """The recordings used and the quality verdict with its reasons."""
    esc = html.escape
    parts = []
    if results.trajectories:
        items = "".join(f"<li>{esc(name)}: {esc(coverage_text(u))}</li>" for name, u in results.trajectories.items())
        parts.append(f"<h2>Recordings used</h2><ul>{items}</ul>")
    q = results.quality
    if q is not None:
        head = ("<p class='ok'>Quality verdict: passed.</p>" if q["passed"] else
                "<p class='partial'>Quality verdict: DEGRADED.</p><ul>"
                + "".join(f"<li>{esc(r)}</li>" for r in q["reasons"]) + "</ul>")
        limits = ", ".join(f"{esc(k)} = {esc(str(v))}" for k, v in q["thresholds"].items())
        parts.append(f"<h2>Quality</h2>{head}<p>Thresholds (identification.quality): {limits}.</p>")
    return "".join(parts)


def _html_base_fit(fit: BaseFit) -> str:
    """The base-parameter table: every base parameter, the poorly identified ones marked, not hidden."""
    esc = html.escape
    head = ["base parameter", "initial (CAD)", "identified", "σ", "%σ"]
    head += ["truth", "error %"] if fit.truth is not None else []
    head += ["on this data"]
    rows = []
    for r in fit.rows():
        cells = [r["base_parameter"], _fmt(r["initial"]), _fmt(r["identified"]), _fmt(r["sigma"]),
                 _fmt_rel(r["rel_sigma_percent"])]
        if fit.truth is not None:
            cells += [_fmt(r.get("truth")), _fmt(r.get("error_percent"), "+.2f")]
        cells.append("identified" if r["well_identified"] else f"poorly identified (%σ > {fit.threshold:g})")
        rows.append(("<tr>" if r["well_identified"] else "<tr class='poor'>")
                    + "".join(f"<td>{esc(str(c))}</td>" for c in cells) + "</tr>")
    held = f" Held at known values: {esc(', '.join(fit.held))}." if fit.held else ""
    unexcited = f" Not excited by the data: {esc(', '.join(fit.unexcited))}." if fit.unexcited else ""
    return (f"<h2>Base parameters: {esc(fit.method)} on {esc(', '.join(fit.trajectories))} (step {esc(fit.step)})</h2>"
            f"<p>Each combination is what the data determine (the SVD-DLS paper); σ from the least-squares statistics "
            f"(the power-model paper). Identified: %σ ≤ {fit.threshold:g}.{held}{unexcited}</p>"
            f"<table><tr>{''.join(f'<th>{esc(h)}</th>' for h in head)}</tr>{''.join(rows)}</table>")


def _fmt_rel(value) -> str:
    """A %σ: two decimals, or ``> 1e4`` for an estimate at zero (its bound)."""
    return "> 1e4" if value is not None and math.isfinite(value) and value > 1e4 else _fmt(value, ".2f")


def _fmt(value, spec: str = ".5g") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    return format(value, spec)


def _num(value) -> float | None:
    return float(value) if math.isfinite(value) else None


def _num_in(value, default: float) -> float:
    return default if value is None else float(value)


def _jsonable(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot store {type(obj).__name__} in parameters.json")
