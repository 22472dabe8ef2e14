"""Wall time and accuracy of the whole simulated campaign, as a user runs it.

    python benchmarks/bench_campaign.py [CONFIG]     (default: configs/sim-3prrr.yaml)

Runs ``ident-hw run CONFIG --quiet`` in a subprocess (rig and master in one process, 250 Hz
SYNC) into a temporary folder; prints the wall time, the run's own summary (the physical
parameters step by step, the base parameters of the least-squares step, the validation) and
the figures of issue 6: the worst error against the simulated truth among the base parameters
identified on their data (%sigma below the config's threshold) and the validation d_tau of
both results.
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
        print(f"ident-hw run {config}: exit {proc.returncode}, wall time {wall:.1f} s")
        print(proc.stdout)
        if proc.returncode != 0:
            print(proc.stderr[-2000:])
            return
        doc = json.loads((out / "parameters.json").read_text())
        base = doc.get("base_fit")
        if base is not None:
            good = [r for r in base["rows"] if r["well_identified"] and r.get("error_percent") is not None]
            worst = max(good, key=lambda r: abs(r["error_percent"]))
            print(f"base fit: {len(good)} of {len(base['rows'])} base parameters identified "
                  f"(%sigma <= {base['threshold_rel_sigma_percent']:g}); worst error "
                  f"{worst['error_percent']:+.2f} % ({worst['base_parameter']})")
        for name, m in yaml.safe_load((out / "metrics.yaml").read_text()).items():
            if m["role"] == "validation":
                extra = f", base fit {m['base_fit']['d_tau_percent']:.2f} %" if "base_fit" in m else ""
                print(f"validation {name}: d_tau step by step {m['d_tau_percent']:.2f} %{extra}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "configs/sim-3prrr.yaml")
