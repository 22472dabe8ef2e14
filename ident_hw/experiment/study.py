"""Monte-Carlo studies: many simulated campaigns of one config, each with its own noise seed and
each identified as ``ident-hw run`` does; then, per parameter, how its errors compare with the
standard deviation the campaign reported. One run cannot tell noise from bias; many runs can.

What a run draws is what differs between two campaigns on a real rig: the current noise, and
where the encoders count (``sim.encoder_edges: random``, a fraction of a count per axis; run 0
keeps the config's own). With the count edges fixed, every run would read the same rounded
positions along the same motion, and their errors, the same in every run, would show as a bias.
With ``perturb`` (``--perturb``) each run but run 0 also has a truth of its own, drawn around
the config's (``sim.perturb``, :func:`ident_hw.config.robots.perturbed`): an identification
that only works near the CAD values, or a σ that holds for one truth only, shows.

    study = run_study("configs/sim-3prrr.yaml", "results/study-sim-3prrr", runs=40)
    study.summary      # one ParameterSummary per parameter

A run is a pure function of its config and its seed (the simulated rig in lockstep): :func:`run_one`
takes the config as text (and the files it names) and returns a small :class:`RunOutcome`, so it
gives the same answer in this process, in a worker process of this machine or on another machine
of a Dask cluster (:func:`run_study`'s ``scheduler``). Run ``i`` has the seed ``sim.seed + i``:
run 0 is the config's own campaign (:func:`run_yaml`).

The study folder::

    study.json           what was asked (the config's name, the runs, the perturbation) and the summary
    config.yaml          the config, every ``extends:`` merged in (a described robot's file beside it)
    runs/run-0007.json   one finished run: seed, STATUS, wall time, worker, every estimate with σ
    study.html, plots/   the report (:mod:`ident_hw.report.study`)

Running a study into a folder that holds one of the same config continues it: finished runs
are kept, the missing ones and those that raised run. A run that raised leaves its folder (what it
recorded, its partial results) on the machine it ran on; its error says which and where.
"""

from __future__ import annotations

import functools
import json
import math
import os
import shutil
import socket
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator

import numpy as np
from scipy import special

from ident_hw.config import Config, load_config, resolved_yaml
from ident_hw.identification.intervals import coverage_factor
from ident_hw.results import Results, read_status, write_atomically

from .folders import DESCRIPTION_DIR, new_results_folder

#: z of the two-sided 95 % interval of a normal error (1.96)
Z95 = float(coverage_factor(math.inf))
#: what an honest σ must show over a study (issue 30): the 95 % interval's coverage at least this ...
COVERAGE_TARGET = 0.90
#: ... and the mean error at most this many mean σ
BIAS_TARGET = 0.5
#: a parameter the campaigns call well identified in at least this share of the runs is a claim
CLAIMED_SHARE = 0.5
#: the 95 % interval's coverage where the σ is calibrated (what ``coverage_chance`` assumes)
CALIBRATED_COVERAGE = 0.95
#: a coverage below :data:`COVERAGE_TARGET` that calibrated σs would give somewhere among a study's
#: claimed parameters in at least this share of studies is reported as within chance (it still fails
#: the target): each parameter's ``coverage_chance`` against this level over their number
CHANCE_LEVEL = 0.05
#: simulated studies behind :func:`calibrated_failure_rate`, and their seed (the same figure on any host)
CHANCE_STUDIES = 4000
CHANCE_SEED = 20261127

STUDY_FILE = "study.json"
RUNS_DIR = "runs"


class StudyError(ValueError):
    """A study that cannot run as asked (a config that is not a simulated one, a folder holding
    another study's runs); the message names the file."""


# ----------------------------------------------------------------------------- records
@dataclass(frozen=True)
class Estimate:
    """One parameter's estimate in one run: ``kind`` ``physical`` (a row of the parameter table)
    or ``base`` (a base parameter of the base fit, ``name`` its expression); SI units."""

    kind: str
    name: str
    value: float
    sigma: float | None
    truth: float
    well_identified: bool
    #: the effective degrees of freedom of ``sigma`` (:mod:`ident_hw.identification.intervals`);
    #: None: infinite (the normal 95 % interval, ±1.96σ)
    dof: float | None = None

    @property
    def covered(self) -> bool:
        """The run's 95 % interval (``±k σ``, :func:`coverage_factor` of :attr:`dof`) holds the truth."""
        k = coverage_factor(math.inf if self.dof is None else self.dof)
        return abs(self.value - self.truth) <= k * self.sigma


@dataclass(frozen=True)
class RunOutcome:
    """What one simulated campaign of a study gave: its ``seed``, the results folder's ``status``,
    the wall time (s) and the host it ran on (for the record: no value depends on it), every
    estimate with a known truth; ``error``: why the run gave none (an exception's text)."""

    index: int
    seed: int
    status: str
    wall_seconds: float
    host: str
    estimates: tuple[Estimate, ...]
    error: str | None = None

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> RunOutcome:
        return cls(**{**data, "estimates": tuple(Estimate(**e) for e in data["estimates"])})


@dataclass(frozen=True)
class RunTask:
    """One run as a worker gets it: the config as YAML text, the files it names (relative path,
    bytes), the run's index and seed, and the relative spread of its truth (``sim.perturb``; 0:
    the config's). Nothing in it refers to the machine that made it."""

    index: int
    seed: int
    config_yaml: str
    files: tuple[tuple[str, bytes], ...] = ()
    perturb: float = 0.0


@dataclass(frozen=True)
class ParameterSummary:
    """One parameter over the runs that estimated it with a σ (SI units).

    Attributes:
        runs: how many runs; ``claimed_share``: the share of them that called it well identified.
        mean_error, std_error: mean and empirical standard deviation of estimate - truth.
        mean_sigma: the mean σ the runs reported; ``sigma_ratio`` = std_error / mean_sigma (1 for
            an honest σ of an unbiased estimate).
        coverage: the share of runs whose 95 % interval holds the truth (0.95 for an honest σ):
            ±1.96σ, wider where part of σ is the spread of a few encoder draws (:attr:`Estimate.covered`).
        mean_z: the mean of (estimate - truth) / σ; ``bias_sigmas`` = mean_error / mean_sigma.
    """

    kind: str
    name: str
    truth: float                # run 0's (the config's own; with --perturb each run has its own)
    runs: int
    claimed_share: float
    mean_error: float
    std_error: float
    mean_sigma: float
    coverage: float
    mean_z: float

    @property
    def sigma_ratio(self) -> float:
        return self.std_error / self.mean_sigma if self.mean_sigma > 0 else math.nan

    @property
    def bias_sigmas(self) -> float:
        return self.mean_error / self.mean_sigma if self.mean_sigma > 0 else math.nan

    @property
    def claimed(self) -> bool:
        """The campaigns call it well identified (in at least :data:`CLAIMED_SHARE` of the runs)."""
        return self.claimed_share >= CLAIMED_SHARE

    @property
    def coverage_chance(self) -> float:
        """The probability that a calibrated σ (each run's 95 % interval holding the truth with
        probability :data:`CALIBRATED_COVERAGE`, the runs independent) covers the truth in at most
        as many of :attr:`runs` runs as this parameter's did: the binomial distribution's lower tail.
        A 40-run study of a calibrated σ falls below 90 % coverage in about 5 % of studies; among
        thirty parameters, one or two do by chance alone."""
        covered = round(self.coverage * self.runs)
        return float(special.bdtr(covered, self.runs, CALIBRATED_COVERAGE))

    @property
    def unbiased(self) -> bool:
        """``|mean error|`` at most :data:`BIAS_TARGET` mean σ."""
        return abs(self.bias_sigmas) <= BIAS_TARGET

    @property
    def honest(self) -> bool:
        """Its σ tells the truth: coverage at least :data:`COVERAGE_TARGET`, and :attr:`unbiased`."""
        return self.coverage >= COVERAGE_TARGET and self.unbiased

    def to_dict(self) -> dict:
        return dict(asdict(self), sigma_ratio=self.sigma_ratio, bias_sigmas=self.bias_sigmas,
                    claimed=self.claimed, honest=self.honest, coverage_chance=self.coverage_chance)


@dataclass(frozen=True)
class Study:
    """A study folder's runs (by index) and their per-parameter summary."""

    folder: Path
    config_name: str
    runs_asked: int
    outcomes: tuple[RunOutcome, ...]
    summary: tuple[ParameterSummary, ...]

    @property
    def failed(self) -> tuple[RunOutcome, ...]:
        return tuple(o for o in self.outcomes if o.error is not None)

    @property
    def estimated_runs(self) -> int:
        """The runs that gave estimates (finished, not failed)."""
        return len(self.outcomes) - len(self.failed)

    @functools.cached_property
    def chance_of_failing(self) -> float | None:
        """How often σs that are exactly calibrated would fail this study's bar for at least one of
        its claimed parameters (:func:`calibrated_failure_rate`, with as many runs as this study
        finished and the correlation of the claimed parameters' z-scores over the runs that
        estimated them all); None without a claimed parameter or a finished run. Simulated once
        per study (``study.json``, the terminal and ``study.html`` all show it)."""
        claimed = [(s.kind, s.name) for s in self.summary if s.claimed]
        runs = self.estimated_runs
        if not claimed or runs < 1:
            return None
        z = []
        for outcome in self.outcomes:
            by_key = {(e.kind, e.name): e for e in outcome.estimates if _has_sigma(e)}
            if all(k in by_key for k in claimed):
                z.append([(by_key[k].value - by_key[k].truth) / by_key[k].sigma for k in claimed])
        correlation = np.eye(len(claimed))
        if len(z) > 2:
            with np.errstate(invalid="ignore", divide="ignore"):
                sample = np.corrcoef(np.array(z), rowvar=False)
            correlation = np.where(np.isfinite(sample), sample, correlation)
        return calibrated_failure_rate(np.atleast_2d(correlation), runs)


def calibrated_failure_rate(correlation: np.ndarray, runs: int, studies: int = CHANCE_STUDIES,
                            seed: int = CHANCE_SEED) -> float:
    """The share of ``runs``-run studies in which calibrated σs fail the bar (coverage of the 95 %
    interval below :data:`COVERAGE_TARGET`, or a mean error beyond :data:`BIAS_TARGET` σ) for at
    least one of ``len(correlation)`` parameters whose errors in one run are correlated as
    ``correlation`` (m, m) says: ``studies`` studies simulated, each run's z-scores normal with
    that correlation (its nearest positive semi-definite matrix). A study's bar is a family of
    tests: with thirty parameters, exactly calibrated σs fail it somewhere in most 40-run studies;
    this figure says how often, so a study's misses can be told from chance."""
    values, vectors = np.linalg.eigh(0.5 * (correlation + correlation.T))
    root = vectors * np.sqrt(np.clip(values, 0.0, None))                 # root @ root.T = correlation
    rng = np.random.default_rng(seed)
    failing, chunk = 0, max(1, 200_000 // max(1, runs * len(correlation)))
    for start in range(0, studies, chunk):
        n = min(chunk, studies - start)
        z = rng.standard_normal((n, runs, len(correlation))) @ root.T    # (studies, runs, m)
        coverage = np.mean(np.abs(z) <= Z95, axis=1)
        biased = np.abs(z.mean(axis=1)) > BIAS_TARGET
        failing += int(np.sum(np.any((coverage < COVERAGE_TARGET) | biased, axis=1)))
    return failing / studies


# ----------------------------------------------------------------------------- one run
def estimates_of(results: Results) -> tuple[Estimate, ...]:
    """Every estimate of a campaign's results whose truth is known and that was fitted: the
    physical parameters (held ones left out), then the base parameters of the base fit."""
    out = [Estimate("physical", r.name, r.identified, r.sigma, r.truth, r.well_identified, _dof(r.dof))
           for r in results.parameter_rows() if r.truth is not None and r.step]
    out += [Estimate("base", r.expression, r.identified, r.sigma, r.truth, r.well_identified, _dof(r.dof))
            for r in results.base_rows() if r.truth is not None]
    return tuple(out)


def _dof(dof: float) -> float | None:
    """``dof`` as a run file holds it (JSON has no infinity: None)."""
    return dof if math.isfinite(dof) else None


def run_yaml(task: RunTask) -> str:
    """The config of one run, over the study's ``config.yaml``: its seed and, but for run 0 (the
    config's own campaign, ``ident-hw run`` of the config), count edges and, with ``perturb``, a
    truth of its own."""
    own = ", encoder_edges: random" if task.index else ""
    if task.index and task.perturb:
        own += f", perturb: {task.perturb!r}"
    return f"extends: config.yaml\nsim: {{seed: {task.seed}{own}}}\n"


def run_one(task: RunTask) -> RunOutcome:
    """One campaign of the study, identified as ``ident-hw run`` does (without its report), in a
    temporary folder of the machine it runs on; a pure function of ``task``. The linear algebra
    runs on one thread (``threadpoolctl``): a BLAS splits its sums by its thread count, and a
    worker process (Dask starts them with one) must give the bits this process gives. The folder
    goes when the run gave its estimates; a run that raised keeps it (its recordings, its partial
    results), and its error says on which host and where."""
    from threadpoolctl import threadpool_limits

    started = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix=f"ident-hw-study-{task.index:04d}-"))
    with threadpool_limits(limits=1):
        estimates, status, error = _campaign(task, tmp)
    host = socket.gethostname()
    if error is None:
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        error += f" (the run's folder is kept on {host}: {tmp})"
    return RunOutcome(task.index, task.seed, status, time.perf_counter() - started, host, estimates, error)


def _campaign(task: RunTask, tmp: Path) -> tuple[tuple[Estimate, ...], str, str | None]:
    """The estimates, STATUS and error (None: it finished) of ``task``'s campaign in ``tmp``."""
    from .runner import run_campaign
    from .session import HostSettings
    for relative, data in task.files:
        (tmp / relative).parent.mkdir(parents=True, exist_ok=True)
        (tmp / relative).write_bytes(data)
    (tmp / "config.yaml").write_text(task.config_yaml)
    (tmp / "run.yaml").write_text(run_yaml(task))
    try:
        config = load_config(tmp / "run.yaml")
        folder = new_results_folder(config, tmp / "results", "study")
        results = run_campaign(config, folder, show_progress=False, report=False,
                               host=HostSettings.for_command(config))
        estimates, status, error = estimates_of(results), read_status(folder), None
    except Exception as exc:  # noqa: BLE001 - a failed run is a result of the study, not its end
        estimates, status, error = (), "failed", f"{type(exc).__name__}: {exc}"
    return estimates, status, error


# ----------------------------------------------------------------------------- the summary
def _has_sigma(e: Estimate) -> bool:
    """``e`` has a σ a study can judge: finite and positive."""
    return e.sigma is not None and math.isfinite(e.sigma) and e.sigma > 0


def summarize(outcomes: Iterable[RunOutcome]) -> tuple[ParameterSummary, ...]:
    """Per parameter (in the order the first run lists them), over the runs that estimated it
    with a finite σ: see :class:`ParameterSummary`."""
    by_key: dict[tuple[str, str], list[Estimate]] = {}
    for outcome in outcomes:
        for e in outcome.estimates:
            if _has_sigma(e):
                by_key.setdefault((e.kind, e.name), []).append(e)
    out = []
    for (kind, name), estimates in by_key.items():
        error = np.array([e.value - e.truth for e in estimates])
        sigma = np.array([e.sigma for e in estimates])
        z = error / sigma
        out.append(ParameterSummary(
            kind=kind, name=name, truth=estimates[0].truth, runs=len(estimates),
            claimed_share=float(np.mean([e.well_identified for e in estimates])),
            mean_error=float(error.mean()), std_error=float(error.std(ddof=1)) if len(error) > 1 else math.nan,
            mean_sigma=float(sigma.mean()), coverage=float(np.mean([e.covered for e in estimates])),
            mean_z=float(z.mean())))
    return tuple(out)


# ----------------------------------------------------------------------------- the study
def study_task_source(config: Config) -> tuple[str, tuple[tuple[str, bytes], ...]]:
    """The config as one YAML text and the files it names (a described robot's description file,
    under ``description/``), as a worker on any machine needs them."""
    described = config.robot.described
    if described is None:
        return resolved_yaml(config.source), ()
    relative = (Path(DESCRIPTION_DIR) / Path(described.description).name).as_posix()
    return (resolved_yaml(config.source, {"robot.described.description": relative}),
            ((relative, Path(described.description).read_bytes()),))


def check_config(config: Config) -> None:
    """A study needs a simulated rig in this process, in lockstep (a run is then a pure function
    of its config and seed), and a truth to compare with."""
    where = config.source
    if config.sim is None or not config.simulated:
        raise StudyError(f"{where}: a study runs the simulated rig: the config needs a sim: section and a "
                         f"bus the rig serves (virtual, vcan, local udp_multicast)")
    if not config.sim.in_process:
        raise StudyError(f"{where}: sim.in_process: false: a study's runs start their own rig (set it true)")
    if config.sync_mode != "lockstep":
        raise StudyError(f"{where}: bus.sync: {config.sync_mode}: a study needs lockstep (a run is then the "
                         f"same wherever it runs)")


def run_file(folder: Path, index: int) -> Path:
    return folder / RUNS_DIR / f"run-{index:04d}.json"


def finished(folder: Path, index: int) -> bool:
    """Run ``index`` of the study in ``folder`` gave its estimates (a run that raised runs again
    when the study is continued: its failure may have been the machine's)."""
    path = run_file(folder, index)
    return path.exists() and json.loads(path.read_text()).get("error") is None


def _write_json(path: Path, data) -> None:
    write_atomically(path, json.dumps(data, indent=1))


def _prepare_folder(folder: Path, config: Config, config_yaml: str, runs: int, perturb: float) -> None:
    """Create the study folder, or check that the one there holds this config's study, with the
    same perturbation of the truth."""
    (folder / RUNS_DIR).mkdir(parents=True, exist_ok=True)
    copy = folder / "config.yaml"
    if copy.exists() and copy.read_text() != config_yaml:
        raise StudyError(f"{folder}: holds a study of another config (its config.yaml differs from "
                         f"{config.source}); choose another --out")
    copy.write_text(config_yaml)
    study_file = folder / STUDY_FILE
    asked = runs
    if study_file.exists():
        before = json.loads(study_file.read_text())
        if before.get("perturb", 0.0) != perturb:
            raise StudyError(f"{folder}: holds a study with --perturb {before.get('perturb', 0.0)!r}, not "
                             f"{perturb!r}; choose another --out")
        asked = max(runs, before.get("runs_asked", runs))
    _write_json(study_file, {"config": Path(config.source).name, "runs_asked": asked, "perturb": perturb})


def load_outcomes(folder: Path, runs: int) -> tuple[RunOutcome, ...]:
    """The finished runs among the first ``runs`` of the study in ``folder``."""
    found = []
    for i in range(runs):
        path = run_file(folder, i)
        if path.exists():
            found.append(RunOutcome.from_dict(json.loads(path.read_text())))
    return tuple(found)


def run_study(config_path: str | Path, folder: str | Path, runs: int, *, workers: int | None = None,
              scheduler: str | None = None, perturb: float = 0.0,
              on_outcome: Callable[[RunOutcome, int, int], None] | None = None) -> Study:
    """Run the ``runs`` campaigns of ``config_path`` that ``folder`` does not hold yet, and
    summarize all of them.

    Args:
        config_path: a simulated config (:func:`check_config`).
        folder: the study folder (created; a folder holding this config's study is continued).
        runs: how many runs the study has (run ``i`` with seed ``sim.seed + i``).
        workers: worker processes of a Dask ``LocalCluster`` on this machine (default: the CPUs
            this process may use); 0: every run in this process, one after the other, no Dask.
        scheduler: the address of a running Dask scheduler (``tcp://HOST:PORT``) whose workers run
            the study instead; they need ident_hw installed, nothing of this machine.
        perturb: each run but run 0 on a truth of its own, drawn around the config's with this
            relative spread (``sim.perturb``); 0: every run on the config's truth.
        on_outcome: called with each finished run, the runs finished and the runs asked (progress).
    """
    if runs < 1:
        raise StudyError(f"--runs must be at least 1, got {runs}")
    if not 0.0 <= perturb < 1.0:
        raise StudyError(f"--perturb must be in [0, 1), got {perturb}")
    config = load_config(config_path)
    check_config(config)
    folder = Path(folder)
    config_yaml, files = study_task_source(config)
    _prepare_folder(folder, config, config_yaml, runs, perturb)
    tasks = [RunTask(i, config.sim.seed + i, config_yaml, files, perturb)
             for i in range(runs) if not finished(folder, i)]
    done = runs - len(tasks)
    for outcome in _execute(tasks, workers, scheduler):
        _write_json(run_file(folder, outcome.index), outcome.to_dict())
        done += 1
        if on_outcome is not None:
            on_outcome(outcome, done, runs)
    outcomes = load_outcomes(folder, runs)
    study = Study(folder, Path(config.source).name, runs, outcomes, summarize(outcomes))
    data = json.loads((folder / STUDY_FILE).read_text())
    data["summary"] = [s.to_dict() for s in study.summary]
    data["runs_finished"], data["runs_failed"] = len(outcomes), len(study.failed)
    data["calibrated_failure_rate"] = study.chance_of_failing
    _write_json(folder / STUDY_FILE, data)
    return study


def _execute(tasks: list[RunTask], workers: int | None, scheduler: str | None) -> Iterator[RunOutcome]:
    """The outcomes of ``tasks`` as they finish: in this process (``workers == 0``), else on Dask."""
    if not tasks:
        return
    if workers == 0 and scheduler is None:
        for task in tasks:
            yield run_one(task)
        return
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise StudyError("a study on worker processes needs Dask: pip install 'ident-hw[study]' "
                         "(or --workers 0: every run in this process)") from None
    if scheduler is not None:
        client, cluster = Client(scheduler), None
    else:
        n = workers or (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count())
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address=None)
        client = Client(cluster)
    try:
        futures = [client.submit(run_one, task, pure=False, key=f"run-{task.index:04d}") for task in tasks]
        for future in as_completed(futures):
            yield future.result()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
