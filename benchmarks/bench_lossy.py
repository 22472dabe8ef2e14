"""Rows kept and accuracy on a lossy bus: the main job's excitation with one TPDO frame left out
of a seeded share of its SYNC cycles (any TPDO of any drive alike), decoded and identified alone
(the base step). Prints, per share and seed, the rows used and the base parameters against the
simulated truth: the worst of ``|error| / (3 σ + 1 % of the truth)`` (the main job's test passes
below 1), the largest error and the largest relative σ.

    ident-hw run configs/sim-3prrr.yaml --out results/main
    python benchmarks/bench_lossy.py results/main [0.001,0.01,0.05] [seeds: 0,1,2]
"""

import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from drivers.acquisition import master_layouts  # noqa: E402
from drivers.recording import Recording  # noqa: E402
from ident_hw.config import load_config  # noqa: E402
from ident_hw.experiment.offline import identify  # noqa: E402
from ident_hw.experiment.recordings import load_recording  # noqa: E402
from lossy_logs import drop_frames  # noqa: E402
from test_main_job import BIAS_BUDGET, evaluate  # noqa: E402
from ident_hw.config.robots import model_of, true_parameters
from ident_hw.config.to_drivers import axis_config

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "sim-3prrr.yaml"


def main(folder: Path, shares: list[float], seeds: list[int]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        path = tmp / "base-only.yaml"
        path.write_text(f"extends: {CONFIG}\nidentification:\n  steps:\n"
                        "    - {name: base, trajectories: [excitation], parameters: [all], method: wls}\n"
                        "  validation: []\n")
        config = load_config(path)
        truth = dict(zip(model_of(config.robot).parameter_names, true_parameters(config)))
        layouts = master_layouts([axis_config(a) for a in config.robot.actuators])
        cycles = len(Recording.load(folder / "data" / "excitation.npz").t)
        for share in [0.0] + shares:
            for seed in seeds if share else [0]:
                log = tmp / f"{share}-{seed}" / "excitation.log"
                log.parent.mkdir()
                dropped = drop_frames(folder / "data" / "excitation.log", log, layouts, share, cycles, seed)
                _, rec = load_recording(log, config)
                results = identify(config, {"excitation": rec})
                used = results.trajectories["excitation"]
                kept = used.cycles - sum(used.rows_left_out.values())
                fit = results.base_fit
                rows = [(abs(c - t) / (3 * s + BIAS_BUDGET * abs(t)), abs(c / t - 1), s / abs(t))
                        for c, s, t in zip(fit.coef, fit.sigma, (evaluate(e, truth) for e in fit.expressions))]
                well = sum(r[2] * 100 <= results.rel_sigma_threshold for r in rows)
                print(f"{100 * share:5.1f} % seed {seed}: {len(dropped.measured):4d} position/current and "
                      f"{len(dropped.others):4d} velocity frames lost; rows used {kept / used.cycles:.1%}; "
                      f"{well} of {len(rows)} well identified, bound {max(r[0] for r in rows):.2f}, "
                      f"largest error {max(r[1] for r in rows):.2%}, largest σ {max(r[2] for r in rows):.2%}",
                      flush=True)


if __name__ == "__main__":
    shares = [float(x) for x in sys.argv[2].split(",")] if len(sys.argv) > 2 else [0.001, 0.01, 0.05]
    seeds = [int(x) for x in sys.argv[3].split(",")] if len(sys.argv) > 3 else [0, 1, 2]
    main(Path(sys.argv[1]), shares, seeds)
