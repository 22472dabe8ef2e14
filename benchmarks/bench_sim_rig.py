"""Per-SYNC cost of the simulated rig at 250 Hz and 1 kHz: alone, and with a canopen master in the process.

The nominal rig (``tests/nominal.py``, six EPOS4) on python-can's virtual bus. "alone": the
benchmark drives the rig's SYNC cycle directly, with the six drives enabled in CSP and their
TPDOs mapped, so the numbers are the rig's own cost (plant step + drives + TPDO packing).
"with master": a canopen master maps TPDO1 (position + current, SYNC) and TPDO2 (statusword,
event) over SDO, enables the drives, produces SYNC with python-can's periodic send and counts the
TPDO1 it receives. "alone" also splits the cost: the plant step (per period: the model's
forward kinematics and reduced dynamics, once, then the Heun substeps) and, inside it, the
model's dynamics alone. Run: ``python benchmarks/bench_sim_rig.py``.
"""

import sys
import time
import timeit
from pathlib import Path

import canopen
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import nominal  # noqa: E402
from drivers.profiles import make_object_dictionary  # noqa: E402
from drivers.sim import SimulatedRig  # noqa: E402

CHANNEL = "bench-sim-rig"


def map_and_enable(node: canopen.RemoteNode) -> None:
    """TPDO1 = position + current (SYNC), TPDO2 = statusword (on change); CSP, OPERATION ENABLED."""
    node.tpdo.read()
    for pdo in node.tpdo.values():
        pdo.enabled = False
    t1, t2 = node.tpdo[1], node.tpdo[2]
    t1.clear()
    t1.add_variable(0x6064)
    t1.add_variable(0x30D1, 2)
    t1.trans_type, t1.enabled = 1, True
    t2.clear()
    t2.add_variable(0x6041)
    t2.trans_type, t2.enabled = 255, True   # on change: a real EPOS4 has no TPDO event timer
    node.tpdo.save()
    node.sdo[0x6060].raw = 8
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw


def summary(label: str, seconds: list[float], wall: float) -> str:
    us = np.array(seconds) * 1e6
    return (f"{label}: {len(us)} SYNC in {wall:.1f} s; per-SYNC cost median {np.median(us):.0f} us, "
            f"p99 {np.percentile(us, 99):.0f} us, max {us.max():.0f} us")


def split(rig: SimulatedRig, period: float, n: int = 2000) -> str:
    """Mean costs of the plant step and of the model's dynamics in it (us)."""
    plant, robot = rig.plant, rig.plant.robot
    demand = np.vstack([plant.Theta, np.zeros((3, 6))])
    enabled, limit = np.ones(6, bool), np.full(6, 1e3)
    step = timeit.timeit(lambda: plant.step(period, demand, enabled, limit), number=n) / n

    def dynamics():
        Theta = plant.Theta[None]
        motion = robot.motion_from_actuated(Theta, plant.Thetad[None], np.zeros_like(Theta), plant.X)
        robot.reduced_dynamics_of(motion, plant.params)
    model = timeit.timeit(dynamics, number=n) / n
    return f"; plant step {step * 1e6:.0f} us, of which the model's dynamics {model * 1e6:.0f} us"


def run(rate_hz: float, seconds: float, with_master: bool) -> None:
    rig = SimulatedRig.build(nominal.ROBOT, nominal.TRUE_PARAMS, nominal.axes("epos4"), sync_period=1.0 / rate_hz,
                             interface="virtual", channel=CHANNEL, ignore_config=True)
    master = canopen.Network()
    master.connect(interface="virtual", channel=CHANNEL, ignore_config=True)
    try:
        rig.start()
        counts = [0] * 6
        for j, drive in enumerate(rig.drives):
            node = master.add_node(drive.id, make_object_dictionary("epos4", drive.id))
            map_and_enable(node)
            node.tpdo[1].add_callback(lambda m, j=j: counts.__setitem__(j, counts[j] + 1))
        master.nmt.state = "OPERATIONAL"
        time.sleep(0.1)
        rig.step_seconds.clear()
        done_before = rig.syncs_done
        start = time.perf_counter()
        if with_master:
            master.sync.start(1.0 / rate_hz)
            time.sleep(seconds)
            master.sync.stop()
        else:   # the rig's SYNC handler called back to back, as fast as it runs
            for _ in range(int(rate_hz * seconds)):
                rig._on_sync(0x80, b"", time.monotonic())
        wall = time.perf_counter() - start
        time.sleep(0.2)
        line = summary(f"{rate_hz:6.0f} Hz {'rig + master' if with_master else 'rig alone   '}", rig.step_seconds, wall)
        if not with_master:
            line += split(rig, 1.0 / rate_hz)
        if with_master:
            n = rig.syncs_done - done_before
            line += f"; SYNC handled {n / seconds:.0f}/s of {rate_hz:.0f}; TPDO1 received per node {counts} of {n}"
        print(line, flush=True)
    finally:
        master.disconnect()
        rig.stop()


if __name__ == "__main__":
    for rate in (250.0, 1000.0):
        run(rate, 5.0, with_master=False)
        run(rate, 5.0, with_master=True)
