"""Identification of the dynamic parameters from a regressor ``Y`` (N, k, n) and forces ``tau`` (N, k).

Public API::

    from ident_hw.identification import build_dataset, ols, wls, identify_base, sqp_fit
    from ident_hw.identification import SVDDLS, RLS, DampedRLS, validation_metrics

- :func:`build_dataset`: measured positions and currents → filtered, decimated regressor and forces.
- :func:`ols`, :func:`wls`: least squares with the statistics of the power-model paper (HAC covariance).
- :func:`base_parameters`, :func:`identify_base`: rank, null space and base parameters (the SVD-DLS paper).
- :func:`sqp_fit`: bounded SQP mass fit of the 3PRRR paper, cross-checked by ``lsq_linear``.
- :class:`SVDDLS`, :class:`RLS`, :class:`DampedRLS`: online estimators (``partial_fit``);
  :func:`run_stream` records what one does on a stream.
- :func:`power_rows`, :func:`energy_rows`: power and energy models (no accelerations).
- :func:`validation_metrics`: RMS, NRMS, d_tau and J_RMSE on held-out data.

Every result has ``to_dict()``. Imports :mod:`ident_hw.model` and :mod:`ident_hw.signal`,
nothing of the drivers, trajectories, config or runner.
"""

from .base_params import BaseParameters, base_parameters, identify_base
from .dataset import Dataset, build_dataset
from .least_squares import LeastSquaresResult, ols, stack, wls
from .mass_fit import MassFitResult, sqp_fit
from .metrics import ValidationMetrics, validation_metrics
from .online import RLS, SVDDLS, DampedRLS, StreamTrace, offline_information, run_stream
from .power import energy_rows, power_rows

__all__ = [
    "RLS",
    "SVDDLS",
    "BaseParameters",
    "Dataset",
    "DampedRLS",
    "LeastSquaresResult",
    "MassFitResult",
    "StreamTrace",
    "ValidationMetrics",
    "base_parameters",
    "build_dataset",
    "energy_rows",
    "identify_base",
    "offline_information",
    "ols",
    "power_rows",
    "run_stream",
    "sqp_fit",
    "stack",
    "validation_metrics",
    "wls",
]
