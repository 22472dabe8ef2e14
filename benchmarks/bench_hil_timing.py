"""The lab's HIL campaigns against drives in another process, the master's process disturbed (issue 50).

    python benchmarks/bench_hil_timing.py [--configs hil-3prrr-epos2.yaml hil-3prrr-epos4.yaml]
                                          [--hold 1.0] [--every 10] [--busy N] [--no-realtime]
                                          [--keep DIR]

For each config: its bus swapped for an interface-local ``udp_multicast`` group with a periodic SYNC
(real time, as on a real bus), the main job's simulated truth served by ``ident-hw sim`` in its
own process, on the last CPU (its threads at real-time priority 10 where the system grants it,
unless ``--no-realtime``: real drives answer a SYNC in microseconds and take no CPU of the master's
PC), a busy loop pinned to each of ``--busy`` CPUs (default all), and ``ident-hw run`` of the whole
campaign with its process held ``--hold`` s by a GIL-holding C call every
``--every`` s. The master's SYNC, set-points and heartbeat come from its timing process
(``bus.timing: auto``); ``--no-realtime`` runs that process at normal priority (what a lab PC
without real-time rights gets).

Prints, per trajectory: cycles recorded of those planned, incomplete cycles, SYNC slots skipped,
the latest a SYNC and the heartbeat went out after their slot, the longest hold-up of the master
the timing process saw, the frames late / withdrawn / unplaced; then the run's exit code, STATUS,
the holds made and the drives' states after the run.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import secrets
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def _as_master(argv: list[str]) -> None:
    """The master: ``ident-hw`` with its process held now and then (``HOLD`` s every ``HOLD_EVERY``)."""
    if os.environ.get("NO_REALTIME"):
        import dataclasses

        import ident_hw.config.to_drivers as to_drivers
        import ident_hw.experiment.session as session
        settings = to_drivers.timing_settings
        session.timing_settings = lambda bus: dataclasses.replace(settings(bus), priority=0)
    if os.environ.get("STALL_TRACE"):
        # the threads' stacks whenever the master's loop has said nothing to its timing process for
        # STALL_TRACE s (faulthandler: from a C thread, without the GIL)
        import faulthandler

        import drivers.timing as timing
        after, alive = float(os.environ["STALL_TRACE"]), timing.TimedBus.alive

        def traced(self) -> None:
            faulthandler.dump_traceback_later(after, repeat=True)
            alive(self)
        timing.TimedBus.alive = traced
    every, hold = float(os.environ["HOLD_EVERY"]), float(os.environ["HOLD"])
    usleep = ctypes.PyDLL(None).usleep

    def holds() -> None:
        while True:
            time.sleep(every)
            started = time.monotonic()
            usleep(int(hold * 1e6))
            print(f"held {time.monotonic() - started:.3f} s", file=sys.stderr, flush=True)
    threading.Thread(target=holds, daemon=True).start()
    from ident_hw.cli import main
    sys.exit(main(argv, process_exits=True))


def _config(folder: Path, hil: str) -> Path:
    sim = yaml.safe_load((ROOT / "configs" / "sim-3prrr.yaml").read_text())["sim"]
    sim["in_process"] = False
    group = f"ff11::4944:{secrets.randbits(16):x}:{secrets.randbits(16):x}"
    path = folder / f"udp-{hil}"
    path.write_text(yaml.safe_dump({"extends": str(ROOT / "configs" / hil),
                                    "bus": {"interface": "udp_multicast", "channel": group, "sync": "periodic",
                                            "bring_up_timeout": 30.0},
                                    "sim": sim, "identification": {"encoder_draws": 0}}, sort_keys=False))
    return path


def _drives_apart(pid: int, realtime: bool) -> None:
    """The emulated drives (``ident-hw sim``, process ``pid``) on the last CPU of their own; with
    ``realtime`` their threads at ``SCHED_FIFO`` 10 (below the timing process's 20): real drives
    answer a SYNC in microseconds and take no CPU of the master's PC, and an emulation starved by the
    busy loops, or one at real-time priority starving the master, would be measured instead of the
    master."""
    cpus = sorted(os.sched_getaffinity(0))
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            if len(cpus) > 1:
                os.sched_setaffinity(int(task.name), {cpus[-1]})
            if realtime:
                os.sched_setscheduler(int(task.name), os.SCHED_FIFO, os.sched_param(10))
        except (OSError, AttributeError):
            return


def run_one(hil: str, args, folder: Path) -> None:
    from drivers.recording import Recording
    config = _config(folder, hil)
    cpus = sorted(os.sched_getaffinity(0))[:args.busy] if args.busy else []
    rig = subprocess.Popen([sys.executable, "-m", "ident_hw.cli", "sim", config], stdout=subprocess.PIPE, text=True)
    busy = []
    try:
        while not rig.stdout.readline().startswith("simulated rig:"):
            if rig.poll() is not None:
                raise SystemExit(f"ident-hw sim ended: {rig.returncode}")
        _drives_apart(rig.pid, not args.no_realtime)
        busy = [subprocess.Popen([sys.executable, "-c", f"import os\nos.sched_setaffinity(0, {{{cpu}}})\nwhile True: pass"])
                for cpu in cpus]
        env = dict(os.environ, HOLD=str(args.hold), HOLD_EVERY=str(args.every),
                   **({"NO_REALTIME": "1"} if args.no_realtime else {}),
                   **({"STALL_TRACE": str(args.stall_trace)} if args.stall_trace else {}))
        started = time.monotonic()
        run = subprocess.run([sys.executable, __file__, "--as-master", "run", config, "--out", folder / "run",
                              "--no-report", "--quiet"], capture_output=True, text=True, env=env)
        wall = time.monotonic() - started
    finally:
        for proc in busy:
            proc.kill()
            proc.wait()
        rig.terminate()
        rig.wait()
    (folder / "master.stderr").write_text(run.stderr)
    holds = [float(line.split()[1]) for line in run.stderr.splitlines() if line.startswith("held ")]
    print(f"\n{hil} on udp_multicast, periodic 250 Hz, {len(cpus)} busy loop(s), master held {args.hold:g} s every "
          f"{args.every:g} s ({len(holds)} holds, longest {max(holds, default=0):.3f} s); "
          f"timing process {'normal priority' if args.no_realtime else 'real-time where granted'}; wall {wall:.0f} s")
    print(f"{'trajectory':>10} {'cycles':>12} {'incomplete':>10} {'skipped':>7} {'latest SYNC':>11} "
          f"{'latest hb':>9} {'held':>6} {'late':>5} {'withdrawn':>9} {'unplaced':>8}")
    for npz in sorted((folder / "run" / "data").glob("*.npz"), key=lambda p: p.stat().st_mtime):
        rec = Recording.load(npz)
        m, s, b = rec.metadata, rec.metadata.sync_report, rec.metadata.books
        print(f"{npz.stem:>10} {m.n_cycles:>5} of {m.n_targets:<5} {rec.n_invalid:>10} {s.sync_slots_skipped or 0:>7} "
              f"{(s.latest_sync or 0) * 1e3:>8.2f} ms {(s.latest_heartbeat or 0) * 1e3:>6.2f} ms "
              f"{s.master_longest_stall or 0:>5.2f}s {b.late_frames:>5} {b.withdrawn_cells:>9} {b.unplaced_frames:>8}")
    status = (folder / "run" / "STATUS").read_text().strip() if (folder / "run" / "STATUS").exists() else "(none)"
    drives = folder / "run" / "data" / "drives.json"
    states = json.loads(drives.read_text())["master"] if drives.exists() else {}
    print(f"exit {run.returncode}; STATUS {status[:300]}")
    print(f"drives after the run: {sorted(set(states.values()))}")
    if run.returncode not in (0, 6):
        print(run.stderr[-3000:])


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--as-master":
        _as_master(sys.argv[2:])
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", nargs="+", default=["hil-3prrr-epos2.yaml", "hil-3prrr-epos4.yaml"])
    parser.add_argument("--hold", type=float, default=1.0)
    parser.add_argument("--every", type=float, default=10.0)
    parser.add_argument("--busy", type=int, default=len(os.sched_getaffinity(0)))
    parser.add_argument("--no-realtime", action="store_true")
    parser.add_argument("--keep", metavar="DIR", help="keep each run's folder in DIR/<config>")
    parser.add_argument("--stall-trace", type=float, metavar="S", help="the master's thread stacks (in its stderr, "
                        "kept with --keep) whenever its loop said nothing to the timing process for S s")
    args = parser.parse_args()
    print(f"load before: {os.getloadavg()}")
    for hil in args.configs:
        if args.keep:
            folder = Path(args.keep) / Path(hil).stem
            folder.mkdir(parents=True, exist_ok=True)
            run_one(hil, args, folder)
            continue
        with tempfile.TemporaryDirectory() as tmp:
            run_one(hil, args, Path(tmp))
    print(f"load after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
