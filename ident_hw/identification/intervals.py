"""The 95 % interval of an estimate whose σ is partly estimated from a few draws.

An estimate's variance here adds parts of two kinds: the least-squares one, computed from
thousands of rows (its own uncertainty negligible), and the encoders' one, the sample variance
of a few draws of the recordings read again (:mod:`ident_hw.experiment.encoder`, 8 by default),
which is itself uncertain: a variance from ``D`` draws has ``D - 1`` degrees of freedom, and its
square root is off by some 27 % (one standard deviation) with 8. A ±1.96σ interval drawn with
such a σ holds the truth less often than 95 % even when σ is right on average (93 % where the
draws make three quarters of the variance), as a sample's mean ± 1.96 of its sample standard
deviation does: the interval needs Student's t instead of the normal quantile.

The effective degrees of freedom of the sum follow Welch and Satterthwaite (the GUM, JCGM 100,
G.4): ``nu = sigma^4 / (sigma_draws^4 / (D - 1))``, the least-squares part counted as exact.
The 95 % interval is then ``±k σ`` with ``k = t_{0.975}(nu)``: 1.96 where the draws add nothing,
2.0-2.3 where they make most of σ.
"""

from __future__ import annotations

import numpy as np
from scipy import special

#: the confidence of the reported interval
LEVEL = 0.95


def effective_dof(sigma: np.ndarray | float, draws_sigma: np.ndarray | float, draws: int) -> np.ndarray:
    """Welch-Satterthwaite degrees of freedom (same shape as ``sigma``) of standard deviations
    ``sigma`` whose part ``draws_sigma`` (same unit) is the spread of ``draws`` draws and the rest
    exact: ``sigma^4 / (draws_sigma^4 / (draws - 1))``; ``inf`` where the draws add nothing or
    fewer than two were made."""
    sigma, part = np.broadcast_arrays(np.asarray(sigma, dtype=float), np.asarray(draws_sigma, dtype=float))
    if draws < 2:
        return np.full(sigma.shape, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        nu = sigma ** 4 * (draws - 1) / part ** 4
    return np.where((part > 0) & np.isfinite(nu), np.maximum(nu, draws - 1), np.inf)


def coverage_factor(dof: np.ndarray | float, level: float = LEVEL) -> np.ndarray:
    """``k`` of the two-sided ``level`` interval ``±k σ`` of a σ with ``dof`` degrees of freedom:
    Student's t quantile, the normal one (1.96 at 95 %) where ``dof`` is infinite."""
    dof = np.asarray(dof, dtype=float)
    q = 0.5 + 0.5 * level           # scipy.special, not scipy.stats: that import costs every process ~2 s
    return np.where(np.isfinite(dof), special.stdtrit(np.where(np.isfinite(dof), dof, 1.0), q), special.ndtri(q))
