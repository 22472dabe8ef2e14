"""Where the main job's base-parameter errors come from (issue 30, item 3): one trajectory's
plant motion simulated in-process, then many runs of the sensor side only, per error source.

A study of the simulated rig (``ident-hw study``) draws a new current noise per run, but the
plant's motion is a pure function of the trajectory: every run has the same encoder rounding and
the same set-point rounding, so whatever error these cause is the same in every run and shows as
a bias. Here the motion is simulated once per set-point source (the plant of ``config``'s rig under
the emulated drives' cyclic demand, ``tests/ident_scenarios.follow_targets``) and sampled exactly
at every SYNC; each run then adds what the rig adds (current noise of ``sim.current_noise``,
rounded to whole mA) and, per source:

- ``exact``: set-points and positions exact (only the identification's own filtering);
- ``setpoints``: set-points in whole encoder counts as the master sends them, positions exact;
- ``rig``: set-points and positions in whole counts, the encoder's count edges where the rig has
  them (the same in every run: what a study of the rig sees);
- ``phase``: as ``rig``, with each run's encoder edges shifted by a random fraction of a count
  per axis (what differs between two rigs, or two homings of one).

Per base parameter of the trajectory's base step (``wls``, every parameter free): mean error and
empirical standard deviation in units of the mean reported sigma (with the encoder draws of
``identification.encoder_draws``, ``--encoder-draws 0``: the least-squares sigma alone), coverage
of the +-1.96 sigma interval. ``--instruments``: also the instrumental-variable estimate of the same base parameters
with the regressor of the sent set-points (delayed by ``--delay`` s) as instruments, a candidate
against the encoder's errors in the regressor (not the production estimator).

``--draws-motion``: the motion the encoder draws read again (:mod:`ident_hw.experiment.encoder`):
``recorded`` (production: the recording smoothed at the filter's cutoff), ``exact`` (the plant's
own motion at the SYNC instants), ``lowpassed-exact`` (that motion smoothed as production smooths
the recording), ``setpoint-response`` (the smoothed recording plus the loops' response to the
set-points above the cutoff, estimated from the recording: :func:`setpoint_response`). A
diagnostic: at 100 Hz the draws of ``exact`` give the encoders' part of sigma that the runs show,
those of the others do not (benchmarks/README.md).

    python benchmarks/bench_bias_sources.py [--runs 20] [--sources exact,setpoints,rig,phase]
        [--config configs/sim-3prrr.yaml] [--trajectory excitation] [--cutoff HZ] [--order N]
        [--encoder-draws N] [--instruments] [--delay 0.02] [--draws-motion recorded|exact|lowpassed-exact|setpoint-response]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ident_hw.config.robots import model_of

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from drivers.recording import Recording  # noqa: E402
from drivers.recording_metadata import RecordingMetadata  # noqa: E402
from drivers.sim.plant import DEFAULT_MAX_SUBSTEP, Plant  # noqa: E402
from ident_hw.config import load_config  # noqa: E402
from ident_hw.experiment.inputs import identification_plan  # noqa: E402
from ident_hw.experiment.offline import identify  # noqa: E402
from ident_hw.experiment.preparation import prepare, trajectory_filter  # noqa: E402
from ident_hw.experiment.plan import plan  # noqa: E402
from ident_hw.identification.base_params import column_scale, identify_base  # noqa: E402
from ident_scenarios import follow_targets  # noqa: E402
from ident_hw.config.robots import true_parameters
from ident_hw.config.to_drivers import axes_scaling

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "sim-3prrr.yaml"
SOURCES = ("exact", "setpoints", "rig", "phase")


def base_only_config(config_path: Path, trajectory: str, cutoff: float | None, order: int | None, tmp: Path,
                     encoder_draws: int | None = None):
    """``config_path`` with one ``wls`` step of every parameter on ``trajectory``, the filter's
    ``cutoff``/``order`` and ``identification.encoder_draws`` when given."""
    filt = ", ".join(f"{k}: {v}" for k, v in (("cutoff", cutoff), ("order", order)) if v)
    path = tmp / "base-only.yaml"
    path.write_text(f"extends: {config_path.resolve()}\n"
                    f"bus: {{interface: virtual, channel: unused}}\n"
                    f"identification:\n  steps:\n"
                    f"    - {{name: base, trajectories: [{trajectory}], parameters: [all], method: wls}}\n"
                    f"  validation: []\n" + (f"  filter: {{{filt}}}\n" if filt else "")
                    + (f"  encoder_draws: {encoder_draws}\n" if encoder_draws is not None else ""))
    return load_config(path)


def plant_motion(config, targets: np.ndarray, theta0: np.ndarray) -> dict:
    """The truth log of the config's plant following ``targets`` (N, a) at the SYNC rate."""
    sim = config.sim
    plant = Plant(model_of(config.robot), true_parameters(config), theta0, bandwidth_hz=sim.bandwidth,
                  damping=sim.damping, max_substep=sim.max_substep or DEFAULT_MAX_SUBSTEP)
    follow_targets(plant, targets[:-1], 1.0 / config.bus.sync_rate)
    return plant.truth()


def instrumental(config, robot, name: str, rec: Recording, reference: np.ndarray) -> tuple:
    """IV estimate of the base parameters the base step fits (its kept columns and output
    weights, :func:`identify_base`): the instruments are the regressor of ``reference`` (N, a)
    prepared like the positions. Returns the estimate and its heteroscedasticity-robust sigma
    (rows taken as independent)."""
    plan = identification_plan(config)
    measured = prepare(plan, robot, name, rec)
    instruments = prepare(plan, robot, name, dataclasses.replace(rec, position=reference))
    names = robot.parameter_names
    base, fit = identify_base(measured.Y, measured.tau_fit, names, scale=column_scale(measured.Y), weighted=True,
                              basis=robot.readable_base())
    cols = [names.index(k) for k in base.kept]
    w = 1.0 / fit.output_std
    W, Z, tau = (measured.Y[:, :, cols] * w[None, :, None], instruments.Y[:, :, cols] * w[None, :, None],
                 measured.tau_fit * w)
    ok = np.isfinite(tau)
    W, Z, tau, axis = W[ok], Z[ok], tau[ok], np.nonzero(ok)[1]
    s = 1.0 / np.sqrt((W ** 2).mean(axis=0))
    A_inv = np.linalg.inv((Z * s).T @ (W * s))
    coef = s * (A_inv @ ((Z * s).T @ tau))
    residual = tau - W @ coef
    var = np.array([residual[axis == j].var() for j in range(len(w))])[axis]
    cov = A_inv @ ((Z * s * var[:, None]).T @ (Z * s)) @ A_inv.T
    return coef, s * np.sqrt(np.diag(cov))


def summary(label: str, expressions, errors: np.ndarray, sigmas: np.ndarray, truth: np.ndarray) -> None:
    """Per parameter: mean error / mean sigma, std / mean sigma, mean sigma %, coverage."""
    z = errors / sigmas
    print(f"{label}: {len(errors)} runs; overall coverage {np.mean(np.abs(z) <= 1.96):.2f}")
    print(f"  {'base parameter':<24} {'bias/σ':>7} {'std/σ':>6} {'σ %':>7} {'cover':>6}")
    for i, e in enumerate(expressions):
        ms = sigmas[:, i].mean()
        print(f"  {e:<24} {errors[:, i].mean() / ms:7.2f} {errors[:, i].std(ddof=1) / ms:6.2f} "
              f"{100 * ms / abs(truth[i]):7.3f} {np.mean(np.abs(z[:, i]) <= 1.96):6.2f}")


def sensed(config, source: str, truth_log: dict, targets: np.ndarray, run: int) -> Recording:
    """What run ``run`` records of the plant's ``truth_log`` under ``source`` (module docstring):
    currents with the config's noise in whole mA, positions exact or in whole counts."""
    scaling = axes_scaling(config.robot.actuators)
    counts, force_per_amp = scaling.counts_per_unit, scaling.force_per_amp
    t, n, axes = truth_log["t"], len(truth_log["t"]), counts.size
    rng = np.random.default_rng(run)
    phase = rng.uniform(-0.5, 0.5, axes) if source == "phase" else 0.0
    position = truth_log["Theta"] if source in ("exact", "setpoints") else \
        np.round(truth_log["Theta"] * counts + phase) / counts
    milliamps = np.round(1000.0 * truth_log["force"] / force_per_amp
                         + rng.normal(0.0, 1000.0 * config.sim.current_noise, (n, axes)))
    return Recording(t=t, cycle=np.arange(n), position=position, velocity=truth_log["Thetad"],
                     current=milliamps / 1000.0, statusword=np.zeros((n, axes), np.int32), target=targets[:n],
                     valid=np.ones((n, axes), bool), metadata=RecordingMetadata(sync_period=1.0 / config.bus.sync_rate))


#: samples of set-point history the loops' response of :func:`setpoint_response` spans (0.16 s at 100 Hz)
RESPONSE_LAGS = 16


def setpoint_response(rec: Recording, smooth, exact: np.ndarray | None = None) -> np.ndarray:
    """(N, a) the recorded motion above the cutoff as the position loops' response to the
    set-points' (the whole-count steps the drives follow): per axis, the recording's part above
    the cutoff (``rec.position - smooth(rec.position)``) fitted by least squares on the last
    :data:`RESPONSE_LAGS` samples of the set-points' part (``rec.target - smooth(rec.target)``);
    ``smooth`` (positions (N, a) -> (N, a)) the identification's smoothing. With the plant's
    ``exact`` positions (N, a), prints per axis how that estimate compares with the truth's part
    (the ratio of their RMS, their correlation)."""
    part = rec.position - smooth(rec.position)
    steps = rec.target - smooth(rec.target)
    response = np.zeros_like(part)
    for j in range(part.shape[1]):
        lagged = np.column_stack([np.roll(steps[:, j], d) for d in range(RESPONSE_LAGS)])[RESPONSE_LAGS:]
        gains, *_ = np.linalg.lstsq(lagged, part[RESPONSE_LAGS:, j], rcond=None)
        response[RESPONSE_LAGS:, j] = lagged @ gains
        if exact is not None:
            truth = (exact - smooth(exact))[RESPONSE_LAGS:, j]
            print(f"  axis {j}: estimated/true RMS above the cutoff {response[:, j].std() / truth.std():.2f}, "
                  f"correlation {np.corrcoef(response[RESPONSE_LAGS:, j], truth)[0, 1]:.2f}")
    return response


def draws_read(config, args, truth_log: dict, targets: np.ndarray) -> None:
    """Make the encoder draws read ``args.draws_motion`` (module docstring) instead of the smoothed
    recording: replaces :func:`ident_hw.experiment.encoder.smoothed_positions` where the draws
    read it (:mod:`ident_hw.experiment.uncertainty`) for this process."""
    from ident_hw.experiment import encoder, uncertainty

    exact = sensed(config, "exact", truth_log, targets, 0)
    motion = exact.position
    if args.draws_motion == "lowpassed-exact":
        settings = trajectory_filter(identification_plan(config), args.trajectory, config.bus.sync_rate)
        motion = encoder.smoothed_positions(exact, settings.sample_rate, settings.cutoff_hz, settings.order)
    if args.draws_motion == "setpoint-response":
        original, shown = encoder.smoothed_positions, []

        def smoothed_with_response(rec, *settings):
            def smooth(position):
                return original(dataclasses.replace(rec, position=position), *settings)
            shown.append(True)
            return smooth(rec.position) + setpoint_response(rec, smooth, None if len(shown) > 1 else exact.position)
        uncertainty.smoothed_positions = smoothed_with_response
        return
    uncertainty.smoothed_positions = lambda rec, *_: motion.copy()


def run_source(config, args, source: str, traj, motion: tuple) -> None:
    """``args.runs`` runs of ``source`` on the plant's ``motion`` (targets, truth log), and their summary."""
    targets, truth_log = motion
    t = truth_log["t"]
    reference = np.column_stack([np.interp(t - args.delay, traj.t[:len(targets)], targets[:, j])
                                 for j in range(targets.shape[1])])
    robot = model_of(config.robot)
    rows = {"wls": ([], []), "iv": ([], [])}
    started = time.perf_counter()
    if args.draws_motion != "recorded":
        draws_read(config, args, truth_log, targets)
    for run in range(args.runs):
        rec = sensed(config, source, truth_log, targets, run)
        fit = identify(config, {args.trajectory: rec}).base_fit
        rows["wls"][0].append(fit.coef - fit.truth)
        rows["wls"][1].append(fit.sigma)
        if args.instruments:
            coef, sigma = instrumental(config, robot, args.trajectory, rec, reference)
            rows["iv"][0].append(coef - fit.truth)
            rows["iv"][1].append(sigma)
    print(f"{source}: {time.perf_counter() - started:.0f} s")
    for estimator, (errors, sigmas) in rows.items():
        if errors:
            summary(f"{source}, {estimator}", fit.expressions, np.array(errors), np.array(sigmas), fit.truth)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", type=Path, default=CONFIG)
    ap.add_argument("--trajectory", default="excitation")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--sources", default=",".join(SOURCES))
    ap.add_argument("--cutoff", type=float)
    ap.add_argument("--order", type=int)
    ap.add_argument("--encoder-draws", type=int, help="identification.encoder_draws (default: the config's)")
    ap.add_argument("--instruments", action="store_true")
    ap.add_argument("--delay", type=float, default=0.02, help="s, instruments' set-point delay")
    ap.add_argument("--draws-motion", choices=("recorded", "exact", "lowpassed-exact", "setpoint-response"), default="recorded",
                    help="the motion the encoder draws read again (a diagnostic)")
    args = ap.parse_args()
    sources = args.sources.split(",")
    if unknown := set(sources) - set(SOURCES):
        ap.error(f"unknown source(s) {sorted(unknown)}; known: {', '.join(SOURCES)}")
    with tempfile.TemporaryDirectory() as tmp:
        config = base_only_config(args.config, args.trajectory, args.cutoff, args.order, Path(tmp), args.encoder_draws)
    (planned,) = plan(config, [args.trajectory])
    traj = planned.trajectory
    counts = axes_scaling(config.robot.actuators).counts_per_unit
    print(f"{args.config.name}, {args.trajectory}: {len(traj.t)} cycles at {config.bus.sync_rate:g} Hz, "
          f"current noise {1000 * config.sim.current_noise:g} mA, filter {config.identification.filter}, "
          f"encoder draws {config.identification.encoder_draws}")
    motions = {}
    for source in sources:
        exact = source == "exact"
        if exact not in motions:
            started = time.perf_counter()
            targets = traj.Theta if exact else np.round(traj.Theta * counts) / counts
            motions[exact] = (targets, plant_motion(config, targets, traj.Theta[0]))
            print(f"plant ({'exact' if exact else 'whole-count'} set-points): {time.perf_counter() - started:.1f} s")
        run_source(config, args, source, traj, motions[exact])


if __name__ == "__main__":
    main()
