"""The identification pipeline's own error (issue 30): the base step on one trajectory simulated
once, with the plant's exact positions at the SYNC instants and its force as the current, no
noise and no encoder: whatever error is left is the pipeline's (filtering, differentiation, the
motion between samples), the part of a study's mean error that no number of runs averages away.

``--derivatives`` swaps what the identification's :func:`ident_hw.filtering.prepare_actuated`
gives the regressor, to tell the stages apart:

- ``production``: the positions low-passed, then differentiated (fourth-order central differences);
- ``exact``: the plant's own positions, rates and accelerations at the sample instants;
- ``exact-acceleration``: production's positions and rates, the plant's accelerations;
- ``unfiltered``: central differences of the exact positions, no low-pass.

``--margin`` sets the positions' low-pass above the parallel filter's cut-off
(:attr:`ident_hw.filtering.FilterSettings.position_margin`). Prints each base parameter's error
in percent of its truth.

    python benchmarks/bench_pipeline_error.py [--config configs/sim-3prrr.yaml] [--trajectory excitation]
        [--derivatives production,exact,exact-acceleration,unfiltered] [--margin 1.5]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from bench_bias_sources import CONFIG, base_only_config, plant_motion, sensed  # noqa: E402
from ident_hw import filtering  # noqa: E402
from ident_hw.config.to_drivers import axes_scaling  # noqa: E402
from ident_hw.experiment import offline, preparation  # noqa: E402
from ident_hw.experiment.inputs import identification_plan  # noqa: E402
from ident_hw.experiment.plan import plan  # noqa: E402

DERIVATIVES = ("production", "exact", "exact-acceleration", "unfiltered")


def swapped(derivatives: str, truth_log: dict):
    """A ``prepare_actuated`` whose outputs are production's with ``derivatives`` (module
    docstring) taken from the plant's ``truth_log`` at the same sample instants."""
    production = filtering.prepare_actuated

    def prepare_actuated(t, Theta, current, force_per_amp, settings=None, ends=filtering.WHOLE):
        samples = production(t, Theta, current, force_per_amp, settings, ends)
        rows = np.searchsorted(truth_log["t"], t - 1e-9)
        if derivatives == "exact":
            return dataclasses.replace(samples, Theta=truth_log["Theta"][rows], Thetad=truth_log["Thetad"][rows],
                                       Thetadd=truth_log["Thetadd"][rows])
        if derivatives == "exact-acceleration":
            return dataclasses.replace(samples, Thetadd=truth_log["Thetadd"][rows])
        if derivatives == "unfiltered":
            rate, acceleration = filtering.central_derivatives(truth_log["Theta"][rows], t)
            return dataclasses.replace(samples, Theta=truth_log["Theta"][rows], Thetad=rate, Thetadd=acceleration)
        return samples
    return prepare_actuated


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", type=Path, default=CONFIG)
    ap.add_argument("--trajectory", default="excitation")
    ap.add_argument("--derivatives", default=",".join(DERIVATIVES))
    ap.add_argument("--margin", type=float, help="positions' low-pass over the parallel filter's cut-off")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        config = base_only_config(args.config, args.trajectory, None, None, Path(tmp), encoder_draws=0)
    config = dataclasses.replace(config, sim=dataclasses.replace(config.sim, current_noise=0.0))
    (planned,) = plan(config, [args.trajectory])
    traj = planned.trajectory
    truth_log = plant_motion(config, traj.Theta, traj.Theta[0])
    rec = sensed(config, "exact", truth_log, traj.Theta, 0)
    rec = dataclasses.replace(rec, current=truth_log["force"] / axes_scaling(config.robot.actuators).force_per_amp)
    if args.margin:
        production_filter = preparation.trajectory_filter
        preparation.trajectory_filter = lambda *a, **k: dataclasses.replace(production_filter(*a, **k),
                                                                        position_margin=args.margin)
    print(f"{args.config.name}, {args.trajectory}: {len(traj.t)} cycles at {config.bus.sync_rate:g} Hz, "
          f"filter {preparation.trajectory_filter(identification_plan(config), args.trajectory, config.bus.sync_rate)}")
    for derivatives in args.derivatives.split(","):
        if derivatives not in DERIVATIVES:
            ap.error(f"unknown --derivatives {derivatives!r}; known: {', '.join(DERIVATIVES)}")
        preparation.prepare_actuated = swapped(derivatives, truth_log)
        fit = offline.identify(config, {args.trajectory: rec}).base_fit
        print(f"{derivatives}:")
        for expression, estimate, truth in zip(fit.expressions, fit.coef, fit.truth):
            print(f"  {expression:<24} {100 * (estimate - truth) / abs(truth):+8.3f} %")


if __name__ == "__main__":
    main()
