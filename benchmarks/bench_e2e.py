"""End to end: six emulated drives (EPOS2 theta1..3, EPOS4 zeta1..3) and the real canopen master
in ONE process on python-can's virtual bus, streaming a sinusoid at 1 kHz and at 250 Hz SYNC.

Per rate it prints
* lost samples: rows with a missing or duplicated TPDO (flagged invalid, NaN), invalid cells,
  recorder buffer overflows, set-points sent after their SYNC (``late_setpoints``);
* SYNC period jitter, from the recorded SYNC timestamps (= ``Recording.t``): mean period, std,
  p99 and max of |period - nominal|;
* SYNC-to-sample latency, from the raw log: the j-th SYNC-triggered TPDO1 of a node answers the
  j-th SYNC (the rig answers every SYNC in order), so latency = its timestamp - that SYNC's; and
  how many arrived after the next SYNC (the assembler then counts them in a later cycle);
  and *stale valid* cells: a sample of an earlier SYNC that filled a later cycle flagged valid
  (the master cannot tell: TPDOs carry no SYNC counter; a real drive answers within its period);
* SYNC-to-set-point latency: master's RPDO after the SYNC echo;
* the rig's own per-SYNC cost (plant + six drives), and the process CPU time per SYNC cycle
  (rig + master + SYNC producer, all on one GIL): above the period, the rig falls behind;
* the garbage collections during the run (``gc_longest_pause`` of the recording);
* the bus-load budget of this PDO layout on a 1 Mbit/s bus (the virtual bus has no bitrate).

    python benchmarks/bench_e2e.py [seconds=60] [rate_hz ...=1000 250]
"""

from __future__ import annotations

import dataclasses
import resource
import sys
import tempfile
import time
from pathlib import Path

import can
import numpy as np

from drivers.acquisition import cycle_frame_sizes
from drivers.cia import SYNC_COB_ID
from drivers.bus import BusConfig, check_bus_load, cycle_bits, frame_bits, max_sync_rate, open_network
from drivers.epos import DriveGroup
from drivers.sim import Plant, SimulatedRig
from ident_hw.config import load_config, to_model
from ident_hw.config.robots import model_of
from ident_hw.config.to_drivers import axis_config

CONFIG = load_config(Path(__file__).resolve().parent.parent / "configs" / "sim-3prrr.yaml")
AXES = [dataclasses.replace(axis_config(a), profile="epos2" if i < 3 else "epos4")
        for i, a in enumerate(CONFIG.robot.actuators)]
BITRATE = 1_000_000
DRAIN_TIMEOUT = 120.0  # s to let the rig work off its backlog after a run


def bus_budget(group: DriveGroup) -> None:
    """Worst-case load of this layout at 1 Mbit/s, and the minimal TPDO1 + RPDO1 layout."""
    sizes = cycle_frame_sizes(group.layouts)
    background = frame_bits(1) * (len(AXES) + 1) / group.heartbeat_period
    minimal = [0] + [8, 6] * len(AXES)
    for label, frames, bg in (("this run's layout", sizes, background),
                              ("minimal: SYNC + TPDO1 + RPDO1 per drive", minimal, 0.0)):
        rate = max_sync_rate(frames, BITRATE, bg)
        print(f"  bus budget at 1 Mbit/s, {label}: {len(frames)} frames = {cycle_bits(frames)} bits per "
              f"cycle (worst-case stuffing) + {bg:.0f} bit/s background; load at 1 kHz "
              f"{(cycle_bits(frames) * 1000 + bg) / BITRATE:.0%}, at 250 Hz "
              f"{check_bus_load(frames, 0.004, BITRATE, bg):.0%}; ceiling {rate:.0f} Hz")


def raw_timing(path: Path, node_ids: list[int]):
    """From the raw log: SYNC timestamps, per-node TPDO1 timestamps, SYNC->first RPDO latencies (s)."""
    syncs, tpdo = [], {n: [] for n in node_ids}
    rpdo_first = {}
    with can.LogReader(path) as reader:
        for msg in reader:
            cob = msg.arbitration_id
            if cob == SYNC_COB_ID:
                syncs.append(msg.timestamp)
            elif cob - 0x180 in tpdo:
                tpdo[cob - 0x180].append(msg.timestamp)
            elif 0x201 <= cob <= 0x27F and syncs:
                rpdo_first.setdefault(len(syncs) - 1, msg.timestamp)
    syncs = np.array(syncs)
    return syncs, {n: np.array(v) for n, v in tpdo.items()}, np.array([t - syncs[k] for k, t in rpdo_first.items()])


def sample_timing(syncs: np.ndarray, tpdo: dict, valid: np.ndarray):
    """The j-th TPDO1 of a node answers the j-th SYNC (the rig answers every SYNC, in order):
    latencies (s), samples that came after the next SYNC, SYNCs unanswered when the log closed,
    and *stale valid* cells: a row flagged valid whose sample answered an earlier SYNC."""
    lat, after_next, unanswered, stale = [], 0, 0, 0
    n = len(valid)
    for axis, stamps in enumerate(tpdo.values()):
        m = min(len(stamps), len(syncs))
        lat.append(stamps[:m] - syncs[:m])
        cycle = np.searchsorted(syncs, stamps[:m], side="right") - 1  # the cycle it was counted in
        after_next += int(np.count_nonzero(cycle > np.arange(m)))
        unanswered += max(0, min(n, len(syncs)) - len(stamps))
        shifted = (cycle != np.arange(m)) & (cycle < n)
        stale += int(np.count_nonzero(valid[cycle[shifted], axis]))
    return np.concatenate(lat), after_next, unanswered, stale


def process_cpu() -> float:
    """CPU time (user + system, s) of this process, all threads."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def stats_us(x: np.ndarray) -> str:
    x = np.asarray(x) * 1e6
    if not len(x):
        return "n/a"
    return f"median {np.median(x):8.0f} | p99 {np.percentile(x, 99):8.0f} | max {x.max():8.0f} us"


def run(rate_hz: float, seconds: float, index: int) -> dict:
    period = 1.0 / rate_hz
    channel = f"bench-e2e-{index}"
    robot = model_of(CONFIG.robot)
    rig = SimulatedRig([(a.node_id, a.profile, a.scaling) for a in AXES],
                       Plant(robot, to_model.inertial_params(CONFIG.sim.truth)), seed=1, current_noise_ma=2.0,
                       interface="virtual", channel=channel, ignore_config=True).start()
    network = open_network(BusConfig("virtual", channel, ignore_config=True))
    group = DriveGroup(network, AXES, sdo_timeout=10.0)   # SDO waits behind the rig's SYNC backlog at 1 kHz
    try:
        group.bring_up()
        group.home()
        if index == 0:
            bus_budget(group)
        start = group.positions()
        t = np.arange(round(seconds * rate_hz)) * period
        amp = np.array([0.05] * 3 + [0.004] * 3)
        targets = start + np.sin(2 * np.pi * 0.5 * t)[:, None] * np.minimum(1.0, t / 2)[:, None] * amp
        targets[-round(2 * rate_hz):] = targets[-round(2 * rate_hz)]  # hold the last 2 s
        rig.step_seconds.clear()
        with tempfile.TemporaryDirectory() as tmp:
            raw = Path(tmp) / "raw.log"
            wall, cpu = time.perf_counter(), process_cpu()
            rec = group.run_cyclic(targets, period, output=Path(tmp) / "run.npz", raw_log=raw)
            wall, cpu = time.perf_counter() - wall, process_cpu() - cpu
            syncs, tpdo, rp = raw_timing(raw, [a.node_id for a in AXES])
            lat, after_next, unanswered, stale = sample_timing(syncs, tpdo, rec.valid)
        deadline = time.monotonic() + DRAIN_TIMEOUT
        while rig.sync_count < len(syncs) and time.monotonic() < deadline:
            time.sleep(0.1)
        cost = np.array(rig.step_seconds)
    finally:
        group.close()
        network.disconnect()
        rig.stop()
    dev = np.diff(rec.t) - period
    invalid_cells = int(np.count_nonzero(~rec.valid))
    print(f"\n{rate_hz:g} Hz SYNC, {seconds:g} s: {len(targets)} cycles in {wall:.1f} s wall")
    print(f"  rows recorded {rec.metadata.n_cycles}, invalid rows {rec.n_invalid} "
          f"({rec.n_invalid / max(1, len(rec.t)):.2%}), invalid cells {invalid_cells}, buffer overflows "
          f"{rec.metadata.buffer_overflows}, late frames {rec.metadata.books.late_frames}, late set-points "
          f"{rec.metadata.late_setpoints}")
    print(f"  SYNC period: mean {np.mean(np.diff(rec.t)) * 1e6:.1f} us (nominal {period * 1e6:.0f}), "
          f"|dev| std {dev.std() * 1e6:.0f} us, p99 {np.percentile(np.abs(dev), 99) * 1e6:.0f} us, "
          f"max {np.abs(dev).max() * 1e6:.0f} us")
    print(f"  SYNC->TPDO1 latency (6 nodes, ordinal match): {stats_us(lat)}")
    print(f"    samples arriving after the next SYNC: {after_next} of {len(lat)}; SYNCs never answered "
          f"before the log closed: {unanswered}; stale samples in cells flagged valid: {stale}")
    print(f"  SYNC->set-point (RPDO) latency: {stats_us(rp)}")
    print(f"  rig per-SYNC cost: {stats_us(cost)} (budget {period * 1e6:.0f} us)")
    print(f"  process CPU time per SYNC cycle (rig + master + SYNC, one GIL): {cpu / len(targets) * 1e6:.0f} us "
          f"of {period * 1e6:.0f} us")
    print(f"  garbage collections while streaming: {rec.metadata.gc_collections}, longest "
          f"{rec.metadata.gc_longest_pause * 1e3:.2f} ms")
    return {"rate": rate_hz, "invalid": rec.n_invalid, "rows": len(rec.t)}


def main(argv: list[str]) -> None:
    seconds = float(argv[0]) if argv else 60.0
    rates = [float(r) for r in argv[1:]] or [1000.0, 250.0]
    print(f"bench_e2e: six emulated drives + canopen master, one process, virtual bus, {seconds:g} s per rate")
    for i, rate in enumerate(rates):
        run(rate, seconds, i)


if __name__ == "__main__":
    main(sys.argv[1:])
