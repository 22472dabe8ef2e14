"""Identification of the dynamic parameters from a regressor ``Y`` (N, k, n) and forces ``tau`` (N, k).

Public API::

    from ident_hw.identification import ols, wls, identify_base, sqp_fit
    from ident_hw.identification import SVDDLS, RLS, DampedRLS, validation_metrics

- :func:`ols`, :func:`wls`: least squares with the statistics of the power-model paper (HAC covariance).
- :func:`base_parameters`, :func:`identify_base`: rank, null space and base parameters (the SVD-DLS paper).
- :func:`sqp_fit`: bounded SQP mass fit of the 3PRRR paper, cross-checked by ``lsq_linear``.
- :class:`SVDDLS`, :class:`RLS`, :class:`DampedRLS`: online estimators (``partial_fit``);
  :func:`run_stream` records what one does on a stream.
- :func:`power_rows`, :func:`energy_rows`: power and energy models (no accelerations).
- :func:`validation_metrics`: RMS, NRMS, d_tau and J_RMSE on held-out data.

Every result has ``to_dict()``. Imports :mod:`ident_hw.model` and :mod:`ident_hw.filtering`,
nothing of the drivers, trajectories, config or runner.
"""

import importlib

# Each name is imported from its module on first use (PEP 562): ``ident_hw.identification.least_squares``
# and the config that reads its constants do not pay for SciPy's optimiser and signal modules.
_MODULE_OF = {
    "BaseParameters": "base_params",
    "base_parameters": "base_params",
    "identify_base": "base_params",
    "LeastSquaresResult": "least_squares",
    "ols": "least_squares",
    "stack": "least_squares",
    "wls": "least_squares",
    "MassFitResult": "mass_fit",
    "sqp_fit": "mass_fit",
    "ValidationMetrics": "metrics",
    "validation_metrics": "metrics",
    "RLS": "online",
    "SVDDLS": "online",
    "DampedRLS": "online",
    "StreamTrace": "online",
    "offline_information": "online",
    "run_stream": "online",
    "energy_rows": "power",
    "power_rows": "power",
}

__all__ = [
    "RLS",
    "SVDDLS",
    "BaseParameters",
    "DampedRLS",
    "LeastSquaresResult",
    "MassFitResult",
    "StreamTrace",
    "ValidationMetrics",
    "base_parameters",
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


def __getattr__(name: str):
    try:
        module = _MODULE_OF[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_MODULE_OF})
