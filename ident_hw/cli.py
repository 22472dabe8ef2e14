"""``ident-hw``: identify the dynamic parameters of the 3PRRR from one YAML config.

A thin layer over :mod:`ident_hw.config`, :mod:`ident_hw.experiment` and :mod:`ident_hw.report`;
nothing imports it. Exit codes: 0 success, 1 failure (bad data, infeasible trajectory, fault),
2 bad command line or config, 130 interrupted.
"""

from __future__ import annotations

import argparse
import sys

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def _load(path: str):
    from ident_hw.config import load_config
    return load_config(path)


def cmd_check(args) -> int:
    """Validate the config and every trajectory; move nothing, open no bus."""
    from ident_hw.experiment.plan import plan
    config = _load(args.config)
    print(f"{args.config}: config ok")
    ok = True
    if config.bus is None:
        print("bus: missing section (needed to run)")
        ok = False
    if not config.trajectories:
        print("trajectories: none defined")
        ok = False
    for planned in plan(config):
        print("  " + planned.describe())
        ok &= planned.ok
    if config.bus is not None:
        where = "simulated rig" if config.simulated else "HARDWARE (motion needs --arm)"
        print(f"bus: {config.bus.interface} {config.bus.channel} at {config.bus.sync_rate:g} Hz SYNC: {where}")
    print("everything would run" if ok else "NOT runnable: fix the items above")
    return EXIT_OK if ok else EXIT_FAIL


def cmd_identify(args) -> int:
    """Identify offline from recordings (decoded .npz or raw CAN logs) into a results folder."""
    from ident_hw.experiment.offline import identify, load_recording
    from ident_hw.experiment.results import new_results_folder
    from ident_hw.report import mark_status, save_results, summary_lines
    config = _load(args.config)
    recordings = dict(load_recording(path, config) for path in args.data)
    folder = new_results_folder(config, args.out, "identify")
    results = identify(config, recordings, progress=_logger(args))
    mark_status(folder, "complete")
    page = save_results(folder, results)
    print("\n".join(summary_lines(folder)))
    print(f"results: {folder}  (report: {page})")
    return EXIT_OK


def cmd_report(args) -> int:
    """Rebuild metrics, plots, report.html and results.mat of a results folder."""
    from ident_hw.report import build_report
    print(build_report(args.results))
    return EXIT_OK


def cmd_run(args) -> int:
    """The campaign: checks, then (simulated rig, or hardware with --arm) motion and identification."""
    from ident_hw.experiment.plan import check_campaign
    config = _load(args.config)
    problems = check_campaign(config)
    if problems:
        print("checks failed, nothing moved:\n  " + "\n  ".join(problems), file=sys.stderr)
        return EXIT_FAIL
    if _needs_arm(config, args, "checks passed; motion"):
        return EXIT_FAIL
    from ident_hw.experiment.online import CampaignEstimator
    from ident_hw.experiment.results import new_results_folder
    from ident_hw.experiment.runner import CampaignStopped, run_campaign
    from ident_hw.report import summary_lines
    folder = new_results_folder(config, args.out, args.command)
    print(f"results folder: {folder}", file=sys.stderr)
    online = CampaignEstimator(config, show=print) if args.command == "online" else None
    try:
        run_campaign(config, folder, show_progress=_progress_bars(args), log=_logger(args), online=online)
    except CampaignStopped as exc:
        print(f"STOPPED: {exc.reason}\nmotion stopped, drives disabled; recordings kept in {folder / 'data'}",
              file=sys.stderr)
        return EXIT_INTERRUPTED if exc.interrupted else EXIT_FAIL
    print("\n".join(summary_lines(folder)))
    print(f"results: {folder}  (report: {folder / 'report.html'})")
    return EXIT_OK


def _needs_arm(config, args, what: str) -> bool:
    """True (and says so) when ``what`` would move hardware without --arm."""
    if config.simulated or args.arm:
        return False
    print(f"{config.bus.interface}:{config.bus.channel} is not the simulated rig's bus: "
          f"{what} needs --arm", file=sys.stderr)
    return True


def cmd_sim(args) -> int:
    """Serve the config's simulated rig on its bus until Ctrl-C / SIGTERM."""
    import signal
    import threading

    from ident_hw.experiment.session import simulated_rig
    config = _load(args.config)
    if config.bus is None or config.bus.interface == "virtual":
        print("a python-can 'virtual' bus only reaches its own process: `ident-hw run` of this config "
              "starts the rig itself; `sim` is for a bus shared between processes (e.g. vcan0)", file=sys.stderr)
        return EXIT_USAGE
    rig = simulated_rig(config)
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    with rig:
        ids = [a.node_id for a in config.robot.actuators]
        print(f"simulated rig: nodes {ids} on {config.bus.interface}:{config.bus.channel}; Ctrl-C stops",
              flush=True)
        while not done.wait(0.5):
            pass
    print("simulated rig stopped", flush=True)
    return EXIT_OK


def cmd_scan(args) -> int:
    """List the nodes on the bus and compare them with the config."""
    from ident_hw.experiment.inspect import compare, read_node, scan
    from ident_hw.experiment.session import open_session
    config = _load(args.config)
    with open_session(config) as session:
        heard = scan(session.network, args.wait)
        found = {i: read_node(session.network, i, state, sdo_timeout=config.bus.sdo_timeout)
                 for i, state in heard.items()}
    print(f"{len(found)} node(s) on {config.bus.interface}:{config.bus.channel}")
    for info in found.values():
        print("  " + info.describe())
    problems = compare(config, found)
    print("matches the config" if not problems else "differs from the config:\n  " + "\n  ".join(problems))
    return EXIT_OK if not problems else EXIT_FAIL


def cmd_monitor(args) -> int:
    """Live read-only table of every configured drive."""
    import time

    from ident_hw.experiment.inspect import format_snapshot, snapshot
    from ident_hw.experiment.session import open_session
    config = _load(args.config)
    with open_session(config) as session:
        group = session.drive_group()
        end = time.monotonic() + (args.duration if args.duration is not None else float("inf"))
        tty = sys.stdout.isatty() and not args.once
        while True:
            table = format_snapshot(snapshot(group))
            print(("\x1b[H\x1b[2J" if tty else "") + time.strftime("%H:%M:%S ") + "(read-only)\n" + table,
                  flush=True)
            if args.once or time.monotonic() >= end:
                return EXIT_OK
            time.sleep(args.interval)


def cmd_home(args) -> int:
    """Bring the drives up and home them (CiA 402 homing, methods from the config)."""
    from ident_hw.experiment.session import open_session
    config = _load(args.config)
    if config.bus is None:
        print(f"{config.source}: bus: missing section", file=sys.stderr)
        return EXIT_USAGE
    if _needs_arm(config, args, "homing"):
        return EXIT_FAIL
    with open_session(config) as session:
        with session.drive_group() as group:
            group.bring_up(timeout=config.bus.bring_up_timeout)
            group.home()
            positions = group.positions()
    for act, q in zip(config.robot.actuators, positions):
        print(f"  {act.name}: homed at {q:.6f} {'rad' if act.kind == 'revolute' else 'm'}")
    print("homed; drives disabled")
    return EXIT_OK


def _progress_bars(args) -> bool:
    """tqdm bars only on a terminal and without --quiet."""
    return not args.quiet and sys.stderr.isatty()


def _logger(args):
    return None if args.quiet else (lambda message: print(message, file=sys.stderr, flush=True))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ident-hw",
        description="Dynamic parameter identification of a 3PRRR planar parallel robot "
                    "(Maxon EPOS2/EPOS4 drives over CANopen), from one YAML config.",
        epilog="Start with: ident-hw check configs/sim-3prrr.yaml; then ident-hw run configs/sim-3prrr.yaml")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command(name, func, help_text):
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(func=func)
        return p

    p = command("check", cmd_check, "validate the config and every trajectory (feasibility); moves nothing")
    p.add_argument("config", help="YAML config, e.g. configs/sim-3prrr.yaml")

    p = command("run", cmd_run, "run the campaign: move, record, identify, validate, write a results folder")
    p.add_argument("config", help="YAML config")
    p.add_argument("--arm", action="store_true", help="allow motion on a bus that is not the simulated rig's")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--out", metavar="DIR", help="results folder (default: output.dir/run-<time>)")

    p = command("online", cmd_run, "a run with the SVD-DLS estimator fed as the recordings come in: "
                "its table is printed after each trajectory and its trace saved")
    p.add_argument("config", help="YAML config")
    p.add_argument("--arm", action="store_true", help="allow motion on a bus that is not the simulated rig's")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--out", metavar="DIR", help="results folder (default: output.dir/online-<time>)")

    p = command("identify", cmd_identify, "identify offline from recordings (decoded .npz or raw .log/.asc/.blf)")
    p.add_argument("config", help="YAML config of the recorded run")
    p.add_argument("data", nargs="+", help="recording files; the file stem names the trajectory")
    p.add_argument("--out", metavar="DIR", help="results folder (default: output.dir/identify-<time>)")
    p.add_argument("--quiet", action="store_true", help="no progress messages")

    p = command("sim", cmd_sim, "serve the config's simulated rig on its bus (e.g. vcan0) until Ctrl-C")
    p.add_argument("config", help="YAML config with a sim section")

    p = command("scan", cmd_scan, "list the nodes on the bus (identity, firmware, NMT and CiA 402 state) "
                "and compare them with the config")
    p.add_argument("config", help="YAML config")
    p.add_argument("--wait", type=float, default=1.0, metavar="S", help="s to collect answers (default 1)")

    p = command("monitor", cmd_monitor, "live read-only view of every drive (state, position, velocity, "
                "current, error)")
    p.add_argument("config", help="YAML config")
    p.add_argument("--once", action="store_true", help="print one table and exit")
    p.add_argument("--duration", type=float, metavar="S", help="exit after S seconds")
    p.add_argument("--interval", type=float, default=0.5, metavar="S", help="refresh period (default 0.5 s)")

    p = command("home", cmd_home, "bring the drives up and home them (needed before the first run on hardware)")
    p.add_argument("config", help="YAML config")
    p.add_argument("--arm", action="store_true", help="allow motion on a bus that is not the simulated rig's")

    p = command("report", cmd_report, "rebuild the report of a results folder")
    p.add_argument("results", help="results folder")
    return parser


def main(argv: list[str] | None = None) -> int:
    from ident_hw.config import ConfigError
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ConfigError as exc:
        print(f"config error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_FAIL


if __name__ == "__main__":
    sys.exit(main())
