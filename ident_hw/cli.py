"""``ident-hw``: identify the dynamic parameters of the 3PRRR from one YAML config.

A thin layer over :mod:`ident_hw.config`, :mod:`ident_hw.experiment` and :mod:`ident_hw.report`;
nothing imports it. Exit codes: 0 success, 1 failure (bad data, infeasible trajectory, fault),
2 bad command line or config, 130 interrupted.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

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
    if not config.simulated and not args.arm:
        print(f"checks passed. {config.bus.interface}:{config.bus.channel} is not the simulated rig's bus: "
              "nothing moves without --arm", file=sys.stderr)
        return EXIT_FAIL
    from ident_hw.experiment.results import new_results_folder
    from ident_hw.experiment.runner import CampaignStopped, run_campaign
    from ident_hw.report import summary_lines
    folder = new_results_folder(config, args.out, "run")
    print(f"results folder: {folder}", file=sys.stderr)
    try:
        run_campaign(config, folder, show_progress=_progress_bars(args), log=_logger(args))
    except CampaignStopped as exc:
        print(f"STOPPED: {exc.reason}\nmotion stopped, drives disabled; recordings kept in {folder / 'data'}",
              file=sys.stderr)
        return EXIT_INTERRUPTED if exc.interrupted else EXIT_FAIL
    print("\n".join(summary_lines(folder)))
    print(f"results: {folder}  (report: {folder / 'report.html'})")
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

    p = command("identify", cmd_identify, "identify offline from recordings (decoded .npz or raw .log/.asc/.blf)")
    p.add_argument("config", help="YAML config of the recorded run")
    p.add_argument("data", nargs="+", help="recording files; the file stem names the trajectory")
    p.add_argument("--out", metavar="DIR", help="results folder (default: output.dir/identify-<time>)")
    p.add_argument("--quiet", action="store_true", help="no progress messages")

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
