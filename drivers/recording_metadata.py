"""What a recording says about itself beside its samples: :class:`RecordingMetadata`, a typed
record, and its JSON form (the ``metadata`` member of a recording's NPZ), written and read here
only (:meth:`RecordingMetadata.to_json`, :meth:`RecordingMetadata.from_json`).

The JSON form is one flat object whose keys are the field names (the fields of the nested
:class:`~drivers.acquisition.CycleBooks` and :class:`~drivers.sync.SyncReport` at the top level
too, ``axes`` as a list of objects, ``pdo_layout`` as :func:`drivers.acquisition.layout_record`),
the keys recordings have always been stored with, so that a recording written before loads.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Mapping, Sequence

from drivers.acquisition import AxisLayout, CycleBooks, layout_from_record, layout_record
from drivers.axis import AxisConfig
from drivers.profiles import AVERAGED, INSTANTANEOUS, AveragingFilter
from drivers.sync import SyncReport
from drivers.units import REVOLUTE, AxisScaling

#: keys some recordings hold that no field reads any more (the velocity TPDO is always mapped)
RETIRED_KEYS = ("with_velocity",)


@dataclass(frozen=True)
class RecordedAxis:
    """One axis as the samples of a recording were converted with.

    Args:
        name: the axis name (``theta1``, ...).
        node_id: the drive's node-ID.
        profile: the drive profile's name (``EPOS2``, ``EPOS4``).
        scaling: drive units to SI (:class:`~drivers.units.AxisScaling`).
        current: the motor current streamed: ``instantaneous`` or ``averaged``.
        current_filter: the drive's running average behind an averaged current
            (:class:`~drivers.profiles.AveragingFilter`: cut-off and loop rate), which the
            identification matches; None for an instantaneous one (and in recordings made before
            it was kept: then the generation's, :attr:`~drivers.profiles.DriveProfile.current_averaging`).
    """

    name: str
    node_id: int
    profile: str
    scaling: AxisScaling
    current: str = INSTANTANEOUS
    current_filter: AveragingFilter | None = None

    @classmethod
    def of(cls, axis: AxisConfig, current: str | None = None) -> RecordedAxis:
        """The axis as recorded, streaming ``current`` (default the axis's own, ``axis.current``)."""
        current = axis.current if current is None else current
        averaging = axis.drive_profile.current_averaging if current == AVERAGED else None
        return cls(axis.name, axis.node_id, axis.drive_profile.name, axis.scaling, current, averaging)

    @property
    def units(self) -> dict[str, str]:
        """The SI unit of each recorded quantity of this axis (``rad``/``m``, ``A``)."""
        rev = self.scaling.kind == REVOLUTE
        return {"position": "rad" if rev else "m", "velocity": "rad/s" if rev else "m/s",
                "current": "A", "target": "rad" if rev else "m"}

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "node_id": self.node_id, "profile": self.profile,
                "scaling": dataclasses.asdict(self.scaling), "units": self.units, "current": self.current,
                "current_filter": None if self.current_filter is None else dataclasses.asdict(self.current_filter)}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> RecordedAxis:
        """The axis of a stored recording (its ``units`` follow from the scaling)."""
        averaging = doc.get("current_filter")
        return cls(str(doc["name"]), int(doc["node_id"]), str(doc["profile"]), AxisScaling(**doc["scaling"]),
                   str(doc.get("current", INSTANTANEOUS)), None if averaging is None else AveragingFilter(**averaging))


@dataclass(frozen=True)
class RecordingMetadata:
    """What a recording of a run, or a raw CAN log decoded, says about itself.

    ``None`` is "not known / does not apply" (a recording made by hand, or by a run or a decoder
    that does not fill that field).

    Args:
        trajectory: the trajectory streamed (its name).
        config: the file name of the run's config.
        file: where the recording was loaded from.
        source: the raw CAN log a decoded recording comes from.
        current: the motor current the drives streamed: ``instantaneous`` or ``averaged``.
        status: ``complete``, ``stopped: <why>``, ``running (checkpoint)`` (the recording
            process died), or ``decoded`` (from a raw log).
        format_version: the NPZ format (:data:`drivers.recording.FORMAT_VERSION`).
        axes: the axes in sample order, as the samples were converted.
        pdo_layout: the PDO layout of each axis the frames were decoded with.
        pdo_layout_source: where a decoded log's layout came from (stored beside it, or given by the
            caller, e.g. on the command line).
        sync: the SYNC source's name (``periodic``, ``lockstep``).
        sync_period: the nominal SYNC period, s.
        bus_load: the worst-case bus load of the run, fraction of the bitrate.
        bitrate: bit/s.
        n_targets: the set-points streamed (the cycles planned).
        t0: the bus time of the first SYNC, s (absolute; the samples' ``t`` start at 0).
        n_cycles: the rows recorded.
        invalid_cycles: the rows in which some axis misses a frame.
        setpoints: ``sent`` when the rows hold the set-points the master sent (else the RPDO
            echoes the decoder saw).
        late_setpoints: the rows whose RPDO echo disagreed with the set-point sent.
        buffer_overflows: rows the recorder's queue had no room for (lost).
        books: the decoder's counts of misplaced frames.
        sync_report: what the SYNC source did during the stream.
        raw_log: the raw CAN log written beside the recording.
        gc_collections: garbage collections while streaming.
        gc_longest_pause: the longest of them, s.
        log_truncated: a decoded log was cut short (read up to its last complete frame).
        nodes_heard: node-IDs a decoded log holds a TPDO or a heartbeat of.
        extra: free-form run information a caller of
            :meth:`drivers.epos.DriveGroup.run_cyclic` adds (JSON-able values; stored at the
            top level of the JSON form), and the keys of a stored recording this version
            has no field for, kept so that saving it again loses nothing.
    """

    trajectory: str | None = None
    config: str | None = None
    file: str | None = None
    source: str | None = None
    current: str = INSTANTANEOUS
    status: str | None = None
    format_version: int | None = None
    axes: tuple[RecordedAxis, ...] = ()
    pdo_layout: tuple[AxisLayout, ...] = ()
    pdo_layout_source: str | None = None
    sync: str | None = None
    sync_period: float | None = None
    bus_load: float | None = None
    bitrate: int | None = None
    n_targets: int | None = None
    t0: float | None = None
    n_cycles: int = 0
    invalid_cycles: int = 0
    setpoints: str | None = None
    late_setpoints: int | None = None
    buffer_overflows: int = 0
    books: CycleBooks = CycleBooks()
    sync_report: SyncReport = SyncReport()
    raw_log: str | None = None
    gc_collections: int | None = None
    gc_longest_pause: float | None = None
    log_truncated: bool = False
    nodes_heard: tuple[int, ...] = ()
    extra: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        clash = sorted(set(self.extra) & set(_json_keys()))
        if clash:
            raise ValueError(f"recording metadata: extra keys {clash} are fields of RecordingMetadata")
        object.__setattr__(self, "extra", MappingProxyType(dict(self.extra)))
        object.__setattr__(self, "axes", tuple(self.axes))
        object.__setattr__(self, "pdo_layout", tuple(self.pdo_layout))
        object.__setattr__(self, "nodes_heard", tuple(self.nodes_heard))

    def with_axes(self, axes: Sequence[AxisConfig], currents: Sequence[str] | None = None) -> RecordingMetadata:
        """This metadata with ``axes`` (:class:`~drivers.axis.AxisConfig`, in sample order),
        streaming ``currents`` (one per axis; default each axis's own), ``current`` theirs where
        all agree."""
        recorded = tuple(RecordedAxis.of(a, c) for a, c in zip(axes, currents or [None] * len(axes)))
        kinds = {a.current for a in recorded}
        return dataclasses.replace(self, axes=recorded, current=kinds.pop() if len(kinds) == 1 else self.current)

    def to_json(self) -> str:
        """The JSON form (see the module docstring)."""
        doc: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in _NESTED:
                doc.update(dataclasses.asdict(value))
            elif f.name == "axes":
                doc["axes"] = [a.to_json() for a in value]
            elif f.name == "pdo_layout":
                doc["pdo_layout"] = layout_record(value) if value else None
            elif f.name == "nodes_heard":
                doc["nodes_heard"] = list(value)
            elif f.name != "extra":
                doc[f.name] = value
        doc.update(self.extra)
        return json.dumps(doc, default=_json_default)

    @classmethod
    def from_json(cls, text: str) -> RecordingMetadata:
        """The metadata of a stored recording.

        Raises:
            ValueError: not a JSON object, or a known key holding a value of the wrong kind.
        """
        doc = json.loads(text)
        if not isinstance(doc, dict):
            raise ValueError(f"recording metadata is a JSON {type(doc).__name__}, not an object")
        known = {f.name for f in dataclasses.fields(cls)} - set(_NESTED) - {"extra"}
        values: dict[str, Any] = {k: v for k, v in doc.items() if k in known and v is not None}
        for name, record in _NESTED.items():
            values[name] = record(**{f.name: doc[f.name] for f in dataclasses.fields(record) if f.name in doc})
        try:
            values["axes"] = tuple(RecordedAxis.from_json(a) for a in doc.get("axes") or ())
            values["pdo_layout"] = layout_from_record(doc["pdo_layout"]) if doc.get("pdo_layout") else ()
        except (KeyError, TypeError) as exc:
            raise ValueError(f"damaged axes in the recording metadata ({type(exc).__name__}: {exc})") from None
        values["extra"] = {k: v for k, v in doc.items() if k not in _json_keys() and k not in RETIRED_KEYS}
        return cls(**values)


#: fields whose own fields are stored at the top level of the JSON form
_NESTED = {"books": CycleBooks, "sync_report": SyncReport}


def _json_keys() -> set[str]:
    """Every key of the JSON form a field of :class:`RecordingMetadata` stores."""
    own = {f.name for f in dataclasses.fields(RecordingMetadata)} - set(_NESTED) - {"extra"}
    return own | {f.name for record in _NESTED.values() for f in dataclasses.fields(record)}


def _json_default(obj):
    """NumPy scalars and arrays, paths and dataclasses a caller may put in ``extra``."""
    if dataclasses.is_dataclass(obj):
        return dataclasses.asdict(obj)
    if hasattr(obj, "tolist"):        # NumPy scalars and arrays
        return obj.tolist()
    if hasattr(obj, "__fspath__"):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
