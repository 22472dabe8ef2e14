"""Saving and loading trajectories as CSV (human-readable, hand-editable) or NPZ, for any robot:
the columns are its actuators' (their names and units) and its pose's.

CSV layout (``v2``)::

    # ident_hw trajectory v2
    # name: excitation
    # metadata: {"generator": "joint_excitation", ...}     (JSON on one line)
    # actuators: shoulder[rad],elbow[rad]                   (the robot's, in actuator order)
    # pose: 2                                               (its pose's coordinates)
    t[s],X1,X2,Xd1,Xd2,Xdd1,Xdd2,shoulder[rad],elbow[rad],shoulderd[rad/s],...,elbowdd[rad/s^2]
    0,0.0,...

A file of the first version (``v1``, still read) holds the 3PRRR's columns, named (``x[m],
y[m], alpha[rad]``, ``theta1[rad]`` .. ``zeta3[m]``, :data:`trajectories.trajectory.COLUMNS`);
:func:`save` writes one where it is given those actuators (:data:`THREE_PRRR_ACTUATORS`, the
default). An ``.npz`` holds the same arrays, and ``actuators`` where it is of v2. Values are
written with 17 significant digits, so a save/load round trip is exact.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .trajectory import COLUMNS, Trajectory

MAGIC = "# ident_hw trajectory v1"
MAGIC_V2 = "# ident_hw trajectory v2"
HEADER = [f"{name}[{unit}]" for cols in COLUMNS.values() for name, unit in cols]
#: the 3PRRR's actuators and their units: what a file of the first version holds
THREE_PRRR_ACTUATORS: tuple[tuple[str, str], ...] = tuple(COLUMNS["Theta"])
_DERIVATIVE_UNITS = ("", "/s", "/s^2")


class TrajectoryFileError(ValueError):
    """A trajectory file is malformed; the message names the file and what is wrong."""


@dataclass(frozen=True)
class TrajectoryFile:
    """What a trajectory file holds: the trajectory and the actuators its columns name (name,
    unit of position), in its order."""

    trajectory: Trajectory
    actuators: tuple[tuple[str, str], ...]

    @property
    def actuator_names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.actuators)


def _v2_header(actuators: Sequence[tuple[str, str]], pose: int) -> list[str]:
    """The column names of a v2 file of these actuators and a pose of ``pose`` coordinates."""
    head = ["t[s]"] + [f"{key}{i}" for key in ("X", "Xd", "Xdd") for i in range(1, pose + 1)]
    for suffix, per_s in zip(("", "d", "dd"), _DERIVATIVE_UNITS):
        head += [f"{name}{suffix}[{unit}{per_s}]" for name, unit in actuators]
    return head


def save(traj: Trajectory, path: str | Path, actuators: Sequence[tuple[str, str]] = THREE_PRRR_ACTUATORS) -> Path:
    """Write ``traj`` to ``path`` (``.csv`` or ``.npz``); returns the path. ``actuators``: the
    robot's actuators (name, unit of position: ``rad``, ``m``) in actuator order (the 3PRRR's:
    a file of the first version)."""
    path = Path(path)
    actuators = tuple((str(n), str(u)) for n, u in actuators)
    if traj.Theta.shape[1] != len(actuators):
        raise ValueError(f"trajectory {traj.name!r} moves {traj.Theta.shape[1]} actuators, the file's columns name "
                         f"{len(actuators)} ({', '.join(n for n, _ in actuators)})")
    first = actuators == THREE_PRRR_ACTUATORS and traj.X.shape[1] == len(COLUMNS["X"])
    arrays: dict[str, Any] = {key: getattr(traj, key) for key in COLUMNS}
    if "\n" in traj.name:
        raise ValueError(f"trajectory name {traj.name!r} must fit on one line")
    if path.suffix == ".npz":
        extra: dict[str, Any] = {} if first else {"actuators": np.array([f"{n}[{u}]" for n, u in actuators])}
        np.savez(path, name=traj.name, metadata=json.dumps(traj.metadata), **arrays, **extra)
    elif path.suffix == ".csv":
        table = np.column_stack([a.reshape(len(traj.t), -1) for a in arrays.values()])
        with path.open("w", encoding="utf-8") as f:
            if first:
                f.write(f"{MAGIC}\n# name: {traj.name}\n# metadata: {json.dumps(traj.metadata)}\n")
                f.write(",".join(HEADER) + "\n")
            else:
                f.write(f"{MAGIC_V2}\n# name: {traj.name}\n# metadata: {json.dumps(traj.metadata)}\n"
                        f"# actuators: {','.join(f'{n}[{u}]' for n, u in actuators)}\n# pose: {traj.X.shape[1]}\n")
                f.write(",".join(_v2_header(actuators, traj.X.shape[1])) + "\n")
            np.savetxt(f, table, fmt="%.17g", delimiter=",")
    else:
        raise ValueError(f"{path}: unknown trajectory file type {path.suffix!r} (use .csv or .npz)")
    return path


def load(path: str | Path) -> Trajectory:
    """Read a trajectory written by :func:`save` (or edited by hand); :func:`read` also says
    which actuators its columns name.

    Raises:
        TrajectoryFileError: naming the file and the line, column or key that is wrong.
    """
    return read(path).trajectory


def read(path: str | Path) -> TrajectoryFile:
    """A trajectory file's trajectory and the actuators its columns name (:class:`TrajectoryFile`).

    Raises:
        TrajectoryFileError: naming the file and the line, column or key that is wrong.
    """
    path = Path(path)
    if not path.is_file():
        raise TrajectoryFileError(f"{path}: no such trajectory file")
    if path.suffix == ".npz":
        return _load_npz(path)
    if path.suffix == ".csv":
        return _load_csv(path)
    raise TrajectoryFileError(f"{path}: unknown trajectory file type {path.suffix!r} (use .csv or .npz)")


def _actuators(path: Path, text: str) -> tuple[tuple[str, str], ...]:
    """``name[unit],...`` of a v2 file's ``actuators`` line."""
    out = []
    for item in (x.strip() for x in text.split(",")):
        name, sep, unit = item.partition("[")
        if not sep or not unit.endswith("]") or not name:
            raise TrajectoryFileError(f"{path}: actuators: expected name[unit], got {item!r}")
        out.append((name, unit[:-1]))
    return tuple(out)


def _build(path: Path, name: str, metadata: dict, arrays: dict[str, np.ndarray],
           actuators: tuple[tuple[str, str], ...]) -> TrajectoryFile:
    width = {"X": None, "Theta": len(actuators)}
    for key in COLUMNS:
        shape = np.shape(arrays[key])
        family = "Theta" if key.startswith("Theta") else "X"
        if key == "t":
            continue
        if len(shape) != 2 or (width[family] is not None and shape[1] != width[family]):
            raise TrajectoryFileError(f"{path}: {key} has shape {shape}, expected (N, {width[family]})")
        width[family] = shape[1]
    try:
        return TrajectoryFile(Trajectory(name=name, metadata=metadata, **arrays), actuators)
    except ValueError as exc:
        raise TrajectoryFileError(f"{path}: {exc}") from None


def _load_npz(path: Path) -> TrajectoryFile:
    try:
        data = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise TrajectoryFileError(f"{path}: not a readable NPZ file ({exc})") from None
    with data:
        missing = [key for key in ["name", "metadata", *COLUMNS] if key not in data.files]
        if missing:
            raise TrajectoryFileError(f"{path}: missing array(s) {', '.join(missing)}")
        arrays = {key: data[key] for key in COLUMNS}
        name, meta = str(data["name"]), str(data["metadata"])
        actuators = (_actuators(path, ",".join(str(a) for a in data["actuators"])) if "actuators" in data.files
                     else THREE_PRRR_ACTUATORS)
    return _build(path, name, _parse_metadata(path, meta), arrays, actuators)


def _parse_metadata(path: Path, text: str) -> dict:
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as exc:
        raise TrajectoryFileError(f"{path}: metadata is not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise TrajectoryFileError(f"{path}: metadata must be a JSON object, got {type(meta).__name__}")
    return meta


def _load_csv(path: Path) -> TrajectoryFile:
    lines = path.read_text(encoding="utf-8").splitlines()
    if not lines or lines[0].strip() not in (MAGIC, MAGIC_V2):
        raise TrajectoryFileError(f"{path}, line 1: expected {MAGIC_V2!r} (or {MAGIC!r}), "
                                  f"found {lines[0] if lines else ''!r}")
    second = lines[0].strip() == MAGIC_V2
    fields: dict[str, str] = {}
    row = 1
    while row < len(lines) and lines[row].startswith("#"):
        key, sep, value = lines[row][1:].strip().partition(":")
        if sep:
            fields[key.strip()] = value.strip()
        row += 1
    for key in ("name", "metadata") + (("actuators", "pose") if second else ()):
        if key not in fields:
            raise TrajectoryFileError(f"{path}: header has no '# {key}:' line")
    if row >= len(lines):
        raise TrajectoryFileError(f"{path}: no column header line")
    actuators, pose = THREE_PRRR_ACTUATORS, len(COLUMNS["X"])
    expected = HEADER
    if second:
        actuators = _actuators(path, fields["actuators"])
        try:
            pose = int(fields["pose"])
        except ValueError:
            raise TrajectoryFileError(f"{path}: pose: expected the number of pose coordinates, "
                                      f"got {fields['pose']!r}") from None
        expected = _v2_header(actuators, pose)
    header = [h.strip() for h in lines[row].split(",")]
    if header != expected:
        missing = [h for h in expected if h not in header]
        extra = [h for h in header if h not in expected]
        detail = f"missing {missing}" if missing else f"unexpected {extra}" if extra else "columns out of order"
        raise TrajectoryFileError(f"{path}, line {row + 1}: bad column header ({detail}); expected {','.join(expected)}")
    table = _table(path, lines, row, expected)
    widths = {"t": 1, "X": pose, "Xd": pose, "Xdd": pose, "Theta": len(actuators), "Thetad": len(actuators),
              "Thetadd": len(actuators)}
    arrays, col = {}, 0
    for key in COLUMNS:
        arrays[key] = table[:, col] if key == "t" else table[:, col:col + widths[key]]
        col += widths[key]
    return _build(path, fields["name"], _parse_metadata(path, fields["metadata"]), arrays, actuators)


def _table(path: Path, lines: list[str], row: int, header: list[str]) -> np.ndarray:
    """The data rows after the column header (line ``row``, 0-based) as an array."""
    table = []
    for number, line in enumerate(lines[row + 1:], start=row + 2):
        if not line.strip():
            continue
        cells = line.split(",")
        if len(cells) != len(header):
            raise TrajectoryFileError(f"{path}, line {number}: {len(cells)} values, expected {len(header)}")
        try:
            table.append([float(c) for c in cells])
        except ValueError:
            bad = next(i for i, c in enumerate(cells) if not _is_float(c))
            raise TrajectoryFileError(
                f"{path}, line {number}, column {header[bad]}: {cells[bad].strip()!r} is not a number"
            ) from None
    if not table:
        raise TrajectoryFileError(f"{path}: no data rows")
    return np.array(table)


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
