"""No record is changed after it is built (issue 49): every dataclass of the three packages is
frozen but the emulated drive's own running state, and a recording's arrays are read-only."""
from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from drivers.recording import Recording, RecordingMetadata

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ident_hw", "drivers", "trajectories")
#: dataclasses that are state, not records: what an emulated drive changes every SYNC period
MUTABLE_STATE = {"drivers/sim/modes.py:Demand", "drivers/sim/pdo.py:Pdo"}


def _dataclass_frozen(node: ast.ClassDef) -> bool | None:
    """True/False for a ``@dataclass``/``@dataclass(frozen=...)`` class, None for another class."""
    for deco in node.decorator_list:
        call = deco if isinstance(deco, ast.Call) else None
        name = ast.unparse(call.func if call else deco)
        if name.split(".")[-1] != "dataclass":
            continue
        return any(k.arg == "frozen" and isinstance(k.value, ast.Constant) and k.value.value is True
                   for k in (call.keywords if call else ()))
    return None


def test_every_dataclass_is_frozen_but_the_drives_running_state():
    mutable = set()
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.ClassDef) and _dataclass_frozen(node) is False:
                    mutable.add(f"{path.relative_to(ROOT).as_posix()}:{node.name}")
    assert mutable == MUTABLE_STATE


def _recording(n: int = 4, axes: int = 2) -> Recording:
    t = np.arange(n) * 0.01
    return Recording(t=t, cycle=np.arange(n), position=np.zeros((n, axes)), velocity=np.zeros((n, axes)),
                     current=np.zeros((n, axes)), statusword=np.zeros((n, axes), dtype=np.int32),
                     target=np.zeros((n, axes)), valid=np.ones((n, axes), dtype=bool), metadata=RecordingMetadata())


def test_a_recording_is_built_once_and_leaves_the_callers_arrays_alone():
    position = np.zeros((4, 2))
    rec = dataclasses.replace(_recording(), position=position)
    with pytest.raises(dataclasses.FrozenInstanceError):
        rec.target = np.ones((4, 2))       # type: ignore[misc]
    for name in ("t", "position", "valid", "current_valid"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(rec, name)[0] = 1
    position[0, 0] = 5.0                   # the caller's array is its own, still writable
    assert rec.position[0, 0] == 5.0       # (a view: no copy of a long recording)
    assert np.array_equal(rec.current_valid, rec.valid) and rec.current_valid is not rec.valid


def test_sent_setpoints_make_a_new_recording(tmp_path):
    from drivers.axis import AxisConfig
    from drivers.recording import with_sent_setpoints
    from drivers.units import AxisScaling

    scaling = AxisScaling(kind="revolute", counts_per_turn=1000, torque_constant=0.05)
    axes = [AxisConfig(name=f"a{i}", node_id=i + 1, profile="epos4", scaling=scaling, position_min=-10.0,
                       position_max=10.0, max_velocity=1.0, max_current=1.0, following_error_window=0.1)
            for i in range(2)]
    rec = _recording()
    sent = with_sent_setpoints(rec, np.full((4, 2), 500), axes)
    assert sent is not rec and sent.metadata.setpoints == "sent"
    assert np.allclose(sent.target, np.pi) and not rec.target.any()    # 500 of 1000 counts a turn: π rad
    assert rec.metadata.setpoints != "sent"
    saved = Recording.load(sent.save(tmp_path / "r.npz"))
    assert np.array_equal(saved.target, sent.target)
