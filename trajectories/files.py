"""Saving and loading trajectories as CSV (human-readable, hand-editable) or NPZ.

CSV layout::

    # ident_hw trajectory v1
    # name: square-1
    # metadata: {"generator": "square", ...}        (JSON on one line)
    t[s],x[m],y[m],alpha[rad],xd[m/s],...,zeta3dd[m/s^2]
    0,0.0,...

Values are written with 17 significant digits, so a save/load round trip is exact.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .trajectory import COLUMNS, Trajectory

MAGIC = "# ident_hw trajectory v1"
HEADER = [f"{name}[{unit}]" for cols in COLUMNS.values() for name, unit in cols]


class TrajectoryFileError(ValueError):
    """A trajectory file is malformed; the message names the file and what is wrong."""


def save(traj: Trajectory, path: str | Path) -> Path:
    """Write ``traj`` to ``path`` (``.csv`` or ``.npz``); returns the path."""
    path = Path(path)
    arrays = {key: getattr(traj, key) for key in COLUMNS}
    wrong = [key for key, cols in COLUMNS.items() if key != "t" and arrays[key].shape[1] != len(cols)]
    if wrong:
        raise ValueError(f"trajectory {traj.name!r}: the file format holds the 3PRRR's columns; "
                         f"{wrong[0]} has {arrays[wrong[0]].shape[1]}")
    if path.suffix == ".npz":
        np.savez(path, name=traj.name, metadata=json.dumps(traj.metadata), **arrays)
    elif path.suffix == ".csv":
        table = np.column_stack([a.reshape(len(traj.t), -1) for a in arrays.values()])
        if "\n" in traj.name:
            raise ValueError(f"trajectory name {traj.name!r} must fit on one line")
        with path.open("w", encoding="utf-8") as f:
            f.write(f"{MAGIC}\n# name: {traj.name}\n# metadata: {json.dumps(traj.metadata)}\n")
            f.write(",".join(HEADER) + "\n")
            np.savetxt(f, table, fmt="%.17g", delimiter=",")
    else:
        raise ValueError(f"{path}: unknown trajectory file type {path.suffix!r} (use .csv or .npz)")
    return path


def load(path: str | Path) -> Trajectory:
    """Read a trajectory written by :func:`save` (or edited by hand).

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


def _build(path: Path, name: str, metadata: dict, arrays: dict[str, np.ndarray]) -> Trajectory:
    for key, cols in COLUMNS.items():
        shape = np.shape(arrays[key])
        if key != "t" and (len(shape) != 2 or shape[1] != len(cols)):
            raise TrajectoryFileError(f"{path}: {key} has shape {shape}, expected (N, {len(cols)})")
    try:
        return Trajectory(name=name, metadata=metadata, **arrays)
    except ValueError as exc:
        raise TrajectoryFileError(f"{path}: {exc}") from None


def _load_npz(path: Path) -> Trajectory:
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
    return _build(path, name, _parse_metadata(path, meta), arrays)


def _parse_metadata(path: Path, text: str) -> dict:
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as exc:
        raise TrajectoryFileError(f"{path}: metadata is not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise TrajectoryFileError(f"{path}: metadata must be a JSON object, got {type(meta).__name__}")
    return meta


def _load_csv(path: Path) -> Trajectory:
    lines = path.read_text(encoding="utf-8").splitlines()
    if not lines or lines[0].strip() != MAGIC:
        raise TrajectoryFileError(f"{path}, line 1: expected {MAGIC!r}, found {lines[0] if lines else ''!r}")
    fields: dict[str, str] = {}
    row = 1
    while row < len(lines) and lines[row].startswith("#"):
        key, sep, value = lines[row][1:].strip().partition(":")
        if sep:
            fields[key.strip()] = value.strip()
        row += 1
    for key in ("name", "metadata"):
        if key not in fields:
            raise TrajectoryFileError(f"{path}: header has no '# {key}:' line")
    if row >= len(lines):
        raise TrajectoryFileError(f"{path}: no column header line")
    header = [h.strip() for h in lines[row].split(",")]
    if header != HEADER:
        missing = [h for h in HEADER if h not in header]
        extra = [h for h in header if h not in HEADER]
        detail = f"missing {missing}" if missing else f"unexpected {extra}" if extra else "columns out of order"
        raise TrajectoryFileError(f"{path}, line {row + 1}: bad column header ({detail}); expected {','.join(HEADER)}")
    table = []
    for number, line in enumerate(lines[row + 1:], start=row + 2):
        if not line.strip():
            continue
        cells = line.split(",")
        if len(cells) != len(HEADER):
            raise TrajectoryFileError(f"{path}, line {number}: {len(cells)} values, expected {len(HEADER)}")
        try:
            table.append([float(c) for c in cells])
        except ValueError:
            bad = next(i for i, c in enumerate(cells) if not _is_float(c))
            raise TrajectoryFileError(
                f"{path}, line {number}, column {HEADER[bad]}: {cells[bad].strip()!r} is not a number"
            ) from None
    if not table:
        raise TrajectoryFileError(f"{path}: no data rows")
    data = np.array(table)
    arrays, col = {}, 0
    for key, cols in COLUMNS.items():
        arrays[key] = data[:, col] if key == "t" else data[:, col:col + len(cols)]
        col += len(cols)
    return _build(path, fields["name"], _parse_metadata(path, fields["metadata"]), arrays)


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
