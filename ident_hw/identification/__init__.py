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
- :func:`axis_gains`: each axis's gain against its own model refitted (a torque constant,
  gear ratio or screw lead off; the quality verdict's check).

In a results folder, the figures of a least-squares or mass fit are those of a step's record
(:class:`ident_hw.records.BaseStep`, :class:`ident_hw.records.MassFitStep`), and
:class:`BaseParameters` is :class:`ident_hw.records.BaseAnalysis`. Imports :mod:`ident_hw.model` and :mod:`ident_hw.filtering`,
nothing of the drivers, trajectories, config or runner.
"""

import lazy_loader

# Each name is imported from its module on first use (PEP 562, by lazy_loader):
# ``ident_hw.identification.least_squares`` and the config that reads its constants do not pay
# for SciPy's optimiser and signal modules.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "axis_gain": ["AxisGains", "axis_gains"],
    "base_params": ["BaseParameters", "base_parameters", "identify_base"],
    "least_squares": ["LeastSquaresResult", "ols", "stack", "wls"],
    "mass_fit": ["MassFitResult", "sqp_fit"],
    "metrics": ["ValidationMetrics", "validation_metrics"],
    "online": ["RLS", "SVDDLS", "DampedRLS", "StreamTrace", "offline_information", "run_stream"],
    "power": ["energy_rows", "power_rows"],
})
