"""Wall time and accuracy of the whole simulated campaign, as a user runs it.

    python benchmarks/bench_campaign.py [CONFIG]     (default: configs/sim-3prrr.yaml)

Runs ``ident-hw run CONFIG --quiet`` in a subprocess (rig and master in one process, 250 Hz
SYNC) into a temporary folder and prints the wall time, each fitted parameter's error against
the simulated truth with its %sigma, and the validation errors (d_tau, seed 001).
"""

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def main(config: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        start = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "ident_hw.cli", "run", config, "--quiet", "--out", str(out)],
                              cwd=ROOT, capture_output=True, text=True)
        wall = time.perf_counter() - start
        print(f"ident-hw run {config}: exit {proc.returncode}, wall time {wall:.1f} s, "
              f"STATUS {(out / 'STATUS').read_text().strip() if (out / 'STATUS').exists() else '?'}")
        if proc.returncode != 0:
            print(proc.stderr[-2000:])
            return
        rows = json.loads((out / "parameters.json").read_text())["parameters"]
        worst = 0.0
        for r in rows:
            if not r["step"]:
                continue
            err = r.get("error_percent")
            sig = r["rel_sigma_percent"]
            print(f"  {r['name']:>10} [{r['step']}]: {r['identified']:.6g} {r['unit']} (truth {r.get('truth', float('nan')):.6g}), "
                  f"error {err:+.2f} %, %sigma {sig if sig is not None else float('nan'):.2f}")
            if r["name"].startswith(("m_", "I_")) and err is not None:
                worst = max(worst, abs(err))
        print(f"  worst inertial-parameter error: {worst:.2f} %")
        for name, m in yaml.safe_load((out / "metrics.yaml").read_text()).items():
            print(f"  {m['role']:>14} {name}: d_tau = {m['d_tau_percent']:.2f} %")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "configs/sim-3prrr.yaml")
