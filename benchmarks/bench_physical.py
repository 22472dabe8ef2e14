"""Physically consistent parameters (issue 29): the semidefinite program's wall time per robot.

For each config: its base parameters (the model's readable base; for the 3PRRR the SVD of a
regressor on random states) of the simulated truth, with noise of 0.2 % of each (σ known, the
covariance diagonal), then :func:`ident_hw.identification.physical.consistent_parameters` from
the CAD values, in both metrics: the median wall time of 5 solves (cvxpy's canonicalisation and
Clarabel's solve; the first import of cvxpy is not counted), χ² against its 95 % quantile and
the smallest body margin.

Run: python benchmarks/bench_physical.py   (quote ``bench_model.py --speed`` of the same hour)
"""

import time

import numpy as np

from ident_hw.config import load_config
from ident_hw.identification.base_params import base_parameters
from ident_hw.identification.physical import consistent_parameters
from ident_hw.config.robots import initial_parameters, model_of, true_parameters
from ident_hw.config.to_identification import physical_scales

CONFIGS = ("configs/sim-3prrr.yaml", "configs/sim-delta.yaml", "configs/sim-2r.yaml", "configs/sim-stewart.yaml")


def base_of(config, robot):
    """``H`` (r, n) of the model's base parameters."""
    readable = robot.readable_base()
    if readable is not None:
        return readable.H
    rng = np.random.default_rng(0)     # the 3PRRR: the SVD of its regressor near home
    home = robot.home_actuated()
    N = 400
    Theta = home + 0.02 * rng.standard_normal((N, len(home)))
    Y, _ = robot.identification_regressor(Theta, rng.standard_normal(Theta.shape),
                                          rng.standard_normal(Theta.shape), np.zeros((N, robot.pose_size)))
    return base_parameters(Y, robot.parameter_names, scale=np.maximum(np.abs(initial_parameters(config.robot)),
                                                                      1e-3)).H


def main() -> None:
    import cvxpy  # noqa: F401  (imported once, as a run does)

    print(f"{'config':<28} {'metric':<10} {'n':>4} {'r':>4} {'bodies':>6} {'median s':>9} {'chi2':>9} "
          f"{'q95':>6} {'min margin':>11}")
    for path in CONFIGS:
        config = load_config(path)
        robot = model_of(config.robot)
        names = robot.parameter_names
        cad, truth = initial_parameters(config.robot), true_parameters(config)
        H = base_of(config, robot)
        beta = H @ truth
        sigma = 0.002 * np.maximum(np.abs(beta), 1e-3 * np.abs(beta).max())
        noisy = beta + sigma * np.random.default_rng(1).standard_normal(len(beta))
        typical = np.where(cad != 0, cad, truth)
        scale = np.array(physical_scales(config.identification.physical, names, np.where(typical != 0, typical, 1.0)))
        for metric in ("euclidean", "entropic"):
            times = []
            for _ in range(5):
                t0 = time.perf_counter()
                out = consistent_parameters(names, ("",) * len(names), H, noisy, np.diag(sigma ** 2), cad, scale,
                                            robot.physical_bodies(), metric=metric, truth=truth)
                times.append(time.perf_counter() - t0)
            print(f"{path:<28} {metric:<10} {len(names):>4} {len(beta):>4} {len(out.bodies):>6} "
                  f"{np.median(times):>9.3f} {out.chi2:>9.3g} {out.chi2_limit:>6.1f} "
                  f"{min(b.margin for b in out.bodies):>11.3g}")


if __name__ == "__main__":
    main()
