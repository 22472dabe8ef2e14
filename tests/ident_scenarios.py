"""Synthetic identification data with known truth, shared by the test_ident_* modules and the
identification benchmarks.

Motion: sums of sines on the pose ``X`` and the carriages ``zeta`` inside the workspace
(|x|, |y| <= 0.06 m, |alpha| <= 0.3 rad, |zeta| <= 0.05 m), evaluated analytically, mapped to
the actuators by the model. Measurements: currents from the model forces through the drive
scaling of the nominal rig, optionally with noise and quantisation (1 mA, encoder counts).
``tests/test_ident_data.py`` checks the generator itself.
"""

from __future__ import annotations

import math
import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drivers.recording import Recording
from drivers.recording_metadata import RecordingMetadata
from drivers.sim import Plant
import nominal
from drivers.sim.modes import Demand, cyclic_segment
from drivers.sim.plant import DEFAULT_MAX_SUBSTEP
from ident_hw.config.robots import model_of
from ident_hw.model import InertialParams, ThreePRRR
from ident_hw.config.robots import true_parameters
from ident_hw.config.to_drivers import axis_scaling

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
#: a campaign of the paper's carriage sweep alone, identifying m_c and the carriage friction
#: (YAML lines to append to a config that extends the main job's)
SWEEP_CAMPAIGN = (
    "trajectories: [{name: sweep, kind: carriage_sweep, size: 0.06}]\n"
    "identification:\n"
    "  steps: [{name: carriages, trajectories: [sweep],\n"
    "           parameters: [m_c, fv_zeta1, fv_zeta2, fv_zeta3, fc_zeta1, fc_zeta2, fc_zeta3]}]\n"
    "  validation: []\n")


def without_draws(config):
    """``config`` identifying without the encoder draws: they widen sigma and change no estimate
    (``ident_hw.experiment.encoder``); for tests that check what is decoded, kept out, or named by
    the verdict, not sigma's width."""
    return dataclasses.replace(config, identification=dataclasses.replace(config.identification, encoder_draws=0))


GEOMETRY = nominal.GEOMETRY
ROBOT = ThreePRRR(GEOMETRY, coulomb_width=1e-3)
NAMES = ROBOT.parameter_names

# Nominal drives: EC 45 flat + 26:1 gearhead on the links, EC 40 on a 2 mm screw for the carriages.
AXES = [nominal.REVOLUTE] * 3 + [nominal.PRISMATIC] * 3
FORCE_PER_AMP = np.array([ax.force_per_amp for ax in AXES])
COUNTS_PER_UNIT = np.array([ax.counts_per_unit for ax in AXES])

# Truth: the paper's identified masses (m_l1 = 0.30 instead of its degenerate 0), slender-rod
# and disc inertias, friction of our choosing.
TRUE = InertialParams(
    m_c=603.62, m_l1=0.30, I_l1=0.30 * 0.30**2 / 12, m_l2=0.5723, I_l2=0.5723 * 0.30**2 / 12,
    m_ee=0.2269, I_ee=0.2269 * 0.12**2 / 2,
    f_v=(0.02, 0.02, 0.02, 250.0, 250.0, 250.0), f_c=(0.03, 0.03, 0.03, 40.0, 40.0, 40.0),
)
CAD = InertialParams(
    m_c=780.0, m_l1=0.30, I_l1=0.00225, m_l2=0.354, I_l2=0.002655, m_ee=0.78, I_ee=0.005616,
    f_v=(0.01,) * 3 + (100.0,) * 3, f_c=(0.01,) * 3 + (10.0,) * 3,
)

# (amplitude, frequency Hz, phase) of each sine, per coordinate [x, y, alpha, zeta1, zeta2, zeta3].
RICH = [
    [(0.03, 0.40, 0.0), (0.02, 1.10, 1.0)],
    [(0.03, 0.55, 0.5), (0.02, 0.90, 2.0)],
    [(0.15, 0.35, 0.3), (0.10, 1.30, 1.5)],
    [(0.03, 0.45, 0.2), (0.015, 1.00, 0.7)],
    [(0.03, 0.60, 1.2), (0.015, 0.80, 2.5)],
    [(0.03, 0.50, 2.2), (0.015, 1.20, 0.4)],
]


def sines(spec, t):
    """Sum of sines (N, len(spec)) and its two derivatives; ``spec[j]`` lists (amp, Hz, phase)."""
    q = np.zeros((t.size, len(spec)))
    qd, qdd = q.copy(), q.copy()
    for j, terms in enumerate(spec):
        for amp, f, ph in terms:
            w = 2 * math.pi * f
            q[:, j] += amp * np.sin(w * t + ph)
            qd[:, j] += amp * w * np.cos(w * t + ph)
            qdd[:, j] -= amp * w * w * np.sin(w * t + ph)
    return q, qd, qdd


@dataclass
class Motion:
    """Analytic motion: pose and carriages, their actuator image, regressor and true forces."""

    t: np.ndarray
    X: np.ndarray
    Xd: np.ndarray
    zeta: np.ndarray
    zetad: np.ndarray
    Theta: np.ndarray
    Thetad: np.ndarray
    Thetadd: np.ndarray
    Y: np.ndarray
    tau: np.ndarray


def make_motion(spec=RICH, rate=1000.0, duration=10.0, t0=0.0) -> Motion:
    t = t0 + np.arange(int(round(duration * rate))) / rate
    q, qd, qdd = sines(spec, t)
    args = (q[:, :3], qd[:, :3], qdd[:, :3], q[:, 3:], qd[:, 3:], qdd[:, 3:])
    actuated = ROBOT.actuated_motion(*args)
    Y = ROBOT.regressor(*args)
    return Motion(t, q[:, :3], qd[:, :3], q[:, 3:], qd[:, 3:], actuated.q, actuated.qd, actuated.qdd, Y,
                  Y @ TRUE.as_vector())


def measure(motion: Motion, rng: np.random.Generator, noise: float = 0.03):
    """Quantised encoder positions (N, 6) and noisy currents (N, 6) in A (1 mA steps).

    Positions: whole encoder counts, the count grid at a random sub-count offset per axis
    (where the encoder's zero falls after homing). Currents: Gaussian noise of ``noise`` ×
    each axis' RMS current, then rounding to 1 mA.
    """
    offset = rng.uniform(size=COUNTS_PER_UNIT.shape)
    counts = np.round(motion.Theta * COUNTS_PER_UNIT + offset)
    current = motion.tau / FORCE_PER_AMP
    current = current + rng.normal(size=current.shape) * noise * np.sqrt(np.mean(current**2, axis=0))
    return counts / COUNTS_PER_UNIT, np.round(current * 1e3) * 1e-3


PAYLOAD_KG = 0.5  # compact, at the platform centre: adds to m_ee only


@dataclass
class OnlineScenario:
    """A stream for the online estimators, with the truth known at every sample.

    Phases (``phase`` (N,) = 0, 1, 2): rich motion; a slow small circle of the platform with
    the carriages still (1 cm diameter at 0.1 Hz: accelerations ~2 mm/s², carriage terms
    unexcited), where only the link friction keeps being excited; rich motion again with a
    payload on the end-effector. ``Y`` (N, 6, 18) and ``truth`` (N, 18) are in the base set
    with ``m_l2`` held at its known value (breaks the structural null direction, so ``m_ee``
    is identifiable alone); ``tau`` has Gaussian noise of 3 % RMS per output, ``tau_ref`` none.
    ``offline``: an earlier, separate rich block (Y, tau) for the warm start.
    """

    t: np.ndarray
    phase: np.ndarray
    Y: np.ndarray
    tau: np.ndarray
    tau_ref: np.ndarray
    truth: np.ndarray
    names: list
    offline: tuple


def online_scenario(rate: float = 200.0, durations=(20.0, 20.0, 20.0), seed: int = 0) -> OnlineScenario:
    held = NAMES.index("m_l2")
    free = [i for i in range(len(NAMES)) if i != held]
    circle = [[(0.005, 0.1, 0.0)], [(0.005, 0.1, math.pi / 2)], [], [], [], []]
    loaded = TRUE.replace(m_ee=TRUE.m_ee + PAYLOAD_KG)
    offline = make_motion(RICH, rate=rate, duration=10.0)
    t0, parts = 10.0, []
    for spec, dur, params in zip((RICH, circle, RICH), durations, (TRUE, TRUE, loaded)):
        m = make_motion(spec, rate=rate, duration=dur, t0=t0)
        parts.append((m, params.as_vector()))
        t0 += dur
    rng = np.random.default_rng(seed)
    noise = 0.03 * np.sqrt(np.mean(offline.tau**2, axis=0))

    def reduced(Y, pi):  # forces with the held parameter's contribution removed
        return Y[:, :, free], Y @ pi - Y[:, :, held] * TRUE.m_l2

    Y, tau_ref = zip(*(reduced(m.Y, pi) for m, pi in parts))
    tau_ref = np.concatenate(tau_ref)
    Y_off, tau_off = reduced(offline.Y, TRUE.as_vector())
    return OnlineScenario(
        t=np.concatenate([m.t for m, _ in parts]),
        phase=np.concatenate([np.full(len(m.t), i) for i, (m, _) in enumerate(parts)]),
        Y=np.concatenate(Y), tau=tau_ref + rng.normal(size=tau_ref.shape) * noise, tau_ref=tau_ref,
        truth=np.concatenate([np.tile(pi[free], (len(m.t), 1)) for m, pi in parts]),
        names=[NAMES[i] for i in free],
        offline=(Y_off, tau_off + rng.normal(size=tau_off.shape) * noise),
    )


#: The paper's identification steps on its campaign, with m_l2 held at its known value (it breaks
#: the structural null direction): the squares (carriages blocked, orientation held, so m_c,
#: I_ee and the carriage friction are unexcited) give the link and end-effector mass terms,
#: then the carriage sweep gives m_c, I_ee and the carriage friction with those held.
HELD_KNOWN = "m_l2"
PAPER_STEPS = (
    ("squares", tuple(f"square-{i}" for i in range(1, 6)),
     ("m_l1", "I_l1", "I_l2", "m_ee") + tuple(n for n in NAMES if n.startswith(("fv_theta", "fc_theta")))),
    ("sweep", ("carriage-sweep",), ("m_c", "I_ee") + tuple(n for n in NAMES if n.startswith(("fv_zeta", "fc_zeta")))),
)


def paper_campaign(rate: float, dwell: float = 0.0) -> dict:
    """The paper's trajectories (``trajectories`` package, nominal limits) by name."""
    from trajectories import Limits, carriage_sweep, five_squares, validation_triangle

    limits = Limits()
    trajs = [carriage_sweep(ROBOT, limits, rate=rate, dwell=dwell), *five_squares(ROBOT, limits, rate=rate, dwell=dwell),
             validation_triangle(ROBOT, limits, rate=rate, dwell=dwell)]
    return {tr.name: tr for tr in trajs}


def exact_regressor(tr) -> np.ndarray:
    """Regressor (N, 6, 19) of a trajectory from its exact pose and carriage motion."""
    return ROBOT.regressor(tr.X, tr.Xd, tr.Xdd, tr.zeta, tr.zetad, tr.zetadd)


def identify_paper_steps(data: dict, initial: np.ndarray) -> list:
    """Run :data:`PAPER_STEPS` on ``data`` (name → (Y, tau)) from ``initial`` (19,), which
    must hold the known value of :data:`HELD_KNOWN`. Returns the steps' ``MassFitResult``."""
    from ident_hw.identification import sqp_fit

    fits, coef = [], np.asarray(initial, dtype=float)
    for _, names, free in PAPER_STEPS:
        Y = np.concatenate([data[n][0] for n in names])
        tau = np.concatenate([data[n][1] for n in names])
        fits.append(sqp_fit(Y, tau, NAMES, coef, free=free))
        coef = fits[-1].coef
    return fits


def follow_targets(plant, targets: np.ndarray, period: float, force_limit: float = 1e6) -> None:
    """Step ``plant`` one ``period`` (s) per row of ``targets`` (N, n), every loop closed, under
    the emulated drives' cyclic demand: the cubic B-spline of the targets
    (:func:`drivers.sim.modes.cyclic_segment`), starting from the held first target."""
    axes = targets.shape[1]
    enabled, limit = np.ones(axes, bool), np.full(axes, force_limit)
    demands = [Demand(position=float(q)) for q in targets[0]]
    history = [None] * axes
    for target in targets:
        for j, demand in enumerate(demands):
            history[j] = cyclic_segment(demand, float(target[j]), period, history[j])
        plant.step(period, np.array([d.coefficients() for d in demands]).T, enabled, limit)
        for demand in demands:
            demand.advance(period)


def exact_recording(config, traj, max_substep: float | None) -> Recording:
    """The plant of ``config``'s rig (integration step ``max_substep``, s, ``None``: the plant's
    default) following ``traj`` at the SYNC rate under the emulated drives' cyclic demand (the
    cubic B-spline of the targets, :func:`drivers.sim.modes.cyclic_segment`), sampled exactly at
    every period start: positions, velocities, forces as currents. No drive units, no noise."""
    period = 1.0 / config.bus.sync_rate
    sim = config.sim
    plant = Plant(model_of(config.robot), true_parameters(config), traj.Theta[0], bandwidth_hz=sim.bandwidth,
                  damping=sim.damping, max_substep=max_substep or DEFAULT_MAX_SUBSTEP)
    axes = traj.Theta.shape[1]
    follow_targets(plant, traj.Theta[:-1], period)
    truth = plant.truth()
    n = len(truth["t"])
    force_per_amp = np.array([axis_scaling(a).force_per_amp for a in config.robot.actuators])
    return Recording(t=truth["t"], cycle=np.arange(n), position=truth["Theta"], velocity=truth["Thetad"],
                     current=truth["force"] / force_per_amp, statusword=np.zeros((n, axes), np.int32),
                     target=traj.Theta[:n], valid=np.ones((n, axes), bool), metadata=RecordingMetadata(sync_period=period))
