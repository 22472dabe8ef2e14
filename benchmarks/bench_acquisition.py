"""Acquisition capacity of the master: frames per second decoded and recorded without loss.

A second thread plays six drives on python-can's virtual bus as fast as it can (SYNC, then per
drive TPDO1 position+current(+statusword) and TPDO3 velocity); the master side is the real
canopen network + notifier, the CycleAssembler and the SampleRecorder thread writing an NPZ.
Prints frames/s and checks that every cycle arrived complete (no loss).

    python benchmarks/bench_acquisition.py [n_cycles] [epos2|epos4]
"""

import sys
import tempfile
import threading
import time
from pathlib import Path

import can

from drivers.acquisition import CycleAssembler, master_layouts
from drivers.axis import AxisConfig
from drivers.bus import BusConfig, open_network
from drivers.recording import SampleRecorder
from drivers.units import AxisScaling


def main(n_cycles: int = 20000, profile: str = "epos4") -> None:
    scaling = AxisScaling("revolute", 2048, 0.0369, gear_ratio=26.0)
    axes = [AxisConfig(f"a{i}", i + 1, profile, scaling, -6, 6, 3, 4, 0.05) for i in range(6)]
    layouts = master_layouts(axes)
    per_cycle = []
    for a, lay in zip(axes, layouts):
        for f in lay.frames:
            if f.direction == "tpdo" and f.per_sync:
                values = {"position": 123456, "current": -1500, "statusword": 0x0237, "velocity": 42}
                per_cycle.append(can.Message(arbitration_id=f.cob_id(a.node_id), is_extended_id=False,
                                             data=f.struct.pack(*[values[n] for n, _ in f.entries])))
    sync = can.Message(arbitration_id=0x80, is_extended_id=False, data=b"")
    network = open_network(BusConfig("virtual", "bench-acq", ignore_config=True))
    with tempfile.TemporaryDirectory() as tmp:
        recorder = SampleRecorder(axes, Path(tmp) / "bench.npz").start()
        asm = CycleAssembler(layouts, recorder.put, max_cycles=n_cycles)
        network.notifier.add_listener(asm)
        feeder_bus = can.Bus(interface="virtual", channel="bench-acq", ignore_config=True)

        def feed():
            for _ in range(n_cycles + 1):
                feeder_bus.send(sync)
                for m in per_cycle:
                    feeder_bus.send(m)

        t0 = time.perf_counter()
        threading.Thread(target=feed).start()
        while not asm.done:
            time.sleep(0.005)
        elapsed = time.perf_counter() - t0
        rec = recorder.close()
        feeder_bus.shutdown()
    network.disconnect()
    frames = n_cycles * (1 + len(per_cycle))
    print(f"{profile}: {n_cycles} cycles x {1 + len(per_cycle)} frames in {elapsed:.2f} s: "
          f"{frames / elapsed:,.0f} frames/s decoded+recorded; rows {rec.metadata.n_cycles}, "
          f"invalid {rec.n_invalid}, overflows {rec.metadata.buffer_overflows}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20000, sys.argv[2] if len(sys.argv) > 2 else "epos4")
