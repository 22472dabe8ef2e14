"""``ident-hw``: identify the dynamic parameters of the 3PRRR from one YAML config.

A thin layer over :mod:`ident_hw.config`, :mod:`ident_hw.experiment` and :mod:`ident_hw.report`;
nothing imports it. Every command runs under :func:`ident_hw.experiment.interrupts.stop_on_signals`
(SIGTERM and SIGHUP are Ctrl-C) and ends with one exit code per class of outcome,
:class:`Exit` (documented in the README): no traceback reaches the user.
"""

from __future__ import annotations

import argparse
import enum
import os
import sys
from pathlib import Path


class Exit(enum.IntEnum):
    """The exit codes of ``ident-hw``, one per class of outcome."""

    OK = 0            #: done; a run or identify passed the quality verdict
    FAILURE = 1       #: any other error (the message says what; an unexpected one is flagged as a bug)
    CONFIG = 2        #: the command line or the config is wrong, or the config cannot run (nothing moved)
    BUS = 3           #: the CAN bus cannot be opened or reported errors
    DRIVE_FAULT = 4   #: a drive faulted, refused a command or stopped answering
    DATA = 5          #: a recording or results folder is unreadable, incomplete or does not match the config
    DEGRADED = 6      #: finished, but the quality verdict failed (STATUS degraded, with the reasons)
    INTERRUPTED = 130  #: Ctrl-C, SIGTERM or SIGHUP (motion stopped, data kept, STATUS partial)


def _load(path: str):
    from ident_hw.config import load_config
    return load_config(path)


def cmd_check(args) -> int:
    """Validate the config and every trajectory; move nothing, open no bus. A config of
    recordings made elsewhere only (``recorded`` trajectories): read every file as ``identify``
    would and say what it holds."""
    from ident_hw.experiment.plan import check_campaign, plan
    config = _load(args.config)
    print(f"{args.config}: config ok")
    if config.trajectories and all(t.recorded for t in config.trajectories):
        return _check_recorded(config)
    planned = plan(config, online=True)
    for p in planned:
        print("  " + p.describe() + ("  (ident-hw online only)" if p.config.online_only else ""))
    if config.bus is not None:
        from ident_hw.experiment.session import watchdog_lines
        where = "simulated rig" if config.simulated else "HARDWARE (motion needs --arm)"
        print(f"bus: {config.bus.interface} {config.bus.channel} at {config.bus.sync_rate:g} Hz SYNC: {where}")
        print("\n".join(watchdog_lines(config)))
    problems = [m for m in check_campaign(config, planned) if m not in {p.describe() for p in planned}]
    for message in problems:
        print(message)
    if problems or not all(p.ok for p in planned):
        print("NOT runnable: fix the items above")
        return Exit.CONFIG
    print("everything would run")
    return Exit.OK


def _check_recorded(config) -> int:
    """``check`` of a config of recordings made elsewhere: each file read, what it holds."""
    from drivers.errors import RecordingError
    from ident_hw.experiment.external import read_external
    failed = False
    for tcfg in config.trajectories:
        try:
            summary = read_external(config, tcfg).summary
        except RecordingError as exc:
            print(f"  {tcfg.name}: cannot read: {exc}")
            failed = True
            continue
        print(f"  {tcfg.name}: {tcfg.path}")
        print("\n".join(f"    {line}" for line in summary.describe()))
    if failed:
        print("NOT identifiable: fix the items above")
        return Exit.CONFIG
    print(f"recordings made elsewhere: nothing to move; identify them with `ident-hw identify {config.source}`")
    return Exit.OK


def cmd_identify(args) -> int:
    """Identify offline from recordings (decoded .npz or raw CAN logs, or a results folder's) into
    a results folder.

    Every recording is read and checked against the config before the folder is made; the
    folder's STATUS ends ``complete``, ``degraded: <reasons>`` or ``failed: <why>``."""
    from ident_hw.config import ConfigError
    from ident_hw.experiment.folders import new_results_folder
    from ident_hw.experiment.recordings import gather_recordings, require_trajectories
    from ident_hw.experiment.runner import identify_recordings
    from ident_hw.report import summary_lines
    config = _load(args.config)
    if config.identification is None:
        raise ConfigError("identification: missing section (the steps to run on the recordings)",
                          file=config.source)
    recordings, imported, notes = gather_recordings(config, args.data, layout=args.pdo_layout)
    for note in notes:
        print(note, file=sys.stderr)
    require_trajectories(config, recordings)
    folder = new_results_folder(config, args.out, "identify")
    results = identify_recordings(config, recordings, folder, log=_logger(args), report=not args.no_report,
                                  imported=imported)
    print("\n".join(summary_lines(folder)))
    print(f"results: {folder}" + ("" if args.no_report else f"  (report: {folder / 'report.html'})"))
    return Exit.OK if results.passed else Exit.DEGRADED


def cmd_report(args) -> int:
    """Rebuild metrics, plots, report.html and results.mat of a results folder."""
    from ident_hw.report import build_report
    try:
        page = build_report(args.results)
    except (OSError, ValueError, KeyError) as exc:
        print(f"data error: {args.results}: cannot rebuild the report: {exc}", file=sys.stderr)
        return Exit.DATA
    print(page)
    return Exit.OK


def cmd_export(args) -> int:
    """Write the robot's description file with the consistent parameters of a results folder."""
    from ident_hw.experiment.export import export_description
    print(export_description(args.results, args.to, for_mujoco=args.for_mujoco))
    return Exit.OK


def cmd_study(args) -> int:
    """A Monte-Carlo study: ``--runs`` campaigns of a simulated config, each with its own noise seed."""
    import time

    from ident_hw.experiment.study import StudyError, run_study
    from ident_hw.report.study import study_lines, write_study_report
    config = _load(args.config)
    folder = Path(args.out) if args.out else Path(config.output.dir) / f"study-{Path(args.config).stem}"
    print(f"study folder: {folder}", file=sys.stderr)
    bar, started, ran_here = None, time.monotonic(), 0
    if _progress_bars(args):
        from tqdm import tqdm
        bar = tqdm(total=args.runs, unit="run", desc="study", file=sys.stderr)

    def progress(outcome, done: int, runs: int) -> None:
        nonlocal ran_here
        ran_here += 1
        if bar is not None:
            bar.n = done
            bar.refresh()
            return
        if args.quiet:
            return
        rate = ran_here / (time.monotonic() - started)
        print(f"run {outcome.index} (seed {outcome.seed}): {outcome.status.split(':')[0]} in "
              f"{outcome.wall_seconds:.0f} s; {done} of {runs} done, about {(runs - done) / rate / 60:.1f} min left",
              file=sys.stderr, flush=True)
    try:
        study = run_study(args.config, folder, args.runs, workers=args.workers, scheduler=args.scheduler,
                          perturb=args.perturb, on_outcome=progress)
    except StudyError as exc:
        print(f"config error: {exc}", file=sys.stderr)
        return Exit.CONFIG
    finally:
        if bar is not None:
            bar.close()
    print("\n".join(study_lines(study)))
    print(f"study: {folder}  (report: {write_study_report(study)})")
    return Exit.OK if not study.failed else Exit.DEGRADED


def cmd_run(args) -> int:
    """The campaign: checks, then (simulated rig, or hardware with --arm) motion and identification."""
    from drivers.errors import BusOpenError
    from ident_hw.experiment.plan import check_campaign, plan
    config = _load(args.config)
    planned = plan(config, online=True)
    problems = check_campaign(config, planned)
    if problems:
        print("checks failed, nothing moved:\n  " + "\n  ".join(problems), file=sys.stderr)
        return Exit.CONFIG
    if _needs_arm(config, args, "checks passed; motion"):
        return Exit.CONFIG
    from ident_hw.experiment.campaign_estimator import CampaignEstimator
    from ident_hw.experiment.folders import discard_unused, new_results_folder
    from ident_hw.experiment.runner import CampaignStopped, run_campaign
    from ident_hw.experiment.session import HostSettings
    from ident_hw.report import online_lines, summary_lines
    folder = new_results_folder(config, args.out, args.command)
    print(f"results folder: {folder}", file=sys.stderr)
    online = None
    if args.command == "online":
        online = CampaignEstimator(config, show=print)
    elif config.identification.online.in_run:
        online = CampaignEstimator(config)
    try:
        results = run_campaign(config, folder, show_progress=_progress_bars(args), log=_logger(args), online=online,
                               planned=planned, host=HostSettings.for_command(config),
                               report=not args.no_report)
    except BusOpenError:
        if discard_unused(folder):
            print(f"nothing moved, nothing recorded: {folder} removed", file=sys.stderr)
        raise
    except CampaignStopped as exc:
        print(f"STOPPED: {exc.reason}\n{exc.stop_message()}", file=sys.stderr)
        return Exit.INTERRUPTED if exc.interrupted else exit_code(exc.cause)
    print("\n".join(summary_lines(folder)))
    if results.online is not None:
        print("\n".join(online_lines(results.online)))
    print(f"results: {folder}" + ("" if args.no_report else f"  (report: {folder / 'report.html'})"))
    return Exit.OK if results.passed else Exit.DEGRADED


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
        return Exit.CONFIG
    rig = simulated_rig(config)
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, lambda *_: done.set())
    with rig:
        ids = [a.node_id for a in config.robot.actuators]
        print(f"simulated rig: nodes {ids} on {config.bus.interface}:{config.bus.channel}; Ctrl-C stops",
              flush=True)
        while not done.wait(0.5):
            pass
    print("simulated rig stopped", flush=True)
    return Exit.OK


def cmd_scan(args) -> int:
    """List the nodes on the bus and compare them with the config."""
    from ident_hw.experiment.inspection import compare, read_node, scan
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
    return Exit.OK if not problems else Exit.CONFIG


def cmd_monitor(args) -> int:
    """Live read-only table of every configured drive."""
    import time

    from ident_hw.experiment.inspection import format_snapshot, snapshot
    from ident_hw.experiment.session import open_session
    config = _load(args.config)
    with open_session(config) as session:
        group = session.drive_group(uses=("bring_up",))
        end = time.monotonic() + (args.duration if args.duration is not None else float("inf"))
        tty = sys.stdout.isatty() and not args.once
        while True:
            table = format_snapshot(snapshot(group))
            print(("\x1b[H\x1b[2J" if tty else "") + time.strftime("%H:%M:%S ") + "(read-only)\n" + table,
                  flush=True)
            if args.once or time.monotonic() >= end:
                return Exit.OK
            time.sleep(args.interval)


def cmd_home(args) -> int:
    """Bring the drives up and home them (CiA 402 homing, methods from the config)."""
    from ident_hw.experiment.session import HostSettings, open_session
    from ident_hw.model.interface import POSITION_UNITS
    config = _load(args.config)
    if config.bus is None:
        print(f"config error: {config.source}: bus: missing section", file=sys.stderr)
        return Exit.CONFIG
    if _needs_arm(config, args, "homing"):
        return Exit.CONFIG
    with HostSettings.for_command(config).pinned(), open_session(config) as session:
        with session.drive_group(uses=("bring_up", "home")) as group:
            group.bring_up(timeout=config.bus.bring_up_timeout)
            group.home()
            positions = group.positions()
    for act, q in zip(config.robot.actuators, positions):
        print(f"  {act.name}: homed at {q:.6f} {POSITION_UNITS[act.kind]}")
    print("homed; drives disabled")
    return Exit.OK


def _progress_bars(args) -> bool:
    """tqdm bars only on a terminal and without --quiet."""
    return not args.quiet and sys.stderr.isatty()


def _logger(args):
    return None if args.quiet else (lambda message: print(message, file=sys.stderr, flush=True))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ident-hw",
        description="Dynamic parameter identification of a robot (the 3PRRR, the Delta, or any from its "
                    "description file) straight from its Maxon EPOS2/EPOS4 drives over CANopen, from one YAML "
                    "config.",
        epilog="Start with: ident-hw check configs/sim-3prrr.yaml; then ident-hw run configs/sim-3prrr.yaml")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command(name, func, help_text):
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(func=func)
        return p

    _add_campaign_commands(command)
    _add_offline_commands(command)
    _add_rig_commands(command)
    _add_results_commands(command)
    return parser


def _at_least(lowest: int):
    """An argparse type: a whole number of at least ``lowest`` (refused on the command line, before
    anything is printed or made)."""
    def whole(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
        if value < lowest:
            raise argparse.ArgumentTypeError(f"must be at least {lowest}, got {value}")
        return value
    return whole


def _add_campaign_commands(command) -> None:
    """The commands that check a config or run campaigns (on the rig or simulated): ``check``, ``run``,
    ``online``, ``study``. ``command(name, func, help)`` adds a subparser and returns it."""
    p = command("check", cmd_check, "validate the config and every trajectory (feasibility); moves nothing")
    p.add_argument("config", help="YAML config, e.g. configs/sim-3prrr.yaml")

    p = command("run", cmd_run, "run the campaign: move, record, identify, validate, write a results folder")
    p.add_argument("config", help="YAML config")
    p.add_argument("--arm", action="store_true", help="allow motion on a bus that is not the simulated rig's")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--out", metavar="DIR", help="results folder (default: output.dir/run-<time>)")
    p.add_argument("--no-report", action="store_true", help="no plots and no report.html (`ident-hw report DIR` "
                   "builds them later)")

    p = command("online", cmd_run, "a run with the SVD-DLS estimator fed as the recordings come in: "
                "its table is printed after each trajectory and its trace saved")
    p.add_argument("config", help="YAML config")
    p.add_argument("--arm", action="store_true", help="allow motion on a bus that is not the simulated rig's")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--out", metavar="DIR", help="results folder (default: output.dir/online-<time>)")
    p.add_argument("--no-report", action="store_true", help="no plots and no report.html")

    p = command("study", cmd_study, "a Monte-Carlo study: --runs campaigns of a simulated config, each with "
                "its own noise seed; per parameter the errors against the reported sigma (coverage, bias)")
    p.add_argument("config", help="YAML config of a simulated rig (in process, lockstep)")
    p.add_argument("--runs", type=_at_least(1), required=True, metavar="N",
                   help="campaigns in the study (run i: seed sim.seed + i)")
    p.add_argument("--out", metavar="DIR", help="study folder (default: output.dir/study-<config name>); "
                   "a folder holding this config's study is continued")
    p.add_argument("--workers", type=_at_least(0), metavar="K", help="worker processes of a local Dask cluster "
                   "(default: this machine's CPUs); 0: every run in this process")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on the workers of this Dask scheduler instead")
    p.add_argument("--perturb", type=float, default=0.0, metavar="REL",
                   help="each run but run 0 on a true robot of its own: every body's parameters scaled by a "
                        "factor exp(REL * N(0, 1)) drawn from the run's seed (sim.perturb; default 0)")
    p.add_argument("--quiet", action="store_true", help="no progress")


def _add_offline_commands(command) -> None:
    """``identify``: identification from recordings, without a bus (``command`` as in
    :func:`_add_campaign_commands`)."""
    p = command("identify", cmd_identify, "identify offline from recordings (decoded .npz or raw .log/.asc/.blf), "
                "a results folder's recordings, or recordings made elsewhere (CSV)")
    p.add_argument("config", help="YAML config of the recorded run (its results folder's config.yaml is the run's own)")
    p.add_argument("data", nargs="*", help="recording files (the file stem names the trajectory), a results folder "
                   "(the recordings of its data/), or NAME=PATH: PATH in the place of trajectory NAME; the config's "
                   "recorded trajectories not given are read from their own files")
    p.add_argument("--out", metavar="DIR", help="results folder (default: output.dir/identify-<time>)")
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    p.add_argument("--no-report", action="store_true", help="no plots and no report.html (`ident-hw report DIR` "
                   "builds them later)")
    p.add_argument("--pdo-layout", metavar="SOURCE", help="the PDO layout to decode a raw log without its sidecar "
                   "(<log>.json) with: 'config' (the one this config maps, with its bus.current), a sidecar "
                   "<run>.log.json or a decoded <recording>.npz of a run with the same drives; without it such a log "
                   "is refused")


def _add_rig_commands(command) -> None:
    """The commands that serve or talk to a bus: ``sim``, ``scan``, ``monitor``, ``home``
    (``command`` as in :func:`_add_campaign_commands`)."""
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


def _add_results_commands(command) -> None:
    """The commands on a results folder: ``report``, ``export`` (``command`` as in
    :func:`_add_campaign_commands`)."""
    p = command("report", cmd_report, "rebuild the report of a results folder")
    p.add_argument("results", help="results folder")

    p = command("export", cmd_export, "write the robot's description file (MJCF or URDF, as it came) with the "
                "physically consistent parameters of a results folder: inertias, friction, rotor inertia")
    p.add_argument("results", help="results folder of a described robot")
    p.add_argument("--to", required=True, metavar="FILE", help="the file to write (.xml/.mjcf or .urdf)")
    p.add_argument("--for-mujoco", action="store_true", help="refuse bodies MuJoCo would refuse (massless moving "
                   "bodies, point masses, zero principal moments) instead of writing them for pinocchio")


def exit_code(exc: BaseException) -> int:
    """The :class:`Exit` class of an exception."""
    from drivers.errors import BusError, BusOpenError, ConfigError, DriveError, RecordingError
    if isinstance(exc, KeyboardInterrupt):
        return Exit.INTERRUPTED
    if isinstance(exc, (BusOpenError, BusError)):
        return Exit.BUS
    # the config file's errors (ident_hw.config.ConfigError) are drive-layer ConfigErrors too
    if isinstance(exc, (ConfigError, FileExistsError)):    # FileExistsError: --out holds results already
        return Exit.CONFIG
    if isinstance(exc, RecordingError):
        return Exit.DATA
    if isinstance(exc, DriveError):
        return Exit.DRIVE_FAULT
    return Exit.FAILURE


#: what the message of each exit class starts with
_LABELS = {Exit.CONFIG: "config error", Exit.BUS: "bus error", Exit.DRIVE_FAULT: "drive fault",
           Exit.DATA: "data error", Exit.FAILURE: "error"}


def main(argv: list[str] | None = None, process_exits: bool = False) -> int:
    """Run the command of ``argv`` (default: the process's arguments); its exit code.
    ``process_exits``: the process ends when this returns (:func:`script`), so the signal
    handlers stay (a second Ctrl-C while it exits is reported, not a kill)."""
    from ident_hw.experiment.interrupts import signal_name, stop_on_signals
    args = build_parser().parse_args(argv)
    with stop_on_signals(restore=not process_exits):
        try:
            return int(args.func(args))
        except KeyboardInterrupt as exc:
            print(f"interrupted ({signal_name(exc)})", file=sys.stderr)
            return Exit.INTERRUPTED
        except Exception as exc:
            code = exit_code(exc)
            if code == Exit.FAILURE and not isinstance(exc, (ValueError, OSError)):
                print(f"internal error (a bug, please report it): {type(exc).__name__}: {exc}", file=sys.stderr)
                if os.environ.get("IDENT_HW_TRACEBACK"):
                    raise
            else:
                print(f"{_LABELS[code]}: {exc}", file=sys.stderr)
            return code


def script() -> None:
    """The installed ``ident-hw`` command (and ``python -m ident_hw.cli``): :func:`main`'s exit
    code is the process's. After a stop by a signal, further signals are ignored while the
    interpreter exits: it puts the default handlers back on its way out, and a second Ctrl-C
    then would end the process with that signal's status instead of :attr:`Exit.INTERRUPTED`."""
    import signal

    from ident_hw.experiment.interrupts import SIGNAL_NAMES
    code = main(process_exits=True)
    if code == Exit.INTERRUPTED:
        for sig in SIGNAL_NAMES:
            signal.signal(sig, signal.SIG_IGN)
    sys.exit(code)


if __name__ == "__main__":
    script()
