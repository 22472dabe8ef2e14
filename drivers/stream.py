"""One streamed run of set-points, one per SYNC, recorded: the steps of
:meth:`drivers.epos.DriveGroup.run_cyclic` as a session object.

    stream = CyclicStream(group, targets, period, output="run.npz")
    recording = stream.run()          # check, prepare, start, wait, hold, close

:meth:`CyclicStream.run` is the only caller of the steps; they are methods so that each reads on
its own: :meth:`~CyclicStream.check` (set-points in range, bus load, the drives at the start),
:meth:`~CyclicStream.prepare` (first set-point, cyclic mode, enable), :meth:`~CyclicStream.start`
(recorder, raw log, set-point streamer, cycle assembler), :meth:`~CyclicStream.stream` (the SYNC
source runs the cycles, or starts its timer), :meth:`~CyclicStream.wait` (a stall watchdog while
a free-running SYNC runs), :meth:`~CyclicStream.hold` (leave the cyclic mode while the SYNC
still runs, where a drive watches its set-points) and :meth:`~CyclicStream.close` (stop the
SYNC, stop the motion after an error, save the samples).

The SYNC comes from the drive group's :class:`drivers.sync.SyncSource`; what the host does
meanwhile (the garbage collector, the CPUs the threads run on) is the caller's choice: ``quiet``
is a context entered while the SYNC runs (e.g. :func:`drivers.gc_freeze.frozen_gc`).
"""

from __future__ import annotations

import dataclasses
import logging
import os
from contextlib import AbstractContextManager, ExitStack, nullcontext
from typing import Callable, Sequence, TypeVar

import canopen
import numpy as np

from drivers.acquisition import CycleAssembler, cycle_books
from drivers.axis import check_setpoints
from drivers.cia import CW_ENABLE_OPERATION, SW_FAULT
from drivers.errors import ConfigError, DriveError, DriveFault
from drivers.gc_freeze import GcPauses
from drivers.recording import FlushingLogger, Recording, SampleRecorder
from drivers.recording_metadata import RecordedAxis, RecordingMetadata
from drivers.supervision import Supervisor, WatchClock
from drivers.sync import FrameTable
from drivers.units import AxesScaling

logger = logging.getLogger(__name__)


def setpoint_counts(axes: Sequence, targets) -> np.ndarray:
    """The counts streamed for the set-points ``targets`` (n_cycles, n_axes) in rad|m, one row
    per SYNC: checked against the axes' software position limits
    (:func:`drivers.axis.check_setpoints`), rounded to whole counts (:class:`AxesScaling`),
    within the I32 range of the drives; :class:`ConfigError` otherwise. Pure (no bus): the
    campaign's check runs it on the set-points before any bus is opened, as
    :meth:`CyclicStream.check` does before the SYNC starts."""
    targets = np.asarray(targets, dtype=float)
    check_setpoints(axes, targets, "run_cyclic targets")
    counts = AxesScaling([a.scaling for a in axes]).counts_from_position(targets)
    if np.abs(counts).max() >= 2**31:
        raise ConfigError("run_cyclic targets: beyond the I32 range of the drives' counts")
    return counts


_T = TypeVar("_T")


def _made(value: _T | None, what: str) -> _T:
    """``value``, made by an earlier step of the run (RuntimeError naming it if not)."""
    if value is None:
        raise RuntimeError(f"streaming run: {what} used before the step that makes it (check, then start)")
    return value


class TargetStreamer:
    """Sends the set-points of cycle k+1 as RPDO frames when SYNC k is seen (notifier thread);
    after the last cycle it repeats the last set-points, until the SYNC stops (the drives hold
    them, and their RPDO deadline is met, while they are switched out of the cyclic mode)."""

    def __init__(self, network: canopen.Network, drives: Sequence, counts: np.ndarray,
                 supervisor: Supervisor):
        self.network = network
        self.counts = counts.tolist()
        self.supervisor = supervisor
        self.rpdos = []
        for drive in drives:
            frame = next(f for f in drive.frames if f.direction == "rpdo")
            self.rpdos.append((frame.cob_id(drive.axis.node_id), frame.struct.pack))
        self.failed = False

    def send(self, k: int) -> None:
        if self.failed:
            return
        try:
            for (cob_id, pack), value in zip(self.rpdos, self.counts[min(k, len(self.counts) - 1)]):
                self.network.send_message(cob_id, pack(value, CW_ENABLE_OPERATION))
        except Exception as exc:  # noqa: BLE001 - any send failure stops the run
            self.failed = True
            self.supervisor.bus_error(f"sending the set-points of cycle {k} failed: {exc!r}")

    def on_sync(self, k: int) -> None:
        self.send(k + 1)

    def table(self) -> FrameTable:
        """Every cycle's RPDO frames, for a SYNC source that sends them itself (a timing
        process): their COB-IDs, their lengths in bytes, and the data of all cycles, row k the
        frames of cycle k one after the other (:class:`drivers.sync.SetpointFrames`)."""
        cob_ids = tuple(cob_id for cob_id, _ in self.rpdos)
        rows = [b"".join(pack(value, CW_ENABLE_OPERATION) for (_, pack), value in zip(self.rpdos, row))
                for row in self.counts]
        sizes = tuple(len(pack(0, CW_ENABLE_OPERATION)) for _, pack in self.rpdos)
        return FrameTable(cob_ids, sizes, b"".join(rows))


class CyclicStream:
    """The set-points ``targets`` (n_cycles, n_axes) in rad|m streamed by ``group`` (a
    :class:`drivers.epos.DriveGroup`, brought up) at ``period`` s, recorded; the arguments and
    the contract are :meth:`drivers.epos.DriveGroup.run_cyclic`'s."""

    def __init__(self, group, targets, period: float, output: str | os.PathLike | None = None,
                 raw_log: str | os.PathLike | None = None, metadata: RecordingMetadata | None = None, queue_size: int = 100_000,
                 sync_timeout: float | None = None,
                 quiet: Callable[[], AbstractContextManager] = nullcontext):
        self.group = group
        self.sync = group.sync
        self.quiet = quiet
        self.targets = np.asarray(targets, dtype=float)
        self.period = period
        self.output, self.raw_log, self.metadata = output, raw_log, metadata
        self.queue_size = queue_size
        self.sync_timeout = sync_timeout or group.watchdogs.sync_progress
        self.counts: np.ndarray | None = None
        self.load = 0.0
        self.hold_at_end = False
        self.recorder: SampleRecorder | None = None
        self.raw: FlushingLogger | None = None
        self.streamer: TargetStreamer | None = None
        self.assembler: CycleAssembler | None = None
        self._host = ExitStack()
        self._pauses: GcPauses | None = None

    def run(self) -> Recording:
        """Every step in order; on any exception (Ctrl-C included) the motion is stopped, the
        samples so far saved and the exception raised."""
        self.check()
        self.prepare()
        self.start()
        error: BaseException | None = None
        try:
            self.stream()
            self.wait()
            self.hold()
        except BaseException as exc:
            error = exc
        return self.close(error)

    # -- steps ------------------------------------------------------------------------------------
    def check(self) -> None:
        """Set-points in range (:func:`setpoint_counts`), no fault pending, the bus load within
        the bitrate, the drives at the first set-point (within their following-error window)."""
        group, targets = self.group, self.targets
        self.counts = setpoint_counts(group.axes, targets)
        group.supervisor.raise_if_fault()
        self.load = group.check_bus_load(self.period)
        actual = group.positions()
        for i, a in enumerate(group.axes):
            if abs(actual[i] - targets[0, i]) > a.following_error_window:
                raise ConfigError(f"{a.label} is at {actual[i]:.6g}, the trajectory starts at "
                                  f"{targets[0, i]:.6g}: move_to() the start first")
        self.sync.check_period(self.period)

    def prepare(self) -> None:
        """The first set-point, then the cyclic mode (the drive holds its position when it starts),
        then enable. A drive watching its set-points (an RPDO deadline) must leave the cyclic
        mode while the SYNC still runs (:meth:`hold`): only a free-running SYNC does."""
        group = self.group
        for d, c in zip(group.drives, _made(self.counts, "the set-point counts")[0]):
            d.write(d.profile.cyclic_target, int(c))
        group.guarded(lambda: [d.prepare_cyclic(self.period) for d in group.drives])
        self.hold_at_end = self.sync.free_running and any(d.watches_setpoints() for d in group.drives)
        group.enable()

    def start(self) -> None:
        """Recorder, raw log, set-point streamer and cycle assembler on the notifier; the
        caller's ``quiet`` context entered, the garbage collector's pauses counted."""
        group, sync = self.group, self.sync
        meta = dataclasses.replace(self.metadata or RecordingMetadata(), sync_period=self.period, bus_load=self.load,
                                   bitrate=group.bitrate, n_targets=len(self.targets), sync=sync.name)
        self.recorder = SampleRecorder(group.axes, self.output, meta, maxsize=self.queue_size,
                                       layouts=group.layouts, setpoints=self.counts).start()
        filters = [RecordedAxis.of(a).current_filter for a in group.axes]
        self.raw = (FlushingLogger(self.raw_log, layouts=group.layouts, setpoints=self.counts, current_filters=filters)
                    if self.raw_log else None)
        self.streamer = TargetStreamer(group.network, group.drives, _made(self.counts, "the set-point counts"),
                                       group.supervisor)
        answers = sync.answers_on_sync(group.network)
        self.assembler = CycleAssembler(
            group.layouts, self.recorder.put, on_sync=self.streamer.on_sync if answers else None,
            period=sync.row_period,
            on_status=lambda i, sw: group.supervisor.report(DriveFault(
                group.drives[i].label, None, f"statusword 0x{sw:04X}: " +
                ("fault bit" if sw & SW_FAULT else "following error bit"))),
            on_bus_error=group.supervisor.bus_error, max_cycles=len(self.targets),
            forward=[self.raw] if self.raw else [])
        group.network.notifier.add_listener(self.assembler)
        self._host.enter_context(self.quiet())
        self._pauses = self._host.enter_context(GcPauses())

    def stream(self) -> None:
        """The SYNC source's part (:meth:`drivers.sync.SyncSource.stream`): a stepped one runs
        every cycle here, a free-running one starts its timer after the first set-points."""
        self.sync.stream(self.group.network, self.period, len(self.targets), self.streamer,
                         self.group.supervisor.raise_if_fault)

    def wait(self) -> None:
        """While a free-running SYNC runs: until the last cycle is recorded, watching faults,
        heartbeats and a stall (no new cycle for ``sync_timeout`` s of the time the master was
        running and watching, :class:`~drivers.supervision.WatchClock`: a hold-up of the master's
        own process is no stall of the SYNC; its notifier catches up afterwards)."""
        group, assembler = self.group, _made(self.assembler, "the cycle assembler")
        watch = WatchClock()
        last_count, last_progress = -1, watch.advance()
        while not assembler.done and self.sync.free_running:
            if group.supervisor.fault_event.wait(min(0.05, 10 * self.period)):
                break
            group.supervisor.check_heartbeats()
            progress = assembler.progress
            now = watch.advance()
            if progress != last_count:
                last_count, last_progress = progress, now
            elif now - last_progress > self.sync_timeout:
                hint = " (is the bus opened with receive_own_messages=True?)" if progress == 0 else ""
                raise DriveError(f"no SYNC cycle seen for {now - last_progress:.2f} s (bus.watchdogs.sync_progress "
                                 f"{self.sync_timeout:g} s){hint}")
        group.supervisor.raise_if_fault()

    def hold(self) -> None:
        """Where a drive watches its set-points: every drive to profile position holding the last
        set-point, before the SYNC stops (:meth:`drivers.epos.EposDrive.hold_position`)."""
        if self.hold_at_end:
            for d, c in zip(self.group.drives, _made(self.counts, "the set-point counts")[-1]):
                d.hold_position(int(c))
            self.group.supervisor.raise_if_fault()

    def close(self, error: BaseException | None) -> Recording:
        """Stop the SYNC; after an error stop the motion (quick stop, disable); save the samples
        with the cycle books; raise ``error`` (a :class:`DriveFault` carries the NPZ path)."""
        group = self.group
        self.sync.stop()
        self._host.close()
        if error is not None:
            error = group.with_error_code(error)
            stopped = self.sync.report().timers_stopped_after
            if stopped is not None and isinstance(error, DriveError):
                error = _with_cause(error, f"the timing process had stopped SYNC, set-points and the master's "
                                           f"heartbeat after the master made no progress for {stopped:.2f} s "
                                           f"(bus.watchdogs.master_progress)")
            group.stop_motion()
        assembler = _made(self.assembler, "the cycle assembler")
        pauses = _made(self._pauses, "the garbage collector's pauses")
        group.network.notifier.remove_listener(assembler)
        assembler.flush()
        if self.raw is not None:
            self.raw.stop()
        status = "complete" if error is None else f"stopped: {error}"
        recording = _made(self.recorder, "the recorder").close(status, books=cycle_books(assembler),
                                        raw_log=str(self.raw_log) if self.raw_log else None,
                                        gc_collections=len(pauses.durations),
                                        gc_longest_pause=pauses.longest,
                                        sync_report=self.sync.report())
        if error is not None:
            if isinstance(error, DriveFault):
                error.recording = self.output
            raise error
        return recording


def _with_cause(error: DriveError, cause: str) -> DriveError:
    """``error`` with ``cause`` added to its message (a fault keeps its type, node and code); an
    error of another kind is kept as it is, the cause logged."""
    if isinstance(error, DriveFault):
        extended = type(error).__new__(type(error))
        DriveFault.__init__(extended, error.node, error.code, f"{error.text}; {cause}")
        return extended
    if type(error) is DriveError:
        return DriveError(f"{error}; {cause}")
    logger.error("%s", cause)
    return error
