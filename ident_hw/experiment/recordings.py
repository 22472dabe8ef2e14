"""The recordings given to ``ident-hw identify``: found (files, or a results folder's
``data/``: :func:`recording_paths`), loaded and checked against the config before anything is
written.

A decoded ``.npz`` keeps the node-IDs, profiles and drive scalings it was converted with
(``metadata.axes``); a mismatch with the config is an error naming both files, since the SI
samples of the file were made with the recording's values (a raw CAN log holds counts and mA and
is decoded with the config's values instead). A raw log must hold frames of every configured
node. What each recording covers (complete, stopped, checkpoint, truncated) is reported by
:func:`ident_hw.experiment.preparation.coverage` and judged by the quality verdict.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drivers.errors import RecordingError
from drivers.acquisition import master_layouts
from drivers.axis import AxisConfig
from drivers.recording import RAW_LOG_SUFFIXES, Recording, decode_log, read_layouts, sidecar_path
from drivers.recording_metadata import RecordingMetadata
from ident_hw.config import ActuatorConfig, Config, IdentificationConfig
from ident_hw.records import ImportSummary
from ident_hw.config.to_drivers import axis_config, axis_scaling

from .external import read_external
from .plan import cycles_planned, plan

#: drive-scaling fields compared between a recording and the config (drivers.units.AxisScaling)
SCALING_FIELDS = ("kind", "counts_per_turn", "torque_constant", "gear_ratio", "screw_lead")


def identification_valid(rec: Recording) -> np.ndarray:
    """(N, n_axes) bool: the rows of each axis whose values identification uses, its position
    and its current, were received in their cycle (a lost velocity or statusword frame does not
    matter here)."""
    position, current = rec.position_valid, rec.current_valid
    assert position is not None and current is not None     # Recording.__post_init__ fills them
    return position & current


def require_trajectories(ident: IdentificationConfig, source: str, names: Collection[str]) -> None:
    """Every trajectory the identification section ``ident`` (of the config file ``source``)
    needs is among ``names`` (those recorded)."""
    needed = [n for s in ident.steps for n in s.trajectories] + list(ident.validation)
    missing = [n for n in dict.fromkeys(needed) if n not in names]
    if missing:
        raise RecordingError(f"no recording of trajectories {missing}, which the identification of "
                             f"{source} needs (given: {sorted(names) or 'none'})")


@dataclass(frozen=True)
class RecordingChecks:
    """What a recording file is decoded with and checked against, taken from the config once
    (:meth:`of`): the config file ``source`` (named in errors), its drives (``actuators``), its
    ``bus.current``, its SYNC period (s; None without a bus section), whether it runs in lockstep
    (a raw log's row times are then its cycle times) and ``cycles_of``, the samples (SYNC cycles)
    the config plans for a trajectory name (None if it has none or cannot be built; the trajectory
    is built when asked, which only a raw log needs)."""

    source: str
    actuators: tuple[ActuatorConfig, ...]
    current: str
    sync_period: float | None
    lockstep: bool
    cycles_of: Callable[[str], int | None]

    @classmethod
    def of(cls, config: Config) -> RecordingChecks:
        """The checks of ``config``."""
        period = 1.0 / config.bus.sync_rate if config.bus is not None else None
        return cls(config.source, config.robot.actuators, config.current, period, config.sync_mode == "lockstep",
                   lambda name: cycles_planned(plan(config, [name])).get(name))


#: what ``--pdo-layout`` may name besides a file: the layout the config's master maps today
CONFIG_LAYOUT = "config"


@dataclass(frozen=True)
class GivenLayout:
    """The PDO layouts to decode a raw log with (:func:`given_layout`) and where they come from,
    in words."""

    layouts: list
    source: str


def given_layout(source: str | Path, axes: Sequence[AxisConfig], config_file: str, current: str) -> GivenLayout:
    """The PDO layouts ``source`` names (``ident-hw identify --pdo-layout``), to decode a raw log
    without its sidecar with: :data:`CONFIG_LAYOUT` (the layout the master maps on the config's
    drive ``axes``, of the file ``config_file``, with its ``bus.current``, ``current``), a sidecar
    ``<log>.json`` or a decoded ``.npz`` recording of another run with the same drives."""
    if str(source) == CONFIG_LAYOUT:
        return GivenLayout(master_layouts(list(axes)),
                           f"the layout {Path(config_file).name} maps (bus.current: {current})")
    return GivenLayout(list(read_layouts(source)), f"that of {source}")


def load_recording(path: str | Path, checks: RecordingChecks, layout: str | Path | None = None) -> tuple[str, Recording]:
    """A recording from a decoded ``.npz`` or a raw CAN log (``.log``/``.asc``/``.blf``), checked
    against the config's ``checks``; returns (trajectory name, recording).

    The trajectory name is the recording's ``metadata.trajectory``, else the file stem. A raw
    log is decoded up to the length of the config's trajectory of that name (the SYNC keeps
    running for a few cycles after the last set-point), on the config's SYNC period (in lockstep
    the row times are the cycle times, as the run recorded them), with the PDO layout of its
    sidecar; a log without one only with ``layout`` (:func:`given_layout`, the command line's
    ``--pdo-layout``). The metadata gets ``file`` (the path) and, for a raw log, ``n_targets``
    (the planned cycles). Which current a recording holds (instantaneous or averaged, per axis)
    and the running average behind an averaged one are the recording's own (the run's metadata;
    a log's layout and sidecar): a config whose ``bus.current`` says otherwise is an error.

    Raises:
        RecordingError: unreadable file, a raw log without its layout and none given, or a
            recording that does not fit the config (node-IDs, profiles, drive scaling, current);
            the message names the file, the config and the axis.
    """
    path = Path(path)
    axes = [axis_config(a, current=checks.current) for a in checks.actuators]
    if path.suffix.lower() in RAW_LOG_SUFFIXES:
        name = path.stem
        if not sidecar_path(path).is_file() and layout is None:
            raise RecordingError(
                f"raw CAN log {path}: no {sidecar_path(path).name} beside it with the PDO layout it was recorded with "
                f"(a candump, a log copied without it, or one written before sidecars), and decoded with another "
                f"layout its frames give wrong values marked valid. Give the layout on the command line: "
                f"--pdo-layout {CONFIG_LAYOUT} (the layout {Path(checks.source).name} maps: bus.current "
                f"{checks.current}), --pdo-layout <run>.log.json (the sidecar of a run with the same drives and "
                f"bus.current) or --pdo-layout <recording>.npz (a decoded recording of such a run)")
        given = given_layout(layout, axes, checks.source, checks.current) if layout is not None else None
        layouts, source = (given.layouts, given.source) if given is not None else (None, None)
        period = checks.sync_period
        lockstep_period = period if period is not None and checks.lockstep else None
        cycles = checks.cycles_of(name)
        meta = RecordingMetadata(trajectory=name, file=str(path), sync_period=period, n_targets=cycles)
        rec = decode_log(path, axes, max_cycles=cycles, metadata=meta, lockstep_period=lockstep_period,
                         layouts=layouts, layout_source=source)
        check_log_nodes(path, rec, checks.actuators, checks.source)
    else:
        rec = Recording.load(path)
        rec = dataclasses.replace(rec, metadata=dataclasses.replace(rec.metadata, file=str(path)))
        check_axes(path, rec, checks.actuators, checks.source)
    check_current(path, rec, checks.actuators, checks.current, checks.source)
    return rec.metadata.trajectory or path.stem, rec


@dataclass(frozen=True)
class Gathered:
    """The recordings ``ident-hw identify`` works on (:func:`gather_recordings`): by trajectory
    name; for those read from files made elsewhere, how they were read (``imported``); and the
    notes to print (what a folder gave, what was skipped)."""

    recordings: Mapping[str, Recording]
    imported: Mapping[str, ImportSummary]
    notes: tuple[str, ...]


def gather_recordings(config: Config, given: Sequence[str], layout: str | Path | None = None) -> Gathered:
    """The recordings ``ident-hw identify`` works on: each item ``given`` (``NAME=PATH``: the
    recording of trajectory NAME; a results folder or its ``data/``: its recordings,
    :func:`recording_paths`; else a decoded ``.npz`` or raw log named by its trajectory, or a file
    made elsewhere whose stem is a ``recorded`` trajectory's name), then every ``recorded``
    trajectory of the config not given, from its own file and window. A file given in a recorded
    trajectory's place is read as the config's ``recordings`` section says, whole (its window is
    the config's file's). Returns the recordings by trajectory name, for those read from files made
    elsewhere how they were read, and the notes to print (what a folder gave, what was skipped):
    a :class:`Gathered`.

    Raises:
        RecordingError: an unreadable or mismatched file, two files for one trajectory, a folder
            without recordings, or a file made elsewhere that names no trajectory.
    """
    recordings: dict[str, Recording] = {}
    imported: dict[str, ImportSummary] = {}
    files: dict[str, str] = {}
    notes: list[str] = []
    recorded = {t.name: t for t in config.trajectories if t.recorded}
    checks = RecordingChecks.of(config)

    def keep(name: str, rec: Recording, path) -> None:
        if name in recordings:
            raise RecordingError(f"{files[name]} and {path} are both recordings of trajectory {name!r}: give one "
                                 "(or the results folder: its decoded .npz recordings are used)")
        recordings[name], files[name] = rec, str(path)

    for item in given:
        name, path = _named(item, [t.name for t in config.trajectories], config.source)
        if name is None and (Path(path).is_dir() or Path(path).name.endswith(NOT_RECORDINGS)):
            paths, more = recording_paths([path])
            notes += more
            for found in paths:
                keep(*load_recording(found, checks, layout=layout), found)
            continue
        if name is None and Path(path).suffix.lower() not in RECORDING_SUFFIXES:
            stem = Path(path).stem
            if stem not in recorded:
                raise RecordingError(f"{path}: a file made elsewhere: give it as NAME={path}, NAME one of the "
                                     f"config's trajectories ({', '.join(t.name for t in config.trajectories)})")
            name = stem
        if name is not None and name in recorded:
            external = read_external(config, recorded[name], path, use_window=False)
            imported[name] = external.summary
            keep(name, external.recording, path)
        else:
            loaded, rec = load_recording(path, checks, layout=layout)
            keep(name or loaded, rec, path)
    for name, tcfg in recorded.items():
        if name not in recordings:
            external = read_external(config, tcfg)
            recordings[name], imported[name] = external.recording, external.summary
    return Gathered(recordings, imported, tuple(notes))


def _named(item: str, names: Sequence[str], source: str) -> tuple[str | None, str]:
    """``(NAME, PATH)`` of an argument ``NAME=PATH`` naming one of the config's trajectories
    ``names`` (of the config file ``source``), else ``(None, item)``."""
    name, sep, path = item.partition("=")
    if sep and name in names and not Path(item).exists():
        return name, path
    if sep and not Path(item).exists() and "/" not in name:
        raise RecordingError(f"{item}: no trajectory {name!r} in {source} (its trajectories: {', '.join(names)})")
    return None, item


#: what a results folder's ``data/`` holds beside the recordings, by name or ending (not recordings)
NOT_RECORDINGS = ("drives.json", ".log.json", ".asc.json", ".blf.json")
#: the endings of the files the tool recorded: a decoded recording or a raw CAN log
RECORDING_SUFFIXES = (".npz", *RAW_LOG_SUFFIXES)


def recording_paths(given: Sequence[str | Path]) -> tuple[list[Path], list[str]]:
    """The recording files ``ident-hw identify`` reads, from what the command line gives: a file
    as it is; a folder (a results folder, or its ``data/``) as its recordings, one per trajectory:
    the decoded ``<name>.npz`` the run wrote, else its raw CAN log (``.log``/``.asc``/``.blf``,
    decoded with the config's values). What a results folder holds beside its recordings
    (``drives.json``, the raw logs' ``.json`` sidecars) is skipped, also when given by a shell
    glob, and said. Returns the files and the notes to print.

    Raises:
        RecordingError: a folder without recordings, or a file that is no recording (by its
            ending: ``.npz`` or a raw CAN log), naming it and what is accepted.
    """
    files: list[Path] = []
    notes: list[str] = []
    skipped: list[str] = []
    for item in map(Path, given):
        if item.is_dir():
            folder = item / "data" if (item / "data").is_dir() else item
            found = _folder_recordings(folder)
            if not found:
                raise RecordingError(f"{item}: no recordings in {folder} (decoded .npz or raw CAN logs "
                                     f"{'/'.join(RAW_LOG_SUFFIXES)}); an 'ident-hw identify' results folder keeps "
                                     "none: give the folder of the run that recorded them")
            notes.append(f"{item}: the recordings in {folder}: {', '.join(p.name for p in found)}")
            files += found
        elif item.name.endswith(NOT_RECORDINGS):
            skipped.append(str(item))
        elif item.suffix.lower() not in RECORDING_SUFFIXES:
            raise RecordingError(f"{item}: not a recording (a decoded .npz or a raw CAN log "
                                 f"{'/'.join(RAW_LOG_SUFFIXES)}); to use a results folder's recordings, give the folder")
        else:
            files.append(item)
    if skipped:
        notes.append(f"skipped, not recordings: {', '.join(skipped)}")
    return files, notes


def _folder_recordings(folder: Path) -> list[Path]:
    """One file per trajectory of ``folder``: ``<name>.npz``, else its raw CAN log."""
    chosen: dict[str, Path] = {}
    for path in sorted(folder.iterdir()):
        kind = path.suffix.lower()
        if not path.is_file() or kind not in RECORDING_SUFFIXES:
            continue
        if path.stem not in chosen or kind == ".npz":
            chosen[path.stem] = path
    return [chosen[name] for name in sorted(chosen)]


def recorded_currents(rec: Recording, n_axes: int) -> list[str]:
    """Which current each axis of ``rec`` holds: its axes' own (``metadata.axes``), else the
    recording's ``metadata.current`` for all."""
    if rec.metadata.axes:
        return [a.current for a in rec.metadata.axes]
    return [rec.metadata.current] * n_axes


def check_current(path: Path, rec: Recording, acts: Sequence[ActuatorConfig], current: str, source: str) -> None:
    """The current the recording holds (per axis) is the one the config (the file ``source``, its
    actuators ``acts``) names in ``bus.current`` (``current``): identified as the other kind, an
    averaged current moves the estimates (docs/drives.md, *Which current*), so a disagreement is
    an error, not a choice."""
    differ = [f"{a.name} (node {a.node_id})" for a, kind in zip(acts, recorded_currents(rec, len(acts)))
              if kind != current]
    if differ:
        kinds = sorted(set(recorded_currents(rec, len(acts))))
        raise RecordingError(f"{path} holds the {' and '.join(kinds)} current of {', '.join(differ)}, "
                             f"{source} says bus.current: {current}. Identify with the run's own config "
                             f"(config.yaml of its results folder), or set bus.current to what the recording holds")


def check_axes(path: Path, rec: Recording, acts: Sequence[ActuatorConfig], source: str) -> None:
    """The axes a decoded recording was made with (``metadata.axes``) are the config's actuators
    ``acts`` (of the config file ``source``): same node-IDs, profiles and drive scaling. A
    recording without them is not checked."""
    recorded = rec.metadata.axes
    if not recorded:
        return
    if len(recorded) != len(acts):
        raise RecordingError(f"{path}: recorded with {len(recorded)} axes, {source} has {len(acts)}")
    nodes = [f"{a.name} on node {r.node_id} (config: node {a.node_id})"
             for a, r in zip(acts, recorded) if r.node_id != a.node_id]
    if nodes:
        raise RecordingError(f"{path} was recorded from other nodes than {source} configures: "
                             f"{'; '.join(nodes)}. Identify with the run's own config (config.yaml of its "
                             "results folder)")
    differ = []
    for act, r in zip(acts, recorded):
        if r.profile.lower() != (act.profile or ""):
            differ.append(f"{act.name} (node {act.node_id}) profile {r.profile!r} (config: {act.profile!r})")
        mine = axis_scaling(act)
        for key in SCALING_FIELDS:
            theirs, ours = getattr(r.scaling, key), getattr(mine, key)
            if not _same(theirs, ours):
                differ.append(f"{act.name} (node {act.node_id}) {key} = {theirs} (config: {ours})")
    if differ:
        raise RecordingError(
            f"{path} was converted to SI units with other drive data than {source}: {'; '.join(differ)}. "
            "Identify with the run's own config (config.yaml of its results folder), or from the raw CAN log "
            "of the run, which is decoded with this config's values")


def check_log_nodes(path: Path, rec: Recording, acts: Sequence[ActuatorConfig], source: str) -> None:
    """Every configured node (of the actuators ``acts`` of the config file ``source``) has samples
    in a decoded raw log (else the log is of other nodes, or holds no streaming at all)."""
    heard = list(rec.metadata.nodes_heard)
    if not len(rec.t):
        raise RecordingError(f"{path}: no SYNC cycle of the configured nodes in the log (nodes heard: "
                             f"{heard or 'none'})")
    received = np.asarray(identification_valid(rec).any(axis=0))
    silent = [f"node {a.node_id} ({a.name})" for a, any_valid in zip(acts, received) if not any_valid]
    if silent:
        raise RecordingError(f"{path}: no sample of {', '.join(silent)} configured in {source}; the log "
                             f"holds frames of nodes {heard or 'none'}")


def _same(a, b) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(a, b, rel_tol=1e-9)
    return a == b
