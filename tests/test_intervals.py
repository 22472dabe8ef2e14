"""The 95 % interval of a σ partly estimated from a few draws (ident_hw.identification.intervals),
against Monte-Carlo draws of the situation it describes: an error of known spread, a σ whose one
part is the sample standard deviation of D draws and whose other part is exact."""

import numpy as np
import pytest
from scipy import stats

from ident_hw.identification.intervals import coverage_factor, effective_dof

TRIALS = 400_000        # the coverage of a 95 % interval then known to ±0.07 % (two standard errors)


def _coverage(share: float, draws: int, k_of) -> float:
    """The share of ``TRIALS`` errors (standard normal) within ``±k σ``, where σ² = (1 - share)
    exact + ``share`` × the sample variance of ``draws`` normal draws (unit variance on average),
    ``k_of(sigma, draws_sigma)`` the factor of each trial."""
    rng = np.random.default_rng(7)
    error = rng.standard_normal(TRIALS)
    sample_var = share * rng.chisquare(draws - 1, TRIALS) / (draws - 1)
    sigma = np.sqrt(1.0 - share + sample_var)
    return float(np.mean(np.abs(error) <= k_of(sigma, np.sqrt(sample_var)) * sigma))


def test_a_sigma_from_draws_alone_gets_students_t_of_draws_minus_one():
    dof = effective_dof(np.array([2.0, 0.3]), np.array([2.0, 0.3]), 8)
    assert dof == pytest.approx([7.0, 7.0])
    assert coverage_factor(dof) == pytest.approx(stats.t.ppf(0.975, 7))     # 2.365


def test_without_draws_the_interval_is_the_normal_one():
    assert coverage_factor(effective_dof(1.0, 0.0, 8)) == pytest.approx(1.959964, abs=1e-6)
    assert coverage_factor(effective_dof(1.0, 0.5, 1)) == pytest.approx(1.959964, abs=1e-6)
    assert coverage_factor(np.inf) == pytest.approx(stats.norm.ppf(0.975))


@pytest.mark.parametrize("share", [1.0, 0.72, 0.5, 0.2])
def test_the_interval_holds_the_truth_95_percent_of_the_time_where_1_96_sigma_does_not(share):
    draws = 8
    welch = _coverage(share, draws, lambda s, p: coverage_factor(effective_dof(s, p, draws)))
    normal = _coverage(share, draws, lambda s, p: 1.959964)
    assert welch == pytest.approx(0.95, abs=0.004)          # Welch-Satterthwaite: an approximation
    if share >= 0.5:                                         # the draws make much of σ: 1.96σ falls short
        assert normal < 0.945
