"""One gap-free measured 3PRRR run (positions and currents) to an identification data set
(filtered, decimated regressor and forces), for the tests and benchmarks that start from arrays.

It is :mod:`ident_hw.filtering`'s chain applied to a whole run at once: the production path,
which cuts recordings at gaps and serves every robot, is
:func:`ident_hw.experiment.preparation.prepare`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ident_hw.filtering import FilterSettings, kept_samples, parallel_decimate, prepare_actuated


@dataclass(frozen=True)
class Dataset:
    """Filtered, decimated identification data.

    Attributes:
        t: sample times (M,), s.
        Y: regressor (M, k, n), parallel-filtered like ``tau``.
        tau: actuator forces (M, k): N·m (links), N (carriages).
        Theta, Thetad: filtered actuated positions and rates (M, k) at the kept samples.
        settings: the filter settings used.
    """

    t: np.ndarray
    Y: np.ndarray
    tau: np.ndarray
    Theta: np.ndarray
    Thetad: np.ndarray
    settings: FilterSettings


def build_dataset(robot, t, Theta, current, force_per_amp, X_guess, settings: FilterSettings | None = None) -> Dataset:
    """Measured ``t`` (N,), ``Theta`` (N, 6), ``current`` (N, 6) A → :class:`Dataset`.

    Positions are low-passed (zero phase) and differentiated, the regressor is built by the
    model (``robot.regressor_from_actuated``; ``X_guess`` (3,) starts its forward kinematics),
    then forces and regressor go through the same parallel filter and decimation.
    """
    samples = prepare_actuated(t, Theta, current, force_per_amp, settings)
    if settings is None:
        settings = FilterSettings.for_sample_rate(1.0 / float(np.median(np.diff(samples.t))))
    Y = robot.regressor_from_actuated(samples.Theta, samples.Thetad, samples.Thetadd, X_guess)
    Y_f, tau_f = parallel_decimate(settings, Y, samples.tau)
    keep = kept_samples(settings, len(samples.t))
    return Dataset(
        t=samples.t[keep], Y=Y_f, tau=tau_f,
        Theta=samples.Theta[keep], Thetad=samples.Thetad[keep], settings=settings,
    )
