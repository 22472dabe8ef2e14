"""Optimised Fourier excitation on the nominal rig: time of the optimisation and the criterion.

    python benchmarks/bench_traj_fourier.py [--write]

Prints the optimisation time, cond(W) of the stacked base regressor (column-scaled, see
``trajectories.fourier``) for the random feasible start, the optimum, the five squares stacked and
the paper set stacked, and the time to generate and check the paper set. ``--write`` stores the
optimised coefficients in ``trajectories/data/fourier-nominal.json`` (the cached excitation).
"""

import argparse
import time
from pathlib import Path

import numpy as np

from ident_hw.config import load_config
from ident_hw.config.robots import model_of
from trajectories import carriage_sweep, check_trajectory, five_squares, validation_triangle
from trajectories.fourier import optimise_excitation, stacked_regressor
from ident_hw.experiment.robot_trajectories import feasibility_limits

ROOT = Path(__file__).resolve().parents[1]


def stacked(robot, trajectories):
    return np.vstack([stacked_regressor(robot, np.c_[t.X, t.zeta], np.c_[t.Xd, t.zetad], np.c_[t.Xdd, t.zetadd])
                      for t in trajectories])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write trajectories/data/fourier-nominal.json")
    args = parser.parse_args()
    cfg = load_config(ROOT / "configs" / "robot-3prrr.yaml").robot
    robot, limits = model_of(cfg), feasibility_limits(cfg)

    start = time.perf_counter()
    sweep, squares, triangle = (carriage_sweep(robot, limits), five_squares(robot, limits),
                                validation_triangle(robot, limits))
    generate = time.perf_counter() - start
    start = time.perf_counter()
    ok = all(check_trajectory(t, robot, limits).ok for t in [sweep, *squares, triangle])
    check = time.perf_counter() - start
    samples = sum(len(t.t) for t in [sweep, *squares, triangle])
    print(f"paper set: generated in {generate:.2f} s (triangle carriage schedule included), "
          f"checked {samples} samples in {check * 1e3:.1f} ms, feasible: {ok}")

    start = time.perf_counter()
    result = optimise_excitation(robot, limits)
    elapsed = time.perf_counter() - start
    traj = result.excitation.trajectory(robot, rate=250.0)
    base = result.base
    names = [robot.parameter_names[i] for i in base.columns]
    dropped = sorted(set(robot.parameter_names) - set(names))
    W = stacked(robot, [traj])[:, base.columns]
    print(f"base columns: {len(names)} of {robot.n_params} (structurally dependent: {', '.join(dropped)})")
    print(f"fourier optimisation: {elapsed:.1f} s, {result.iterations} iterations")
    print(f"cond(W) random feasible start : {result.cond_initial:.2f}")
    print(f"cond(W) optimised (100 samples): {result.cond_final:.2f}")
    print(f"cond(W) optimised at 250 Hz    : {base.cond(stacked(robot, [traj])):.2f}, "
          f"rank {np.linalg.matrix_rank(W)} of {len(names)}, duration {traj.duration:.1f} s, "
          f"feasible: {check_trajectory(traj, robot, limits).ok}")
    Ws = stacked(robot, squares)
    print(f"cond(W) five squares stacked   : {base.cond(Ws)}, rank {np.linalg.matrix_rank(Ws[:, base.columns])}")
    print(f"cond(W) paper set stacked      : {base.cond(stacked(robot, [sweep, *squares, triangle])):.2f}")
    if args.write:
        path = ROOT / "trajectories" / "data" / "fourier-nominal.json"
        result.excitation.save(path, config="configs/robot-3prrr.yaml", cond_initial=result.cond_initial,
                               cond_final=result.cond_final, base_columns=names)
        print(f"wrote {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
