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

import logging
import threading
from collections.abc import Generator, Iterator, Mapping
from contextlib import closing, contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import can
import numpy as np

from drivers.cia import SYNC_COB_ID, UNPOWERED
from drivers.epos import DriveGroup
from drivers.errors import BusOpenError, ConfigError, DriveError, NodeError
from drivers.recording import Recording
from drivers.recording_metadata import RecordingMetadata
from ident_hw.config import Config, PayloadConfig, SimFaultConfig
from ident_hw.progress import report_progress
from ident_hw.records import ImportSummary
from ident_hw.results import Results, final_status, mark_status, save_results
from ident_hw.storage import NONE, read_file, stored, write_file

from .campaign_estimator import CampaignEstimator
from .interrupts import shielded, signal_name
from .offline import identify
from .plan import PlannedTrajectory, plan, setpoints, sync_period
from .session import HostSettings, Session, open_session

logger = logging.getLogger(__name__)

#: profile-position moves to a trajectory's start run at this fraction of each axis' speed limit
APPROACH_SPEED = 0.2
#: where a run keeps its drives' states after the stop, in its data folder
DRIVES_FILE = "drives.json"
#: s: a hold-up of the master's process during a stream that the run's log mentions (a timing
#: process kept the drives going meanwhile)
HELD_UP = 0.25


class CampaignStopped(Exception):
    """The campaign ended early (Ctrl-C, SIGTERM, SIGHUP or a fault); the results folder is
    marked partial.

    ``interrupted`` is True for a signal; ``cause`` is the original exception; ``drives`` the
    CiA 402 state of each drive after the stop as the master read it (``unknown (...)`` where
    it could not).
    """

    def __init__(self, folder: Path, reason: str, cause: BaseException, drives: Mapping[str, str] | None = None):
        super().__init__(f"{reason} (partial results in {folder})")
        self.folder, self.reason, self.cause = folder, reason, cause
        self.drives = dict(drives or {})
        self.interrupted = isinstance(cause, KeyboardInterrupt)

    def stop_message(self) -> str:
        """What the stop did, claiming only the drive states the master could read."""
        return (f"stop sent to every drive; {drives_after_stop(self.drives)}\n"
                f"recordings kept in {self.folder / 'data'}")


def drives_after_stop(master: Mapping[str, str]) -> str:
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


@dataclass(frozen=True)
class DriveStates:
    """``data/drives.json``: the CiA 402 state of every drive after the run, as the master read it
    over SDO (``master``: by drive label; ``unknown (...)`` where it did not answer) and, on the
    in-process simulated rig, as the rig holds it (``rig``: by node)."""

    master: Mapping[str, str] = field(default_factory=dict)
    rig: Mapping[str, str] | None = field(default=None, metadata=stored(NONE))


def read_drive_states(data: Path) -> DriveStates | None:
    """The drives' states a run left in its data folder ``data``; None when it wrote none."""
    path = data / DRIVES_FILE
    try:
        return read_file(DriveStates, path) if path.is_file() else None
    except ValueError:
        return None


@dataclass(frozen=True)
class CampaignInputs:
    """What streaming a campaign takes of the config, made once at the edge (:meth:`of`):
    the config file's ``name`` (each recording's metadata says it), the motor ``current`` the drives
    stream (``bus.current``), the ``sync_period`` (s), the raw log's suffix, each actuator's
    ``following_error`` window (a,) (a drive standing further than half of it from a trajectory's
    start is moved there first), the drives' ``bring_up_timeout`` (s), where the bus is
    (``bus_label``), whether it is the simulated rig's, the simulated rig's ``fault`` and each
    trajectory's ``payloads``."""

    name: str
    current: str
    sync_period: float
    raw_log: str
    following_error: np.ndarray
    bring_up_timeout: float
    bus_label: str
    simulated: bool
    fault: SimFaultConfig | None = None
    payloads: Mapping[str, PayloadConfig] = field(default_factory=dict)

    @classmethod
    def of(cls, config: Config) -> CampaignInputs:
        """The inputs of a config whose campaign can run (it has a bus)."""
        if config.bus is None:
            raise ValueError(f"{config.source}: bus: missing section (needed to run)")
        return cls(name=Path(config.source).name, current=config.current, sync_period=sync_period(config.bus),
                   raw_log=config.output.raw_log,
                   following_error=np.array([a.limits.following_error for a in config.robot.actuators]),
                   bring_up_timeout=config.bus.bring_up_timeout,
                   bus_label=f"{config.bus.interface}:{config.bus.channel}", simulated=config.simulated,
                   fault=config.sim.fault if config.sim is not None else None,
                   payloads={t.name: t.payload for t in config.trajectories if t.payload is not None})


class _SyncCounter(can.Listener):
    """Counts the SYNC frames seen on the bus (notifier thread): the progress of a stream."""

    def __init__(self) -> None:
        self.count = 0

    def on_message_received(self, msg: can.Message) -> None:
        if msg.arbitration_id == SYNC_COB_ID and not msg.is_error_frame:
            self.count += 1


@contextmanager
def _progress(network, name: str, cycles: int) -> Iterator[None]:
    """The SYNC cycles of one stream reported (:func:`ident_hw.progress.report_progress`) from a
    thread of its own, five times a second, while someone listens."""
    if not logger.isEnabledFor(logging.DEBUG):
        yield
        return
    counter = _SyncCounter()
    network.notifier.add_listener(counter)
    done = threading.Event()

    def refresh() -> None:
        while not done.wait(0.2):
            report_progress(logger, name, min(counter.count, cycles), cycles, "cycle")
    thread = threading.Thread(target=refresh, name="progress", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        report_progress(logger, name, cycles, cycles, "cycle")
        network.notifier.remove_listener(counter)


@contextmanager
def _injected_events(session: Session, inputs: CampaignInputs, name: str) -> Iterator[None]:
    """Arm the config's ``sim.fault`` and the trajectory's ``payload`` when trajectory ``name``
    starts streaming: each happens ``after`` s of simulated time into the stream
    (:meth:`drivers.sim.SimulatedRig.schedule`); the payload is dropped again at its end."""
    rig = session.rig
    fault = inputs.fault if inputs.fault is not None and inputs.fault.trajectory == name else None
    payload = inputs.payloads.get(name)
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


def _drive_states(session: Session, group: DriveGroup) -> DriveStates:
    """CiA 402 state of every drive: read by the master over SDO, and the in-process rig's own."""
    master = {}
    for drive in group.drives:
        try:
            master[drive.label] = drive.state
        except NodeError as exc:
            master[drive.label] = f"unknown ({exc})"
    rig = None if session.rig is None else {f"node {d.id}": d.state for d in session.rig.drives}
    return DriveStates(master, rig)


def stream(session: Session, group: DriveGroup, planned: PlannedTrajectory, data: Path, inputs: CampaignInputs,
           host: HostSettings = HostSettings()) -> Recording:
    """Move to the trajectory's start, stream its set-points (:func:`~ident_hw.experiment.plan.setpoints`,
    the array the campaign's check validated) at the SYNC period and record it into ``data``."""
    traj = planned.trajectory
    if traj is None:
        raise ValueError(f"trajectory {planned.config.name!r} was not built: {planned.error}")
    targets = setpoints(traj)
    if np.any(np.abs(group.positions() - targets[0]) > 0.5 * inputs.following_error):
        group.move_to(targets[0], speed_fraction=APPROACH_SPEED)
    with _progress(session.network, traj.name, len(targets)), _injected_events(session, inputs, traj.name):
        return group.run_cyclic(targets, inputs.sync_period, output=data / f"{traj.name}.npz",
                                raw_log=data / f"{traj.name}{inputs.raw_log}",
                                metadata=RecordingMetadata(trajectory=traj.name, config=inputs.name,
                                                           current=inputs.current),
                                quiet=host.quiet)


def record_campaign(session: Session, data: Path, planned: list[PlannedTrajectory], inputs: CampaignInputs,
                    host: HostSettings) -> Generator[tuple[str, Recording], None, None]:
    """Bring the drives up (and home the simulated rig), stream every planned trajectory into
    ``data``, yielding each one's name and recording as it ends (a stop keeps those already made),
    then, whether the session ended or stopped, stop and disable the drives and keep their states
    in ``data/drives.json`` (:class:`DriveStates`)."""
    group = session.drive_group()
    try:
        logger.info(f"bringing up {len(group.drives)} drives on {inputs.bus_label}")
        group.bring_up(timeout=inputs.bring_up_timeout)
        if inputs.simulated:
            logger.info("homing (the simulated rig powers up at the home pose)")
            group.home()
        for i, p in enumerate(planned, 1):
            logger.info(f"[{i}/{len(planned)}] {p.describe()}")
            rec = stream(session, group, p, data, inputs, host)
            report = rec.metadata.sync_report
            skipped = report.sync_slots_skipped or 0
            held = report.master_longest_stall or 0.0
            logger.info(f"    recorded {rec.metadata.n_cycles} cycles, {rec.n_invalid} incomplete"
                        + (f", {skipped} SYNC slots skipped (the host woke the SYNC's timer late)" if skipped else "")
                        + (f"; this process was held up to {held:.2f} s, the timing process kept the SYNC, the "
                           f"set-points and the heartbeat going" if held >= HELD_UP else ""))
            yield p.config.name, rec
    finally:
        # quick stop and disable, then the drives stop watching the master's heartbeat before
        # it ends; a signal arriving meanwhile waits for the states to be written
        with shielded():
            group.close()
            write_file(data / DRIVES_FILE, _drive_states(session, group))


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


def identify_recordings(config: Config, recordings: Mapping[str, Recording], folder: str | Path, *,
                        report: bool = True, imported: Mapping[str, ImportSummary] | None = None) -> Results:
    """Identify offline from recordings already read (``ident-hw identify``) into ``folder``,
    whose STATUS ends as a run's does (:func:`conclude`), or ``failed: <why>`` (:func:`stop_reason`)
    if anything, a signal included, stops it; the exception is raised again. ``imported``: how the
    recordings made elsewhere were read."""
    folder = Path(folder)
    try:
        results = identify(config, recordings, imported=imported)
        conclude(folder, results, report)
    except BaseException as exc:
        mark_status(folder, f"failed: {stop_reason(exc)}")
        raise
    return results


def run_campaign(config: Config, folder: str | Path, *, online: CampaignEstimator | None = None,
                 planned: list[PlannedTrajectory] | None = None,
                 host: HostSettings = HostSettings(), report: bool = True) -> Results:
    """Record every trajectory of ``config`` on its bus, identify, validate, save into ``folder``.
    What it does is logged (:mod:`logging`, logger ``ident_hw``), each stream's SYNC cycles
    reported as progress (:mod:`ident_hw.progress`).

    Args:
        config: a config whose :func:`ident_hw.experiment.plan.check_campaign` passed.
        folder: a results folder from :func:`ident_hw.experiment.folders.new_results_folder`.
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
    if planned is None:
        planned = plan(config, online=online is not None)
    elif online is None:
        planned = [p for p in planned if not p.config.online_only]
    inputs = CampaignInputs.of(config)
    recordings: dict[str, Recording] = {}
    try:
        with host.pinned(), open_session(config) as session:
            with closing(record_campaign(session, folder / "data", planned, inputs, host)) as streams:
                for name, rec in streams:
                    recordings[name] = rec
                    if online is not None:
                        online.update(name, rec)
        mark_status(folder, "identifying")
        results = identify(config, recordings)
        if online is not None:
            results = replace(results, online=online.trace(results.base_fit))
        conclude(folder, results, report)
    except BusOpenError as exc:
        mark_status(folder, f"failed: {exc}; nothing moved, nothing recorded")
        raise
    except BaseException as exc:
        reason = stop_reason(exc)
        states = read_drive_states(folder / "data")
        master = dict(states.master) if states is not None else {}
        mark_status(folder, f"partial: {reason}; complete recordings: {', '.join(recordings) or 'none'}"
                    + (f"; drives after the stop: {drives_after_stop(master)}" if master else ""))
        if isinstance(exc, (KeyboardInterrupt, DriveError)):
            raise CampaignStopped(folder, reason, exc, master) from exc
        raise
    return results
