"""The UR10e's real recordings (issue 46): which friction model predicts the held-out run best.

    IDENT_HW_DATASETS=/path/to/datasets python benchmarks/bench_ur10e.py [--runs all|authors] [--models a,b,...]

Identifies ``configs/ur10e.yaml`` with each friction model (the config's ``robot.friction``
replaced) from the authors' excitation run (rows 635..3510) and, with ``--runs all``, from each
other excitation run of the dataset given whole (its idle head and tail found), and prints per
model the per-joint rre (%) on the authors' point-to-point validation run beside the published
parameters', its mean, and over the runs the mean and the worst joint-by-joint ratio to the
published. The published set's rre does not depend on the run.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from ident_hw.config import load_config  # noqa: E402
from ident_hw.config.friction import FrictionConfig  # noqa: E402
from ident_hw.experiment.offline import identify  # noqa: E402
from ident_hw.experiment.recordings import gather_recordings  # noqa: E402
from ident_hw.results import validation_figures  # noqa: E402

#: the friction models compared, as ``robot.friction`` sections
MODELS = {
    "coulomb": FrictionConfig(model="coulomb"),
    "coulomb+offset": FrictionConfig(model="coulomb", offset=True),
    "held+offset": FrictionConfig(model="held", offset=True),
    "coulomb+stribeck+offset": FrictionConfig(model="coulomb", offset=True, stribeck="auto"),
    "dahl+offset": FrictionConfig(model="dahl", offset=True, presliding="auto"),
    "maxwell+offset": FrictionConfig(model="maxwell", offset=True),
    "dahl+stribeck+offset (shipped)": FrictionConfig(model="dahl", offset=True, presliding="auto", stribeck="auto"),
}
RUNS = ("ur-20_02_05-20sec_12harm.csv", "ur-20_02_05-20sec_8harm.csv", "ur-20_02_06-20sec_10harm.csv",
        "ur-20_02_06-20sec_5harm.csv", "ur-20_02_10-20sec_7harm.csv", "ur-20_02_10-30sec_12harm.csv",
        "ur-20_02_12-40sec_12harm.csv", "ur-20_02_19_14harm50sec.csv", "ur-19_12_23_free.csv")


def rre(config, given=()) -> tuple[np.ndarray, np.ndarray]:
    gathered = gather_recordings(config, list(given))
    recordings, imported = gathered.recordings, gathered.imported
    figures = validation_figures(identify(config, recordings, imported=imported))["validation"]
    return (np.array(figures.rre_percent.fit, dtype=float),
            np.array(figures.rre_percent.compared, dtype=float))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", choices=("authors", "all"), default="all")
    parser.add_argument("--models", default=",".join(MODELS))
    args = parser.parse_args()
    if not os.environ.get("IDENT_HW_DATASETS"):
        sys.exit("IDENT_HW_DATASETS: the folder holding ur10e/ is not set")
    base = load_config(ROOT / "configs" / "ur10e.yaml")
    folder = Path(os.environ["IDENT_HW_DATASETS"]) / "ur10e" / "identification"
    published = None
    for name in args.models.split(","):
        config = dataclasses.replace(base, robot=dataclasses.replace(base.robot, friction=MODELS[name]))
        started = time.perf_counter()
        ours, published = rre(config)
        line = f"{name:32s} authors' run: " + " ".join(f"{v:5.1f}" for v in ours) + f"  mean {ours.mean():5.2f}"
        if args.runs == "all":
            per_run = np.array([rre(config, [f"excitation={folder / run}"])[0] for run in RUNS])
            worse = int(np.sum(np.any(per_run > published, axis=1)))
            line += (f" | {len(RUNS)} runs whole: mean {per_run.mean():5.2f} (run means {per_run.mean(axis=1).min():.2f}"
                     f"-{per_run.mean(axis=1).max():.2f}), runs with a joint above the published: {worse}")
        print(line + f"  [{time.perf_counter() - started:.0f} s]", flush=True)
    print(f"{'published (Mamedov et al. 2020)':32s}              " + " ".join(f"{v:5.1f}" for v in published)
          + f"  mean {published.mean():5.2f}")


if __name__ == "__main__":
    main()
