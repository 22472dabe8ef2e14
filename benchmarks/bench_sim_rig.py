"""Per-SYNC cost of the simulated rig (plant step + six drives' TPDOs) at 250 Hz and 1 kHz.

A canopen master on the virtual bus maps TPDO1 (position + current) and TPDO2 (statusword, event)
on six EPOS4 drives, enables them in CSP and produces SYNC; we report the time the rig spends
in each SYNC callback and whether every TPDO1 arrived. Run: ``python benchmarks/bench_sim_rig.py``.
"""

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_sim_rig import Bench, configure_pdos  # noqa: E402


def run(rate_hz: float, seconds: float) -> None:
    b = Bench(sync_period=1.0 / rate_hz)
    try:
        b.rig.start()
        counts = [0] * 6
        for j, node in enumerate(b.nodes):
            configure_pdos(node, "EPOS4")
            node.sdo[0x6060].raw = 8
            for cw in (0x06, 0x07, 0x0F):
                node.sdo[0x6040].raw = cw
            node.tpdo[1].add_callback(lambda m, j=j: counts.__setitem__(j, counts[j] + 1))
        b.master.nmt.state = "OPERATIONAL"
        time.sleep(0.1)
        b.rig.step_seconds.clear()
        start_sync = b.rig.sync_count
        b.master.sync.start(1.0 / rate_hz)
        time.sleep(seconds)
        b.master.sync.stop()
        time.sleep(0.1)
        steps = np.array(b.rig.step_seconds) * 1e6
        syncs = b.rig.sync_count - start_sync
        print(f"{rate_hz:6.0f} Hz, {seconds:.0f} s: {syncs} SYNC handled ({syncs / seconds:.0f}/s), "
              f"per-SYNC cost median {np.median(steps):.0f} us, p99 {np.percentile(steps, 99):.0f} us, "
              f"max {steps.max():.0f} us; TPDO1 received per node {counts} (expected ~{syncs})")
    finally:
        b.close()


if __name__ == "__main__":
    run(250, 5)
    run(1000, 5)
