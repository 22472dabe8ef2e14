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

import logging
import os
import shutil
import socket
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterator

from ident_hw.config import RobotConfig, SimConfig, TrajectoryConfig, load_config, resolved_yaml
from ident_hw.progress import report_progress
from ident_hw.results import read_status
from ident_hw.results.study import (Estimate, RunOutcome, Study, StudyFile, SummaryRow, estimates_of,
                                    summarize)
from ident_hw.storage import read_file, write_file

from .folders import file_copies, new_results_folder

logger = logging.getLogger(__name__)

STUDY_FILE = "study.json"
RUNS_DIR = "runs"


class StudyError(ValueError):
    """A study that cannot run as asked (a config that is not a simulated one, a folder holding
    another study's runs); the message names the file."""


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


# ----------------------------------------------------------------------------- one run
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
        results = run_campaign(config, folder, report=False,
                               host=HostSettings.for_command(config))
        estimates, status, error = estimates_of(results), read_status(folder), None
    except Exception as exc:  # noqa: BLE001 - a failed run is a result of the study, not its end
        estimates, status, error = (), "failed", f"{type(exc).__name__}: {exc}"
    return estimates, status, error


# ----------------------------------------------------------------------------- the study
@dataclass(frozen=True)
class TaskSource:
    """What every run of a study is given: the config as one YAML text (``config_yaml``, every
    ``extends:`` merged in) and the files it names (relative path, bytes)."""

    config_yaml: str
    files: tuple[tuple[str, bytes], ...] = ()


def study_task_source(source: str, robot: RobotConfig, trajectories: Sequence[TrajectoryConfig]) -> TaskSource:
    """The config file ``source`` as one YAML text and the files it names (``robot``: its robot
    section, whose description file goes under ``description/``; ``trajectories``: its
    trajectories, whose files go under ``trajectories/``: :func:`~ident_hw.experiment.folders.file_copies`),
    as a worker on any machine needs them."""
    copies = file_copies(robot, trajectories)
    return TaskSource(resolved_yaml(source, copies.replace),
                      tuple((relative, Path(original).read_bytes()) for relative, original in copies.files))


def check_simulated(source: str, sim: SimConfig | None, simulated: bool, sync_mode: str) -> None:
    """A study needs a simulated rig (the config file ``source``'s ``sim`` section, on a bus the
    rig serves: ``simulated``) in this process, in lockstep (``sync_mode``: a run is then a pure
    function of its config and seed), and a truth to compare with."""
    if sim is None or not simulated:
        raise StudyError(f"{source}: a study runs the simulated rig: the config needs a sim: section and a "
                         f"bus the rig serves (virtual, vcan, local udp_multicast)")
    if not sim.in_process:
        raise StudyError(f"{source}: sim.in_process: false: a study's runs start their own rig (set it true)")
    if sync_mode != "lockstep":
        raise StudyError(f"{source}: bus.sync: {sync_mode}: a study needs lockstep (a run is then the "
                         f"same wherever it runs)")


def run_file(folder: Path, index: int) -> Path:
    return folder / RUNS_DIR / f"run-{index:04d}.json"


def finished(folder: Path, index: int) -> bool:
    """Run ``index`` of the study in ``folder`` gave its estimates (a run that raised runs again
    when the study is continued: its failure may have been the machine's)."""
    path = run_file(folder, index)
    return path.exists() and read_file(RunOutcome, path).error is None


def _prepare_folder(folder: Path, source: str, config_yaml: str, runs: int, perturb: float) -> None:
    """Create the study folder, or check that the one there holds the study of the config file
    ``source`` (``config_yaml``: its text), with the same perturbation of the truth."""
    source_name = Path(source).name
    (folder / RUNS_DIR).mkdir(parents=True, exist_ok=True)
    copy = folder / "config.yaml"
    if copy.exists() and copy.read_text() != config_yaml:
        raise StudyError(f"{folder}: holds a study of another config (its config.yaml differs from "
                         f"{source}); choose another --out")
    copy.write_text(config_yaml)
    study_file = folder / STUDY_FILE
    asked = runs
    if study_file.exists():
        before = read_file(StudyFile, study_file)
        if before.perturb != perturb:
            raise StudyError(f"{folder}: holds a study with --perturb {before.perturb!r}, not "
                             f"{perturb!r}; choose another --out")
        asked = max(runs, before.runs_asked)
    write_file(study_file, StudyFile(source_name, asked, perturb), indent=1)


def load_outcomes(folder: Path, runs: int) -> tuple[RunOutcome, ...]:
    """The finished runs among the first ``runs`` of the study in ``folder``."""
    found = []
    for i in range(runs):
        path = run_file(folder, i)
        if path.exists():
            found.append(read_file(RunOutcome, path))
    return tuple(found)


def run_study(config_path: str | Path, folder: str | Path, runs: int, *, workers: int | None = None,
              scheduler: str | None = None, perturb: float = 0.0) -> Study:
    """Run the ``runs`` campaigns of ``config_path`` that ``folder`` does not hold yet, and
    summarize all of them.

    Args:
        config_path: a simulated config (:func:`check_simulated`).
        folder: the study folder (created; a folder holding this config's study is continued).
        runs: how many runs the study has (run ``i`` with seed ``sim.seed + i``).
        workers: worker processes of a Dask ``LocalCluster`` on this machine (default: the CPUs
            this process may use); 0: every run in this process, one after the other, no Dask.
        scheduler: the address of a running Dask scheduler (``tcp://HOST:PORT``) whose workers run
            the study instead; they need ident_hw installed, nothing of this machine.
        perturb: each run but run 0 on a truth of its own, drawn around the config's with this
            relative spread (``sim.perturb``); 0: every run on the config's truth.
    """
    if runs < 1:
        raise StudyError(f"--runs must be at least 1, got {runs}")
    if not 0.0 <= perturb < 1.0:
        raise StudyError(f"--perturb must be in [0, 1), got {perturb}")
    config = load_config(config_path)
    check_simulated(config.source, config.sim, config.simulated, config.sync_mode)
    assert config.sim is not None
    folder = Path(folder)
    source = study_task_source(config.source, config.robot, config.trajectories)
    _prepare_folder(folder, config.source, source.config_yaml, runs, perturb)
    tasks = [RunTask(i, config.sim.seed + i, source.config_yaml, source.files, perturb)
             for i in range(runs) if not finished(folder, i)]
    done, started = runs - len(tasks), time.monotonic()
    report_progress(logger, "study", done, runs, "run")
    for k, outcome in enumerate(_execute(tasks, workers, scheduler), 1):
        write_file(run_file(folder, outcome.index), outcome, indent=1)
        done += 1
        rate = k / (time.monotonic() - started)
        logger.info(f"run {outcome.index} (seed {outcome.seed}): {outcome.status.split(':')[0]} in "
                    f"{outcome.wall_seconds:.0f} s; {done} of {runs} done, about {(runs - done) / rate / 60:.1f} min left")
        report_progress(logger, "study", done, runs, "run")
    outcomes = load_outcomes(folder, runs)
    study = Study(folder, Path(config.source).name, runs, outcomes, summarize(outcomes))
    asked = read_file(StudyFile, folder / STUDY_FILE)
    write_file(folder / STUDY_FILE, replace(asked, summary=tuple(SummaryRow.of(s) for s in study.summary),
                                            runs_finished=len(outcomes), runs_failed=len(study.failed),
                                            calibrated_failure_rate=study.chance_of_failing), indent=1)
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
