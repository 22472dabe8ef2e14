"""Recording a streaming run: raw CAN traffic and decoded samples in SI units.

* Raw traffic: python-can's :class:`can.Logger` (``.log`` candump, ``.asc``, ``.blf``, chosen by
  the file suffix) fed by the same listener as the decoder, flushed periodically; beside it a
  JSON *sidecar* (:class:`LogSidecar`, ``<log>.json``: the PDO layout and the set-points sent),
  written before the first frame, so that the log decodes later with the layout it was
  recorded with, whatever the master maps by then.
* Samples: :class:`Recording`, saved as NPZ with arrays ``t`` (s, from the first SYNC; see below),
  ``cycle``, ``position`` (N, n_axes) rad|m, ``velocity`` rad/s|m/s, ``current`` A (motor
  current), ``statusword`` (-1 = none received yet), ``target`` rad|m, ``valid`` (N, n_axes):
  every TPDO of the axis placed in its cycle, ``position_valid``, ``velocity_valid``,
  ``current_valid`` (N, n_axes): the TPDO carrying that value placed in its cycle (validity per
  TPDO: a lost velocity frame leaves position and current valid), and ``metadata``
  (:class:`~drivers.recording_metadata.RecordingMetadata` as JSON: axes, scalings, node-IDs,
  profiles, the PDO layout, SYNC period, counts of missing cycles / late frames / buffer
  overflows, the caller's run information). Invalid values are NaN.
* ``target``: the set-point of each row. A streaming run records the set-points it sent, row k
  the one sent for SYNC k (:func:`with_sent_setpoints`); the RPDO echoes the assembler saw only
  count the rows whose echo disagreed (``metadata.late_setpoints``: the set-point reached the bus after
  its SYNC, or its echo came back out of order, as SocketCAN's can under load). A raw log decodes
  to the sent set-points its sidecar holds, else to the echoes.
* :class:`SampleRecorder` drains the bounded queue the assembler writes into, in its own thread,
  and rewrites the NPZ atomically at least every ``checkpoint_interval`` s, so a crash or Ctrl-C
  keeps what was recorded.
* ``t`` is the *measured* bus timestamp of each SYNC frame (``metadata.t0`` is the first one,
  absolute), not ``k * sync_period``: the SYNC producer (the kernel BCM on SocketCAN, a Python
  timer thread elsewhere) drifts above the nominal period, each period being the nominal one plus
  the timer latency, so ``k * period`` would slowly run ahead of the samples. Identification
  resamples or differentiates on ``t``.
* :func:`decode_log` replays a raw log through the same :class:`~drivers.acquisition.CycleAssembler`
  and conversion and gives the same samples (timestamps to the log's 1 µs resolution).
"""

from __future__ import annotations

import dataclasses
import io
import json
import logging
import os
import queue
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import can
import numpy as np

from drivers.acquisition import (AxisLayout, CycleAssembler, Row, current_of, cycle_books, layout_from_record,
                                 layout_record, master_layouts)
from drivers.axis import AxisConfig
from drivers.errors import ConfigError, RecordingError
from drivers.profiles import AveragingFilter
from drivers.recording_metadata import RecordingMetadata
from drivers.units import AxesScaling

logger = logging.getLogger(__name__)

RAW_LOG_SUFFIXES = (".log", ".asc", ".blf")
#: the measured values, each with its own validity array ``<name>_valid``
CHANNELS = ("position", "velocity", "current")
ARRAYS = ("t", "cycle", "position", "velocity", "current", "statusword", "target", "valid",
          "position_valid", "velocity_valid", "current_valid")
#: 2: validity per TPDO (``<channel>_valid``), the PDO layout in the metadata, sent set-points
FORMAT_VERSION = 2


def rows_to_arrays(rows: Sequence[Row], axes: Sequence[AxisConfig]) -> dict[str, np.ndarray]:
    """Convert rows (drive units, ``None`` = missing) to the SI arrays of a :class:`Recording`.

    ``t`` is left absolute here (bus time of each SYNC, s).
    """
    n = len(axes)

    def column(name: str, missing: float, dtype) -> np.ndarray:
        data = [[missing if v is None else v for v in getattr(r, name)] for r in rows]
        return np.array(data, dtype=dtype).reshape(len(rows), n)

    def received(name: str) -> np.ndarray:
        return np.array([[v is not None for v in getattr(r, name)] for r in rows], dtype=bool).reshape(len(rows), n)

    units = AxesScaling([a.scaling for a in axes])
    return {
        "t": np.array([r.timestamp for r in rows], dtype=float),
        "cycle": np.array([r.cycle for r in rows], dtype=np.int64),
        "position": units.position_from_counts(column("position", np.nan, float)),
        "velocity": units.velocity_from_rpm(column("velocity", np.nan, float)),
        "current": units.current_from_ma(column("current", np.nan, float)),
        "statusword": column("statusword", -1, np.int32),
        "target": units.position_from_counts(column("target", np.nan, float)),
        "valid": column("valid", False, bool),
        **{f"{name}_valid": received(name) for name in CHANNELS},
    }


@dataclass(frozen=True)
class Recording:
    """Decoded samples of a run (arrays as described in the module docstring), built once.

    ``position_valid``, ``velocity_valid``, ``current_valid`` (N, n_axes) bool default to
    ``valid`` (a recording made by hand: a value is valid where every TPDO of its axis is).

    Immutable: the fields cannot be rebound and every array is a read-only view (the caller's
    own arrays stay writable), so a recording saved, identified and reported is the one
    acquired. A changed recording is a new one (:func:`dataclasses.replace`,
    :func:`with_sent_setpoints`); :class:`SampleRecorder` accumulates the rows while recording.
    """

    t: np.ndarray
    cycle: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    current: np.ndarray
    statusword: np.ndarray
    target: np.ndarray
    valid: np.ndarray
    metadata: RecordingMetadata = field(default_factory=RecordingMetadata)
    position_valid: np.ndarray | None = None
    velocity_valid: np.ndarray | None = None
    current_valid: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name in ARRAYS:
            value = getattr(self, name)
            if value is None:    # a channel's validity not given: the axis's
                value = np.array(self.valid, dtype=bool, copy=True)
            view = np.asarray(value).view()
            view.flags.writeable = False
            object.__setattr__(self, name, view)

    @classmethod
    def from_chunks(cls, chunks: Sequence[dict[str, np.ndarray]], n_axes: int,
                    metadata: RecordingMetadata) -> "Recording":
        """Concatenate converted chunks; ``t`` becomes relative to the first SYNC (µs grid)."""
        if chunks:
            arrays = {k: np.concatenate([c[k] for c in chunks]) for k in ARRAYS}
        else:
            arrays = {k: np.zeros((0,) if k in ("t", "cycle") else (0, n_axes),
                                  dtype=bool if k.endswith("valid") else np.int32 if k == "statusword"
                                  else np.int64 if k == "cycle" else float) for k in ARRAYS}
        if len(arrays["t"]):
            t0 = float(arrays["t"][0])
            metadata = dataclasses.replace(metadata, t0=t0)
            arrays["t"] = np.round((arrays["t"] - t0) * 1e6) * 1e-6
        metadata = dataclasses.replace(metadata, n_cycles=int(len(arrays["t"])),
                                       invalid_cycles=int(np.count_nonzero(~arrays["valid"].all(axis=1))))
        return cls(**arrays, metadata=metadata)

    @property
    def n_invalid(self) -> int:
        """Cycles in which at least one axis is missing a frame."""
        return int(np.count_nonzero(~self.valid.all(axis=1)))

    def save(self, path: str | os.PathLike) -> Path:
        """Write the NPZ atomically (temporary file, then rename)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "wb") as f:
            np.savez(f, **{k: getattr(self, k) for k in ARRAYS},
                     metadata=np.array(self.metadata.to_json()))
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Recording":
        """Read a recording written by :meth:`save`.

        Raises:
            RecordingError: the file is missing, empty, truncated or not a recording (the
                message names the file).
        """
        try:
            data = np.load(path, allow_pickle=False)
        except FileNotFoundError:
            raise RecordingError(f"{path}: no such file") from None
        except Exception as exc:   # empty (EOFError), truncated zip (BadZipFile), not NumPy (ValueError)
            raise RecordingError(f"{path}: cannot read recording ({_why(exc)}): is the file complete?") from exc
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise RecordingError(f"{path}: not a recording (an NPZ file with arrays {ARRAYS})")
        with data:
            missing = [k for k in (*ARRAYS, "metadata") if k not in data]
            if missing:
                raise RecordingError(f"{path}: not a recording, missing arrays {missing}")
            try:
                arrays = {k: data[k] for k in ARRAYS}
                metadata = RecordingMetadata.from_json(str(data["metadata"]))
            except Exception as exc:   # a member cut short or corrupt (BadZipFile, zlib, EOFError)
                raise RecordingError(f"{path}: damaged recording ({_why(exc)})") from exc
        n = len(arrays["t"])
        if any(len(a) != n for a in arrays.values()):
            raise RecordingError(f"{path}: damaged recording: arrays of different lengths "
                                 f"{ {k: len(a) for k, a in arrays.items()} }")
        return cls(**arrays, metadata=metadata)


def with_sent_setpoints(rec: Recording, sent_counts: np.ndarray, axes: Sequence[AxisConfig]) -> Recording:
    """``rec`` with the set-points the master sent: row k (cycle k) gets
    ``sent_counts[k]`` (the set-points sent for SYNC k, counts, (n_targets, n_axes); a cycle past
    the last one gets the last: the streamer repeats it), converted with the axes' scalings.

    The set-points ``rec`` held are the RPDO echoes the assembler saw; the rows where an echo
    differs from the sent set-point by more than half a count (or is missing) on any axis are
    counted in ``metadata.late_setpoints``: the set-point reached the bus after its SYNC, or
    its echo came back out of order. A row's set-point is never taken from the echo order.
    ``metadata.setpoints`` says ``"sent"``. A new recording; an empty one is returned as it is.
    """
    if not len(rec.t):
        return rec
    counts = np.asarray(sent_counts)
    if counts.ndim != 2 or counts.shape[1] != len(axes) or not len(counts):
        raise ValueError(f"sent set-points of shape {counts.shape}, expected (n_targets, {len(axes)})")
    units = AxesScaling([a.scaling for a in axes])
    sent = units.position_from_counts(counts[np.minimum(rec.cycle, len(counts) - 1)])
    echoed_off = ~(np.abs(rec.target - sent) <= units.position_from_counts(0.5))   # NaN: no echo
    metadata = dataclasses.replace(rec.metadata, late_setpoints=int(np.count_nonzero(echoed_off.any(axis=1))),
                                   setpoints="sent")
    return dataclasses.replace(rec, target=sent, metadata=metadata)


def _why(exc: BaseException) -> str:
    """``Type: message`` of an exception, for a one-line error."""
    text = str(exc)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


class SampleRecorder:
    """Bounded queue of rows drained by a recorder thread into checkpointed NPZ files.

    Args:
        axes: the axes, in sample order.
        path: NPZ file to write (``None``: keep in memory only).
        metadata: the metadata stored with the samples (its axes default to ``axes``; the
            format version, the PDO layout, the status and the counts are the recorder's).
        maxsize: capacity of the queue in rows; a row that does not fit is counted in
            ``overflows`` (and in the metadata), never silently dropped.
        checkpoint_interval: s between rewrites of the NPZ while running (grows to 10× the time
            a write takes, so that long runs do not spend their time writing).
        layouts: the PDO layout the master configured, per axis, stored in the metadata
            (``pdo_layout``); ``None``: the master's :func:`~drivers.acquisition.pdo_layout` of
            the axes' profiles.
        setpoints: the set-points the master sends, counts (n_targets, n_axes), row k for SYNC
            k: every recording written (checkpoints too) holds them as its ``target``
            (:func:`with_sent_setpoints`); ``None``: the RPDO echoes the assembler saw.
    """

    def __init__(self, axes: Sequence[AxisConfig], path: str | os.PathLike | None = None,
                 metadata: RecordingMetadata | None = None, maxsize: int = 100_000,
                 checkpoint_interval: float = 1.0, layouts: Sequence[AxisLayout] | None = None,
                 setpoints: np.ndarray | None = None):
        self.axes = list(axes)
        self.path = Path(path) if path is not None else None
        metadata = metadata or RecordingMetadata()
        if not metadata.axes:
            metadata = metadata.with_axes(self.axes)
        self.metadata = dataclasses.replace(metadata, format_version=FORMAT_VERSION,
                                            pdo_layout=tuple(master_layouts(self.axes) if layouts is None else layouts))
        self.setpoints = None if setpoints is None else np.array(setpoints, dtype=np.int64)
        self.queue: queue.Queue[Row] = queue.Queue(maxsize)
        self.overflows = 0
        self.checkpoint_interval = checkpoint_interval
        self._chunks: list[dict[str, np.ndarray]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sample-recorder", daemon=True)
        self._error: BaseException | None = None

    def put(self, row: Row) -> None:
        """Enqueue a row without blocking (called from the notifier thread)."""
        try:
            self.queue.put_nowait(row)
        except queue.Full:
            self.overflows += 1

    def start(self) -> "SampleRecorder":
        self._thread.start()
        return self

    def _drain(self) -> int:
        rows = []
        while True:
            try:
                rows.append(self.queue.get_nowait())
            except queue.Empty:
                break
        if rows:
            self._chunks.append(rows_to_arrays(rows, self.axes))
        return len(rows)

    def _run(self) -> None:
        interval = self.checkpoint_interval
        last = time.monotonic()
        try:
            while not self._stop.wait(0.05):
                self._drain()
                if self.path is not None and time.monotonic() - last > interval:
                    started = time.monotonic()
                    self.recording("running (checkpoint)").save(self.path)
                    last = time.monotonic()
                    interval = max(self.checkpoint_interval, 10 * (last - started))
        except BaseException as exc:  # reported by close()
            self._error = exc

    def recording(self, status: str) -> Recording:
        """The samples drained so far."""
        meta = dataclasses.replace(self.metadata, status=status, buffer_overflows=self.overflows)
        rec = Recording.from_chunks(self._chunks, len(self.axes), meta)
        if self.setpoints is not None:
            rec = with_sent_setpoints(rec, self.setpoints, self.axes)
        return rec

    def close(self, status: str = "complete", **metadata) -> Recording:
        """Stop the thread, drain the queue, write the final NPZ and return the recording;
        ``metadata``: fields of :class:`RecordingMetadata` the run filled meanwhile."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        self._drain()
        self.metadata = dataclasses.replace(self.metadata, **metadata)
        rec = self.recording(status)
        if self.path is not None:
            rec.save(self.path)
        if self._error is not None:
            raise RuntimeError(f"recorder thread failed: {self._error!r}") from self._error
        return rec


@dataclass(frozen=True)
class LogSidecar:
    """What a raw CAN log needs beside its frames to decode later: the PDO layout of each axis
    (:class:`~drivers.acquisition.AxisLayout`, in sample order) and the set-points the master
    sent (counts, (n_targets, n_axes), row k for SYNC k; ``None`` when not known).

    Stored as JSON next to the log (:func:`sidecar_path`: ``run.log`` → ``run.log.json``), a
    file of its own since python-can's ``.blf`` has no place for text:
    ``{"format": "ident_hw raw CAN log sidecar", "version": 1, "pdo_layout": <layout record>,
    "setpoints": [[...], ...] | null}``.
    """

    layouts: tuple[AxisLayout, ...]
    setpoints: np.ndarray | None = None
    current_filters: tuple[AveragingFilter | None, ...] | None = None

    FORMAT = "ident_hw raw CAN log sidecar"
    VERSION = 1

    def write(self, log: str | os.PathLike) -> Path:
        """Write the sidecar of ``log`` atomically (temporary file, then rename)."""
        path = sidecar_path(log)
        doc = {"format": self.FORMAT, "version": self.VERSION, "log": Path(log).name,
               "pdo_layout": layout_record(self.layouts),
               "setpoints": None if self.setpoints is None else np.asarray(self.setpoints, dtype=np.int64).tolist()}
        if self.current_filters is not None:
            doc["current_filters"] = [None if f is None else dataclasses.asdict(f) for f in self.current_filters]
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(doc, separators=(",", ":")))
        os.replace(tmp, path)
        return path

    @classmethod
    def read(cls, log: str | os.PathLike) -> "LogSidecar | None":
        """The sidecar of ``log``; ``None`` if it has none.

        Raises:
            RecordingError: a sidecar that cannot be read or is not one (names the file).
        """
        path = sidecar_path(log)
        if not path.is_file():
            return None
        try:
            doc = json.loads(path.read_text())
            if not isinstance(doc, dict) or doc.get("format") != cls.FORMAT or doc.get("version") != cls.VERSION:
                raise ValueError(f"not a {cls.FORMAT} of version {cls.VERSION}")
            layouts = layout_from_record(doc["pdo_layout"])
            setpoints = doc.get("setpoints")
            if setpoints is not None:
                setpoints = np.array(setpoints, dtype=np.int64)
                if setpoints.ndim != 2 or setpoints.shape[1] != len(layouts):
                    raise ValueError(f"set-points of shape {setpoints.shape} for {len(layouts)} axes")
            filters = doc.get("current_filters")
            if filters is not None:
                filters = tuple(None if f is None else AveragingFilter(**f) for f in filters)
                if len(filters) != len(layouts):
                    raise ValueError(f"{len(filters)} current filters for {len(layouts)} axes")
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise RecordingError(f"{path}: damaged sidecar of the raw CAN log ({_why(exc)})") from exc
        return cls(layouts, setpoints, filters)


def sidecar_path(log: str | os.PathLike) -> Path:
    """The :class:`LogSidecar` file of the raw CAN log ``log``: its name plus ``.json``."""
    log = Path(log)
    return log.with_name(log.name + ".json")


class FlushingLogger(can.Listener):
    """python-can's :class:`can.Logger` for ``path``, flushed to disk every ``interval`` s.

    The flush happens in the thread that delivers the messages, so the writer is never used
    from two threads at once. With ``layouts`` (the PDO layout the master configured, per axis)
    the log's :class:`LogSidecar` is written first, with ``setpoints`` (counts the master
    sends, (n_targets, n_axes)) and ``current_filters`` (each axis's running average behind an
    averaged current, None for an instantaneous one), so that :func:`decode_log` decodes the log
    as recorded.
    """

    def __init__(self, path: str | os.PathLike, interval: float = 0.5,
                 layouts: Sequence[AxisLayout] | None = None, setpoints: np.ndarray | None = None,
                 current_filters: Sequence[AveragingFilter | None] | None = None):
        suffix = Path(path).suffix.lower()
        if suffix not in RAW_LOG_SUFFIXES:
            raise ConfigError(f"raw CAN log {path}: suffix must be one of {RAW_LOG_SUFFIXES}, "
                              f"got {suffix!r}")
        self.path = Path(path)
        if layouts is not None:
            LogSidecar(tuple(layouts), setpoints,
                       None if current_filters is None else tuple(current_filters)).write(self.path)
        elif sidecar_path(self.path).exists():
            sidecar_path(self.path).unlink()     # a previous log's, which this one would be read with
        self.writer = can.Logger(path)
        self.interval = interval
        self._last = time.monotonic()
        self._lock = threading.Lock()
        self._stopped = False

    def on_message_received(self, msg: can.Message) -> None:
        with self._lock:            # a frame the notifier was delivering when the stream closed is left out
            if self._stopped:
                return
            self.writer.on_message_received(msg)
            now = time.monotonic()
            if now - self._last > self.interval:
                self._last = now
                file = getattr(self.writer, "file", None)
                if file is not None and not file.closed and not self.path.suffix.lower() == ".blf":
                    file.flush()

    def on_error(self, exc: Exception) -> None:
        pass  # reported by the assembler

    def stop(self) -> None:
        """Close the log; frames handed over afterwards are ignored (the notifier may still be
        delivering one when the stream closes: removing a listener does not wait for it)."""
        with self._lock:
            self._stopped = True
            self.writer.stop()


def decode_log(path: str | os.PathLike, axes: Sequence[AxisConfig], max_cycles: int | None = None,
               metadata: RecordingMetadata | None = None, lockstep_period: float | None = None,
               layouts: Sequence[AxisLayout] | None = None, layout_source: str | None = None) -> Recording:
    """Replay a raw CAN log through the acquisition decoder.

    The log decodes with the PDO layout of its :class:`LogSidecar` (the one it was recorded
    with), and its rows get the set-points the sidecar holds (:func:`with_sent_setpoints`). A
    log without a sidecar (a ``candump``, or one written before the sidecar existed) decodes only
    with ``layouts`` given (``layout_source`` says where they come from, for the metadata's
    ``pdo_layout_source``), and to the RPDO echoes: read with another layout its frames would
    decode to wrong values marked valid (another drive generation's current: kiloamperes).
    The metadata holds the layout used (``pdo_layout``) and, per axis, the current its TPDOs
    carried as the layout says (instantaneous or averaged, :func:`drivers.acquisition.current_of`)
    with the running average behind an averaged one (the sidecar's, else the generation's).

    A log cut short (copied or killed while written) is read up to its last complete frame: a
    text log's last line without its newline is left out (it would parse as a shorter frame),
    and a frame the reader cannot parse ends the reading. The metadata says so
    (``log_truncated``) and lists ``nodes_heard``: the node-IDs that sent a TPDO or a heartbeat.

    Args:
        path: ``.log``/``.asc``/``.blf`` file written during a run.
        axes: the axes of the run, in sample order (node-IDs, profiles, scalings).
        max_cycles: stop after this many cycles (the run's ``n_cycles``; ``None``: all).
        metadata: the caller's part of the result's metadata (the trajectory, the SYNC period...).
        lockstep_period: the SYNC period (s) of a run in lockstep, whose row times are the cycle
            index times the period (the simulated time); ``None``: the SYNCs' bus time stamps.
        layouts: the PDO layout of each axis to decode a log without a sidecar with.
        layout_source: where ``layouts`` come from, in words.

    Raises:
        RecordingError: the file is missing or is not a CAN log of that format; its sidecar is
            damaged or names other nodes than ``axes``; it has no sidecar and no ``layouts`` were
            given; or frames of a streamed TPDO have another length than the layout says (the log
            was recorded with another layout).
    """
    path = Path(path)
    if not path.is_file():
        raise RecordingError(f"raw CAN log {path}: no such file")
    sidecar, layouts, source = _log_layouts(path, axes, layouts, layout_source)
    try:
        currents = [current_of(layout, axis.drive_profile) for layout, axis in zip(layouts, axes)]
    except ValueError as exc:
        raise RecordingError(f"raw CAN log {path}: its PDO layout ({source}) does not fit the axes given: {exc}") from None
    rows: list[Row] = []
    assembler = CycleAssembler(layouts, rows.append, max_cycles=max_cycles, period=lockstep_period)
    heard, truncated = _replay(path, assembler)
    assembler.flush()
    _refuse_other_layouts(path, assembler, layouts, source)
    meta = (metadata or RecordingMetadata()).with_axes(axes, currents)
    if sidecar is not None and sidecar.current_filters is not None:
        meta = dataclasses.replace(meta, axes=tuple(dataclasses.replace(a, current_filter=f)
                                                    for a, f in zip(meta.axes, sidecar.current_filters)))
    meta = dataclasses.replace(meta, source=str(path), status="decoded",
                               books=cycle_books(assembler), format_version=FORMAT_VERSION, log_truncated=truncated,
                               nodes_heard=tuple(sorted(heard)), pdo_layout=tuple(layouts), pdo_layout_source=source)
    chunks = [rows_to_arrays(rows, axes)] if rows else []
    rec = Recording.from_chunks(chunks, len(axes), meta)
    if sidecar is not None and sidecar.setpoints is not None:
        rec = with_sent_setpoints(rec, sidecar.setpoints, axes)
    return rec


def _refuse_other_layouts(path: Path, assembler: CycleAssembler, layouts: Sequence[AxisLayout], source: str) -> None:
    """A streamed TPDO's frames of another length than the layout says were recorded with another
    layout: the log is refused, naming the node, the PDO and both lengths."""
    if not assembler.wrong_length:
        return
    sizes = {f.cob_id(a.node_id): (a.node_id, f) for a in layouts for f in a.frames if f.direction == "tpdo"}
    differ = []
    for cob_id, (count, length) in sorted(assembler.wrong_length.items()):
        node, frame = sizes[cob_id]
        differ.append(f"node {node}'s TPDO{frame.number} (COB-ID 0x{cob_id:03X}): {count} frames of {length} bytes, "
                      f"the layout says {frame.size}")
    raise RecordingError(f"raw CAN log {path} was recorded with another PDO layout than its decoding's ({source}): "
                         f"{'; '.join(differ)} (another drive generation, or another bus.current)")


def _log_layouts(path: Path, axes: Sequence[AxisConfig], given: Sequence[AxisLayout] | None = None,
                 given_source: str | None = None) -> tuple[LogSidecar | None, list[AxisLayout], str]:
    """The PDO layouts a log decodes with: its sidecar's, else the ``given`` ones (either checked
    against the node-IDs of ``axes``). Returns the sidecar (or None), the layouts and where they
    came from (``pdo_layout_source`` of the metadata)."""
    sidecar = LogSidecar.read(path)
    if sidecar is not None:
        layouts = list(sidecar.layouts)
        source = f"stored ({sidecar_path(path).name})"
        if given is not None:
            logger.warning("raw CAN log %s: decoded with the PDO layout of its own %s, not the one given (%s)",
                           path, sidecar_path(path).name, given_source or "given")
    elif given is not None:
        layouts = list(given)
        source = f"given: {given_source or 'by the caller'}"
    else:
        raise RecordingError(f"raw CAN log {path}: no {sidecar_path(path).name} beside it with the PDO layout it was "
                             f"recorded with; decoded with another layout its frames give wrong values marked valid. "
                             f"Give the layout it was recorded with (decode_log's layouts)")
    recorded, configured = [a.node_id for a in layouts], [a.node_id for a in axes]
    if recorded != configured:
        differ = [f"{a.label} is node {r} in the log" for a, r in zip(axes, recorded) if a.node_id != r]
        if len(recorded) != len(configured):
            differ.append(f"{len(recorded)} axes in the log, {len(configured)} given")
        raise RecordingError(f"raw CAN log {path}: recorded from nodes {recorded} ({source}), "
                             f"the axes given are nodes {configured}: {'; '.join(differ)}")
    return sidecar, layouts, source


def read_layouts(path: str | os.PathLike) -> tuple[AxisLayout, ...]:
    """The PDO layouts a file holds: a raw log's sidecar (``<log>.json``, :class:`LogSidecar`) or a
    decoded recording (``.npz``, its metadata's ``pdo_layout``), e.g. of another run with the same
    drives, to decode a log that lost its own sidecar with.

    Raises:
        RecordingError: not such a file, or one without a layout.
    """
    path = Path(path)
    if path.suffix.lower() == ".npz":
        layouts = Recording.load(path).metadata.pdo_layout
        if not layouts:
            raise RecordingError(f"{path}: a recording without its PDO layout (made before it was kept)")
        return layouts
    if path.suffix.lower() != ".json" or not path.is_file():
        raise RecordingError(f"{path}: no PDO layout here (a raw log's sidecar <log>.json or a decoded .npz "
                             f"recording has one)")
    try:
        doc = json.loads(path.read_text())
        if not isinstance(doc, dict) or doc.get("format") != LogSidecar.FORMAT:
            raise ValueError(f"not a {LogSidecar.FORMAT}")
        return layout_from_record(doc["pdo_layout"])
    except (OSError, ValueError, KeyError) as exc:
        raise RecordingError(f"{path}: no PDO layout read ({_why(exc)})") from exc


def _replay(path: Path, assembler: CycleAssembler) -> tuple[set[int], bool]:
    """Feeds the log's frames to ``assembler`` until it is done or the log ends. Returns the
    node-IDs heard (a TPDO or a heartbeat) and whether the log was cut short (its last line, or
    a frame the reader cannot parse after the first)."""
    heard: set[int] = set()
    reader, truncated = _log_reader(path)
    frames = 0
    with reader:
        messages = iter(reader)
        while not assembler.done:
            try:
                msg = next(messages)
            except StopIteration:
                break
            except Exception as exc:   # a frame cut short or corrupt: the log ends there
                if not frames:
                    raise RecordingError(f"raw CAN log {path}: not a {path.suffix} CAN log ({_why(exc)})") from exc
                truncated = True
                break
            frames += 1
            cob = msg.arbitration_id
            if not msg.is_extended_id and (cob >> 7 in (3, 5, 7, 9, 14)) and cob & 0x7F:   # TPDO1-4, heartbeat
                heard.add(cob & 0x7F)
            assembler.on_message_received(msg)
    return heard, truncated


def _log_reader(path: Path):
    """python-can's reader of ``path`` and whether its last line was cut short (text formats)."""
    suffix = path.suffix.lower()
    if suffix not in (".log", ".asc"):
        try:
            return can.LogReader(path), False
        except Exception as exc:
            raise RecordingError(f"raw CAN log {path}: cannot read ({_why(exc)})") from exc
    raw = path.read_bytes()
    complete = raw[: raw.rfind(b"\n") + 1]
    text = io.StringIO(complete.decode("latin-1"))
    reader = can.io.CanutilsLogReader(text) if suffix == ".log" else can.io.ASCReader(text)
    return reader, len(complete) < len(raw)
