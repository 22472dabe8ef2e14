"""The SVD-DLS paper's Delta experiments on model data (no rig): the offline base identification
on the training path and the online comparison of SVD-DLS, RLS and damped RLS, rich and
insufficient excitation, with a payload on rod 3 at half the run.

Choices the paper leaves open (the Delta spec): rate 100 Hz, forgetting 0.998, torque noise
uniform within ±0.25 N·m (the kinematics exact), a warm start from the offline fit of 30 s of the
training path, the payload 0.5 kg at mid-rod 3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ident_hw.identification import DampedRLS, RLS, SVDDLS, wls
from ident_hw.identification.online import StreamTrace, offline_information, run_stream
from ident_hw.model.delta import PARAM_NAMES, Delta, closed_form_base, nominal_parameters
from trajectories.delta_paper import training_path

ROBOT = Delta()
BASE = closed_form_base(ROBOT.geometry)
KEPT = [PARAM_NAMES.index(k) for k in BASE.kept]
RATE = 100.0                     # Hz
NOISE = 0.25                     # N·m, half-width of the uniform torque noise
NOISE_STD = NOISE / np.sqrt(3)
FORGETTING = 0.998
#: drive terms of the simulated robot: viscous, Coulomb, reflected rotor inertia per arm
DRIVE = np.array([0.05] * 3 + [0.3] * 3 + [0.02] * 3)


def truth() -> np.ndarray:
    pi = nominal_parameters(ROBOT.geometry)
    pi[70:] = DRIVE
    return pi


def payload(pi: np.ndarray, mass: float = 0.5) -> np.ndarray:
    """0.5 kg at mid-rod 3 (on its axis, at L2/2 from the platform joint): m, mx, Iyy, Izz change."""
    out = pi.copy()
    x = ROBOT.geometry.L2 / 2
    for name, delta in (("m", mass), ("mx", mass * x), ("Iyy", mass * x**2), ("Izz", mass * x**2)):
        out[PARAM_NAMES.index(f"rod3.{name}")] += delta
    return out


def samples(path, t0: float, seconds: float, pi: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
    """Base regressor (N, 3, 40) and noisy torques (N, 3) along ``path`` from ``t0``."""
    t = t0 + np.arange(int(round(seconds * RATE))) / RATE
    m = path(t)
    q, qd, qdd = m.q, m.qd, m.qdd
    Y = ROBOT.regressor(q, qd, qdd)
    tau = Y @ pi + rng.uniform(-NOISE, NOISE, size=(len(t), 3))
    return Y[:, :, KEPT], tau


@dataclass
class Comparison:
    """The online run: the streams, the true base parameters per sample and each estimator's trace."""

    t: np.ndarray
    Y: np.ndarray
    tau: np.ndarray
    truth: np.ndarray                   # (N, 40) base parameters in force at each sample
    change: float                       # s, payload time
    offline: object                     # LeastSquaresResult of the warm start
    traces: dict[str, StreamTrace]

    def j_rmse(self, rows=slice(None)) -> dict[str, float]:
        """RMS a-priori prediction error (N·m) over ``rows``, per estimator (eq. 87)."""
        return {k: float(np.sqrt(np.mean(np.sum((tr.predictions[rows] - self.tau[rows]) ** 2, axis=1))))
                for k, tr in self.traces.items()}


def online_comparison(path=training_path, seconds: float = 60.0, seed: int = 0) -> Comparison:
    """Warm start on 30 s of the training path, then ``seconds`` of ``path`` with the payload
    added at half of them; SVD-DLS, RLS and damped RLS on the same stream."""
    rng = np.random.default_rng(seed)
    pi = truth()
    Y0, tau0 = samples(training_path, 0.0, 30.0, pi, rng)
    offline = wls(Y0, tau0, BASE.kept)
    half = int(round(seconds * RATE / 2))
    Ya, ta = samples(path, 30.0, seconds / 2, pi, rng)
    Yb, tb = samples(path, 30.0 + seconds / 2, seconds / 2, payload(pi), rng)
    Y, tau = np.concatenate([Ya, Yb]), np.concatenate([ta, tb])
    t = 30.0 + np.arange(len(Y)) / RATE
    base_truth = np.where((np.arange(len(Y)) < half)[:, None], BASE.H @ pi, BASE.H @ payload(pi))
    scale = np.maximum(np.abs(offline.coef), 1e-3)
    std = np.full(3, NOISE_STD)
    information = offline_information(Y0, FORGETTING, std)
    estimators = {"SVD-DLS": SVDDLS(len(KEPT), FORGETTING, threshold=100.0, scale=scale, output_std=std),
                  "RLS": RLS(len(KEPT), FORGETTING, scale=scale, output_std=std),
                  "damped RLS": DampedRLS(len(KEPT), FORGETTING, damping=1e2, scale=scale, output_std=std)}
    traces = {}
    for name, est in estimators.items():
        est.warm_start(offline.coef, information)
        traces[name] = run_stream(est, Y, tau)
    return Comparison(t, Y, tau, base_truth, 30.0 + seconds / 2, offline, traces)


def smallest_pseudo_inertia_eigenvalue(body: np.ndarray) -> float:
    """A Delta body ``[m, mx, my, mz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` realisable by a mass
    density iff ``[[tr(I)/2 - I, h], [h^T, m]]`` is positive semidefinite."""
    m, h, (ixx, ixy, ixz, iyy, iyz, izz) = body[0], body[1:4], body[4:]
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    J = np.block([[np.trace(inertia) / 2 * np.eye(3) - inertia, h[:, None]], [h[None, :], np.array([[m]])]])
    return float(np.linalg.eigvalsh(J)[0])
