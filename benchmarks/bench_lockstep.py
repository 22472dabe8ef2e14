"""Lockstep rate of the simulated rig: SYNC cycles per wall-clock second, and what a cycle costs.

The main job's rig (``configs/sim-3prrr.yaml``: six emulated drives, the 3PRRR plant, 1 mA
current quantisation and noise) and the canopen master in one process on the in-process
``virtual`` bus, in lockstep (``bus.sync: lockstep``): the master streams a sinusoid on every
axis for ``seconds`` of simulated time at ``rate_hz`` SYNC, as fast as the host lets it.

Prints the cycles per wall-clock second and what a cycle costs:
* the CPU time of each thread per cycle (Linux, ``/proc``): the rig's notifier (its drives' RPDOs,
  the SYNC handler: demands, sensors, TPDOs, plant step), the master's notifier (echoes and the
  drives' frames: cycle assembly, the lockstep's count), the master's own thread (set-points,
  SYNC) and the rig's clock;
* the plant step (forward kinematics, reduced dynamics, Heun substeps), timed alone;
* the rig's SYNC handler in wall time, median: it includes what the master's threads ran while
  the plant step left the GIL.

As in the main job, the threads run on one CPU (:func:`drivers.affinity.one_cpu`); ``spread``
lets them run on every CPU, for comparison.

    python benchmarks/bench_lockstep.py [seconds=20] [rate_hz=250] [spread] [config=configs/sim-stewart.yaml] [drop=0.05]

``config``: another simulated robot (its rig in lockstep the same way; the sinusoid's amplitude
a tenth of each actuator's room about home). ``drop``: the share of the drives' PDO frames the
rig's fault injection loses (:meth:`drivers.sim.SimulatedRig.frame_faults`); the master asks each
such cycle again.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import threading
import timeit
from contextlib import nullcontext
from pathlib import Path

import can
import numpy as np

from drivers.affinity import one_cpu
from drivers.bus import BusConfig, open_network
from drivers.epos import DriveGroup
from drivers.sim.lockstep import LockstepSync
from ident_hw.config import load_config
from ident_hw.experiment.session import simulated_rig
from ident_hw.config.to_drivers import axis_config
from ident_hw.experiment.robot_trajectories import actuator_limits

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "sim-3prrr.yaml"
#: the main job's sinusoid amplitudes (rad, m), as measured since the first figures
MAIN_JOB_AMPLITUDE = np.array([0.05, 0.05, 0.05, 0.004, 0.004, 0.004])


def main(seconds: float, rate_hz: float, spread: bool, path: Path = CONFIG, drop: float = 0.0) -> None:
    with nullcontext(None) if spread else one_cpu() as cpu:
        print(f"threads on CPU {cpu}" if cpu is not None else "threads on every CPU")
        run(seconds, rate_hz, path, drop)


def run(seconds: float, rate_hz: float, path: Path = CONFIG, drop: float = 0.0) -> None:
    config = load_config(path)
    config = dataclasses.replace(config, bus=dataclasses.replace(config.bus, sync_rate=rate_hz,
                                                                 channel="bench-lockstep"))
    period = 1.0 / rate_hz
    axes = [axis_config(a) for a in config.robot.actuators]
    rig = simulated_rig(config).start()
    network = open_network(BusConfig("virtual", config.bus.channel, ignore_config=True))
    group = DriveGroup(network, axes, sync=LockstepSync(period))
    try:
        group.bring_up()
        group.home()
        start = group.positions()
        t = np.arange(round(seconds / period)) * period
        limits = actuator_limits(config.robot)
        room = np.minimum(start - limits.low, limits.high - start)
        amplitude = MAIN_JOB_AMPLITUDE if Path(path) == CONFIG else 0.1 * room
        targets = start + np.sin(2 * np.pi * 0.5 * t)[:, None] * np.sin(np.pi * t / t[-1])[:, None] * amplitude
        rig.frame_faults(drop_probability=drop)
        rig.step_seconds.clear()
        threads = {"rig's notifier": ThreadOf(), "master's notifier": ThreadOf()}
        rig.network.notifier.add_listener(threads["rig's notifier"])
        network.notifier.add_listener(threads["master's notifier"])
        threads["master's thread"] = ThreadOf(threading.get_native_id())
        cpu_before = thread_cpu()
        began = timeit.default_timer()
        rec = group.run_cyclic(targets, period)
        wall = timeit.default_timer() - began
        cpu = {tid: used - cpu_before.get(tid, 0.0) for tid, used in thread_cpu().items()}
        clock = next((t.native_id for t in threading.enumerate() if t.name == "sim-rig-clock"), None)
        threads["rig's clock"] = ThreadOf(clock)
        rig_us = float(np.median(rig.step_seconds)) * 1e6
    finally:
        group.close()
        network.disconnect()
        rig.stop()
    plant = rig.plant
    n_axes = len(axes)
    demand = np.vstack([plant.Theta, np.zeros((3, n_axes))])
    enabled, limit = np.ones(n_axes, bool), np.full(n_axes, 1e3)
    n = 500
    plant_us = timeit.timeit(lambda: plant.step(period, demand, enabled, limit), number=n) / n * 1e6
    cycles = rec.metadata.n_cycles
    per_cycle_us = wall / cycles * 1e6
    print(f"lockstep at {rate_hz:g} Hz, {seconds:g} s simulated: {cycles} cycles in {wall:.1f} s wall = "
          f"{cycles / wall:.0f} cycles/s ({cycles / wall * period:.2f}x real time); "
          f"{rec.n_invalid} incomplete, {rec.metadata.sync_report.lockstep_retries} asked again "
          f"({rec.metadata.sync_report.lockstep_waited_out} after waiting; {rig.network.dropped} frames dropped)")
    if cpu:
        print(f"per cycle {per_cycle_us:.0f} us wall; CPU by thread: " + ", ".join(
            f"{name} {cpu.get(thread.native_id, 0.0) / cycles * 1e6:.0f} us" for name, thread in threads.items()))
    print(f"plant step alone {plant_us:.0f} us; the rig's SYNC handler {rig_us:.0f} us wall (median)")


class ThreadOf(can.Listener):
    """The native ID of the thread a notifier calls its listeners in (or the one given)."""

    def __init__(self, native_id: int | None = None):
        self.native_id = native_id

    def on_message_received(self, msg: can.Message) -> None:
        if self.native_id is None:
            self.native_id = threading.get_native_id()


def thread_cpu() -> dict[int, float]:
    """User + system CPU seconds of each thread of this process by native ID (Linux ``/proc``;
    empty elsewhere)."""
    tasks = Path("/proc/self/task")
    if not tasks.is_dir():
        return {}
    ticks = os.sysconf("SC_CLK_TCK")
    used = {}
    for task in tasks.iterdir():
        try:
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:          # the thread ended meanwhile
            continue
        used[int(task.name)] = (int(fields[11]) + int(fields[12])) / ticks
    return used


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "spread" and "=" not in a]
    options = dict(a.split("=", 1) for a in sys.argv[1:] if "=" in a)
    main(float(args[0]) if args else 20.0, float(args[1]) if len(args) > 1 else 250.0, "spread" in sys.argv[1:],
         Path(options.get("config", CONFIG)), float(options.get("drop", 0.0)))
