"""The results of a Monte-Carlo study (:mod:`ident_hw.experiment.study` runs it): each run's
estimates with their σ and truth (:class:`RunOutcome`, ``runs/run-0007.json``), and per parameter
how its errors compare with the σ the runs reported (:class:`ParameterSummary`, :func:`summarize`;
``study.json``, :class:`StudyFile`). The report (:mod:`ident_hw.report.study`) renders them."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Iterable, cast

import numpy as np
from scipy import special

from ident_hw.identification.intervals import coverage_factor
from ident_hw.storage import NONE, stored

from .objects import Results

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
        if self.sigma is None:
            raise ValueError(f"{self.kind} {self.name}: no sigma, no interval to hold the truth")
        k = float(coverage_factor(math.inf if self.dof is None else self.dof))
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


@dataclass(frozen=True)
class SummaryRow:
    """One parameter of ``study.json``'s summary: a :class:`ParameterSummary`'s figures and those
    computed from them (what the report shows), as they were when the study was summarised."""

    kind: str
    name: str
    truth: float
    runs: int
    claimed_share: float
    mean_error: float
    std_error: float
    mean_sigma: float
    coverage: float
    mean_z: float
    sigma_ratio: float
    bias_sigmas: float
    claimed: bool
    honest: bool
    coverage_chance: float

    @classmethod
    def of(cls, s: ParameterSummary) -> SummaryRow:
        return cls(**{f.name: getattr(s, f.name) for f in fields(cls)})


def _not_summarised(study: StudyFile) -> bool:
    return study.runs_finished is None


@dataclass(frozen=True)
class StudyFile:
    """``study.json``: what was asked (the ``config`` file's name, the runs, the perturbation of
    the truth) and, once the runs are summarised, the summary, the runs finished and failed and
    :attr:`Study.chance_of_failing` (these stored only then)."""

    config: str
    runs_asked: int
    perturb: float = 0.0
    summary: tuple[SummaryRow, ...] = field(default=(), metadata=stored(record=_not_summarised))
    runs_finished: int | None = field(default=None, metadata=stored(NONE))
    runs_failed: int | None = field(default=None, metadata=stored(NONE))
    calibrated_failure_rate: float | None = field(default=None, metadata=stored(record=_not_summarised))


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
                z.append([(by_key[k].value - by_key[k].truth) / cast(float, by_key[k].sigma) for k in claimed])
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



# ----------------------------------------------------------------------------- one run's estimates
def estimates_of(results: Results) -> tuple[Estimate, ...]:
    """Every estimate of a campaign's results whose truth is known and that was fitted: the
    physical parameters (held ones left out), then the base parameters of the base fit."""
    out = [Estimate("physical", r.name, r.identified, r.sigma, r.truth, r.well_identified, _dof(r.dof))
           for r in results.parameter_rows() if r.truth is not None and r.step]
    out += [Estimate("base", r.base_parameter, r.identified, r.sigma, r.truth, r.well_identified, _dof(r.dof))
            for r in results.base_rows() if r.truth is not None]
    return tuple(out)


def _dof(dof: float) -> float | None:
    """``dof`` as a run file holds it (JSON has no infinity: None)."""
    return dof if math.isfinite(dof) else None


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
