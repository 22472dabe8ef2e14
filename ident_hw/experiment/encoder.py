"""How far the estimates move with the encoders' resolution: re-read draws of the recorded motion.

A position read in whole encoder counts is off by up to half a count, and that error is a
function of the position. The identification differentiates the positions twice, so the error
reaches the regressor as acceleration noise; and where a trajectory passes the same positions
again (a periodic excitation repeated for ten cycles), it meets the same errors again: they do
not average down as the least-squares statistics assume of independent rows. On the main job the
least-squares sigma of the inertia terms was a third to a half of their spread over encoders
whose count edges lie elsewhere (``benchmarks/bench_bias_sources.py``, source ``phase``).

The spread is measured from the data, not assumed: each draw reads the recorded positions,
smoothed, again with every axis's count edges shifted by a random fraction of a count (as two
homings of one rig differ), is prepared as the recording was (:func:`ident_hw.experiment.uncertainty.reread_draws`)
and fitted on the same columns with the same weights; the covariance of the draws' estimates is
added to the least-squares one (:func:`spread_covariance`). The draws are seeded: the same
recordings give the same sigma on any host.
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from drivers.recording import Recording
from ident_hw.filtering import POLYNOMIAL, lowpass

from .recordings import identification_valid

#: seed of the count-edge shifts (fixed: a result is a function of its recordings)
SEED = 20261126


def count_shifts(draws: int, axes: int, seed: int = SEED) -> np.ndarray:
    """(draws, axes): each draw's shift of each axis's count edges, in counts, uniform in [-0.5, 0.5)."""
    return np.random.default_rng(seed).uniform(-0.5, 0.5, (draws, axes))


def smoothed_positions(rec: Recording, sample_rate: float, cutoff_hz: float, order: int) -> np.ndarray:
    """(N, a) the recorded positions, sampled at ``sample_rate`` (Hz, the recording's SYNC rate),
    low-passed at ``cutoff_hz`` (the identification's own filter, each end extended by its
    polynomial; rows without a valid position bridged linearly): the motion the draws of
    :func:`reread` read again, the same for every draw."""
    valid = identification_valid(rec)
    smooth = np.array(rec.position, dtype=float)
    for j in range(smooth.shape[1]):
        ok = valid[:, j]
        if ok.any() and not ok.all():
            smooth[~ok, j] = np.interp(rec.t[~ok], rec.t[ok], smooth[ok, j])
    if len(rec.t) > 30 and cutoff_hz < 0.5 * sample_rate:
        smooth = lowpass(smooth, sample_rate, cutoff_hz, order, (POLYNOMIAL, POLYNOMIAL))
    return smooth


def reread(rec: Recording, smooth: np.ndarray, counts_per_unit: np.ndarray, shift: np.ndarray) -> Recording:
    """``rec`` with its positions read again by encoders of ``counts_per_unit`` (a,) whose count
    edges are moved by ``shift`` (a,) counts: ``smooth`` (N, a, :func:`smoothed_positions`)
    rounded to the shifted grid. Rows without a valid position keep their value."""
    counts = np.round(smooth * counts_per_unit + shift) - shift
    return dataclasses.replace(rec, position=np.where(identification_valid(rec), counts / counts_per_unit,
                                                      rec.position))


#: the mean resultant length of the count phases above which an axis's positions lie on one grid
#: of whole counts (1 on the grid, whatever its offset; about ``1/sqrt(N)`` for positions that are not)
ON_COUNT_GRID = 0.999


def uncounted_axes(rec: Recording, counts_per_unit: np.ndarray) -> tuple[int, ...]:
    """The axes of ``rec`` whose valid positions are not whole counts of encoders of
    ``counts_per_unit`` (a,): a recording made elsewhere (positions resampled, converted, or
    exact, as a simulation's truth), which the draws of :func:`reread` cannot stand for: they
    would round positions that were never rounded, and the correction for the encoders' noise
    (:func:`ident_hw.identification.least_squares.compensated`) would remove noise that is not
    there. An axis is on its grid when ``|mean(exp(2 pi i x))| >= ON_COUNT_GRID`` over its
    positions ``x`` in counts (a grid offset by a constant, a home between two counts, passes)."""
    valid = identification_valid(rec)
    off = []
    for j, per_unit in enumerate(np.asarray(counts_per_unit, dtype=float)):
        counts = rec.position[valid[:, j], j] * per_unit
        if counts.size and abs(np.mean(np.exp(2j * np.pi * counts))) < ON_COUNT_GRID:
            off.append(j)
    return tuple(off)


def spread_covariance(estimates: Sequence[np.ndarray], m: int) -> np.ndarray:
    """(m, m) sample covariance of the draws' estimates (each (m,)); zeros with fewer than two."""
    if len(estimates) < 2:
        return np.zeros((m, m))
    return np.atleast_2d(np.cov(np.asarray(estimates, dtype=float).reshape(len(estimates), m), rowvar=False))
