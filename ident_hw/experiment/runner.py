"""The campaign on the bus: the one place that wires bus, rig, drives, trajectories, recording
and identification together.

    folder = new_results_folder(config, None, "run")
    results = run_campaign(config, folder)        # raises CampaignStopped on Ctrl-C or a fault

:func:`run_campaign` brings the drives up (homes them on the simulated rig, which powers up at
the home pose; on hardware ``ident-hw home`` does that first), and for each trajectory moves
slowly to its start (unless the drives stand there already), streams it at the SYNC rate and
records it (``data/<name>.npz`` decoded, ``data/<name><raw_log>`` raw CAN log). Then it
identifies and validates (:func:`ident_hw.experiment.offline.identify`) and writes the results folder
(:func:`ident_hw.results.save_results`, then :func:`ident_hw.report.build_report`). On Ctrl-C or a
drive fault the drives are stopped and disabled by the driver, the recordings so far stay on disk, STATUS says ``partial: <why>`` and
:class:`CampaignStopped` is raised (SIGTERM and SIGHUP are Ctrl-C too under
:func:`ident_hw.experiment.interrupts.stop_on_signals`). ``data/drives.json`` holds the CiA 402
state of every drive after the run, as the master read it (and as the in-process rig holds it).
A run that ends normally is ``complete`` or ``degraded: <reasons>`` by the quality verdict.

:func:`identify_recordings` is the same ending for recordings made earlier (``ident-hw
identify``): STATUS ``complete``, ``degraded: <reasons>`` or ``failed: <why>``. The STATUS of
both is written here and nowhere else.
"""

from __future__ import annotations

import json
import sys
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator, Mapping

import can
import numpy as np
from tqdm import tqdm

from drivers.cia import SYNC_COB_ID, UNPOWERED
from drivers.epos import DriveGroup
from drivers.errors import BusOpenError, ConfigError, DriveError, NodeError
from drivers.recording import Recording
from drivers.recording_metadata import RecordingMetadata
from ident_hw.config import Config
from ident_hw.records import ImportSummary
from ident_hw.results import Results, final_status, mark_status, save_results

from .campaign_estimator import CampaignEstimator
from .interrupts import shielded, signal_name
from .offline import identify
from .plan import PlannedTrajectory, plan, setpoints, sync_period
from .session import HostSettings, Session, open_session

#: profile-position moves to a trajectory's start run at this fraction of each axis' speed limit
APPROACH_SPEED = 0.2
#: s: a hold-up of the master's process during a stream that the run's log mentions (a timing
#: process kept the drives going meanwhile)
HELD_UP = 0.25


#: CiA 402 states in which a drive's power stage is off


class CampaignStopped(Exception):
    """The campaign ended early (Ctrl-C, SIGTERM, SIGHUP or a fault); the results folder is
    marked partial.

    ``interrupted`` is True for a signal; ``cause`` is the original exception; ``drives`` the
    CiA 402 state of each drive after the stop as the master read it (``unknown (...)`` where
    it could not).
    """

    def __init__(self, folder: Path, reason: str, cause: BaseException, drives: dict[str, str] | None = None):
        super().__init__(f"{reason} (partial results in {folder})")
        self.folder, self.reason, self.cause = folder, reason, cause
        self.drives = dict(drives or {})
        self.interrupted = isinstance(cause, KeyboardInterrupt)

    def stop_message(self) -> str:
        """What the stop did, claiming only the drive states the master could read."""
        return (f"stop sent to every drive; {drives_after_stop(self.drives)}\n"
                f"recordings kept in {self.folder / 'data'}")


def drives_after_stop(master: dict[str, str]) -> str:
    """``drives disabled: a, b; FAULT: c; state unknown: d`` from the states the master read
    (``unknown (...)`` for a drive that did not answer: never claimed disabled)."""
    if not master:
        return "drive states not read"
    groups: dict[str, list[str]] = {}
    for label, state in master.items():
        key = ("state unknown" if state.startswith("unknown") else
               "drives disabled" if state in UNPOWERED else state)
        groups.setdefault(key, []).append(label)
    return "; ".join(f"{key}: {', '.join(labels)}" for key, labels in groups.items())


class _SyncCounter(can.Listener):
    """Counts the SYNC frames seen on the bus (notifier thread): the progress of a stream."""

    def __init__(self) -> None:
        self.count = 0

    def on_message_received(self, msg: can.Message) -> None:
        if msg.arbitration_id == SYNC_COB_ID and not msg.is_error_frame:
            self.count += 1


@contextmanager
def _progress(network, name: str, cycles: int, enabled: bool) -> Iterator[None]:
    """A tqdm bar of the SYNC cycles of one stream, refreshed from its own thread."""
    if not enabled:
        yield
        return
    counter = _SyncCounter()
    network.notifier.add_listener(counter)
    bar = tqdm(total=cycles, desc=f"{name:>10}", unit="cycle", file=sys.stderr, leave=True)
    done = threading.Event()

    def refresh() -> None:
        while not done.wait(0.2):
            bar.n = min(counter.count, cycles)
            bar.refresh()
    thread = threading.Thread(target=refresh, name="progress", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        bar.n = min(counter.count, cycles)
        bar.close()
        network.notifier.remove_listener(counter)


@contextmanager
def _injected_events(session: Session, name: str) -> Iterator[None]:
    """Arm the config's ``sim.fault`` and the trajectory's ``payload`` when trajectory ``name``
    starts streaming: each happens ``after`` s of simulated time into the stream
    (:meth:`drivers.sim.SimulatedRig.schedule`); the payload is dropped again at its end."""
    sim, rig = session.config.sim, session.rig
    fault = sim.fault if sim is not None and sim.fault is not None and sim.fault.trajectory == name else None
    payload = session.config.trajectory(name).payload
    if rig is None or (fault is None and payload is None):
        yield
        return
    if fault is not None:
        rig.schedule(fault.after, lambda: rig.drive(fault.node_id).emcy(fault.code))
    if payload is not None:
        rig.schedule(payload.after, lambda: rig.set_payload(payload.mass, payload.inertia))
    try:
        yield
    finally:
        rig.cancel_scheduled()
        if payload is not None:
            rig.set_payload(0.0)


def _drive_states(session: Session, group: DriveGroup) -> dict:
    """CiA 402 state of every drive: read by the master over SDO, and the in-process rig's own."""
    master = {}
    for drive in group.drives:
        try:
            master[drive.label] = drive.state
        except NodeError as exc:
            master[drive.label] = f"unknown ({exc})"
    states = {"master": master}
    if session.rig is not None:
        states["rig"] = {f"node {d.id}": d.state for d in session.rig.drives}
    return states


def stream(session: Session, group: DriveGroup, planned: PlannedTrajectory, data: Path,
           show_progress: bool, host: HostSettings = HostSettings()) -> Recording:
    """Move to the trajectory's start, stream its set-points (:func:`~ident_hw.experiment.plan.setpoints`,
    the array the campaign's check validated) at the SYNC period and record it into ``data``."""
    config, traj = session.config, planned.trajectory
    targets = setpoints(traj)
    window = np.array([a.limits.following_error for a in config.robot.actuators])
    if np.any(np.abs(group.positions() - targets[0]) > 0.5 * window):
        group.move_to(targets[0], speed_fraction=APPROACH_SPEED)
    with _progress(session.network, traj.name, len(targets), show_progress), _injected_events(session, traj.name):
        return group.run_cyclic(targets, sync_period(config), output=data / f"{traj.name}.npz",
                                raw_log=data / f"{traj.name}{config.output.raw_log}",
                                metadata=RecordingMetadata(trajectory=traj.name, config=Path(config.source).name,
                                                           current=config.current),
                                quiet=host.quiet)


def record_campaign(config: Config, data: Path, planned: list[PlannedTrajectory], recordings: dict[str, Recording],
                    states: dict, say: Callable[[str], None], show_progress: bool,
                    online: CampaignEstimator | None, host: HostSettings) -> None:
    """Bring the drives up (and home the simulated rig), stream every planned trajectory into
    ``data`` and ``recordings`` (filled as each one ends: a stop keeps those already made), then
    stop and disable the drives and put their states into ``states`` (and ``data/drives.json``),
    whether the session ended or stopped."""
    with host.pinned(), open_session(config) as session:
        group = session.drive_group()
        try:
            say(f"bringing up {len(group.drives)} drives on {config.bus.interface}:{config.bus.channel}")
            group.bring_up(timeout=config.bus.bring_up_timeout)
            if config.simulated:
                say("homing (the simulated rig powers up at the home pose)")
                group.home()
            for i, p in enumerate(planned, 1):
                say(f"[{i}/{len(planned)}] {p.describe()}")
                rec = stream(session, group, p, data, show_progress, host)
                recordings[p.config.name] = rec
                report = rec.metadata.sync_report
                skipped = report.sync_slots_skipped or 0
                held = report.master_longest_stall or 0.0
                say(f"    recorded {rec.metadata.n_cycles} cycles, {rec.n_invalid} incomplete"
                    + (f", {skipped} SYNC slots skipped (the host woke the SYNC's timer late)" if skipped else "")
                    + (f"; this process was held up to {held:.2f} s, the timing process kept the SYNC, the "
                       f"set-points and the heartbeat going" if held >= HELD_UP else ""))
                if online is not None:
                    online.update(p.config.name, rec)
        finally:
            # quick stop and disable, then the drives stop watching the master's heartbeat before
            # it ends; a signal arriving meanwhile waits for the states to be written
            with shielded():
                group.close()
                states.update(_drive_states(session, group))
                (data / "drives.json").write_text(json.dumps(states, indent=2))


def stop_reason(exc: BaseException) -> str:
    """What stopped a campaign, for its STATUS: the signal, a config error, a drive fault, else the exception."""
    if isinstance(exc, KeyboardInterrupt):
        return f"interrupted ({signal_name(exc)})"
    if isinstance(exc, ConfigError):
        return f"config error: {exc}"
    if isinstance(exc, DriveError):
        return f"drive fault: {exc}"
    return f"{type(exc).__name__}: {exc}"


def conclude(folder: Path, results: Results, report: bool) -> None:
    """STATUS from the quality verdict (``complete`` or ``degraded: <reasons>``), written before
    the results and the report, which shows it; then the results, then the report if asked."""
    mark_status(folder, final_status(results))
    save_results(folder, results)
    if report:
        from ident_hw.report import build_report  # matplotlib: imported when a report is built
        build_report(folder)


def identify_recordings(config: Config, recordings: dict[str, Recording], folder: str | Path, *,
                        log: Callable[[str], None] | None = None, report: bool = True,
                        imported: Mapping[str, ImportSummary] | None = None) -> Results:
    """Identify offline from recordings already read (``ident-hw identify``) into ``folder``,
    whose STATUS ends as a run's does (:func:`conclude`), or ``failed: <why>`` (:func:`stop_reason`)
    if anything, a signal included, stops it; the exception is raised again. ``imported``: how the
    recordings made elsewhere were read."""
    folder = Path(folder)
    try:
        results = identify(config, recordings, progress=log, imported=imported)
        conclude(folder, results, report)
    except BaseException as exc:
        mark_status(folder, f"failed: {stop_reason(exc)}")
        raise
    return results


def run_campaign(config: Config, folder: str | Path, *, show_progress: bool = True,
                 log: Callable[[str], None] | None = None,
                 online: CampaignEstimator | None = None,
                 planned: list[PlannedTrajectory] | None = None,
                 host: HostSettings = HostSettings(), report: bool = True) -> Results:
    """Record every trajectory of ``config`` on its bus, identify, validate, save into ``folder``.

    Args:
        config: a config whose :func:`ident_hw.experiment.plan.check_campaign` passed.
        folder: a results folder from :func:`ident_hw.experiment.folders.new_results_folder`.
        show_progress: tqdm bars on stderr (the caller turns them off for --quiet / non-TTY).
        log: where progress messages go (``None``: nowhere).
        online: an SVD-DLS estimator fed with each recording as it is made; its trace is saved.
        planned: the config's :func:`~ident_hw.experiment.plan.plan` with ``online=True`` if the
            caller has made it (for its checks); planned here otherwise. Without ``online``, its
            ``online_only`` trajectories are left out.
        host: how the process hosts the session (:class:`HostSettings`: the command line's choice).
        report: build the report (plots, report.html) after saving the results.

    Raises:
        CampaignStopped: Ctrl-C or a fault; the folder is marked ``partial: <reason>``.
    """
    folder = Path(folder)
    say = log or (lambda _message: None)
    if planned is None:
        planned = plan(config, online=online is not None)
    elif online is None:
        planned = [p for p in planned if not p.config.online_only]
    recordings: dict[str, Recording] = {}
    states: dict = {}
    try:
        record_campaign(config, folder / "data", planned, recordings, states, say, show_progress, online, host)
        mark_status(folder, "identifying")
        results = identify(config, recordings, progress=say)
        if online is not None:
            results.online = online.trace(results.base_fit)
        conclude(folder, results, report)
    except BusOpenError as exc:
        mark_status(folder, f"failed: {exc}; nothing moved, nothing recorded")
        raise
    except BaseException as exc:
        reason = stop_reason(exc)
        master = states.get("master", {})
        mark_status(folder, f"partial: {reason}; complete recordings: {', '.join(recordings) or 'none'}"
                    + (f"; drives after the stop: {drives_after_stop(master)}" if master else ""))
        if isinstance(exc, (KeyboardInterrupt, DriveError)):
            raise CampaignStopped(folder, reason, exc, master) from exc
        raise
    return results
