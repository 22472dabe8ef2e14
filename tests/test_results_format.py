"""The files of results and study folders: one declarative way to store records (:mod:`ident_hw.storage`),
a format version in every file, and the folders of before it (format 0) read the same.

``tests/data/format-0`` holds files written by the code of before the version (main at 53f039f):
the main job's ``parameters.json`` (and its ``drives.json``), the UR10e's from its own recordings
(imported files, friction constants chosen, a set compared, notes and checks not judged), its
drive gains' (a ``gains`` step), the planar 2R's online run (the model comparison), and a study's
``study.json`` and run file (the paths of this machine in them renamed). Each is read and written
again byte for byte but for its version, and reads into the objects the report uses."""

from __future__ import annotations

import dataclasses
import gzip
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from ident_hw.experiment.runner import DriveStates, read_drive_states
from ident_hw.records import BaseStep, GainsStep, MassFitStep, Thresholds
from ident_hw.results import ResultsFile, load_fit, load_online, load_results, save_results
from ident_hw.results.study import RunOutcome, StudyFile
from ident_hw.storage import FORMAT, file_document, from_json, of_document, read_file, stored, to_json, write_file

FORMAT_0 = Path(__file__).parent / "data" / "format-0"
FOLDERS = ("main-job", "ur10e", "ur10e-gains", "sim-2r-online")


def _document(name: str) -> dict:
    return json.loads(gzip.decompress((FORMAT_0 / name / "parameters.json.gz").read_bytes()))


def _folder(name: str, into: Path) -> Path:
    """The format-0 folder ``name`` as a results folder in ``into``: its parameters.json, STATUS
    and a fit and an online trace written as that code wrote them (no ``format`` array)."""
    folder = into / name
    (folder / "fits").mkdir(parents=True)
    (folder / "parameters.json").write_bytes(gzip.decompress((FORMAT_0 / name / "parameters.json.gz").read_bytes()))
    shutil.copy(FORMAT_0 / name / "STATUS", folder / "STATUS")
    doc = _document(name)
    a = len(doc["actuators"])
    t = np.arange(20) * 0.004
    np.savez_compressed(folder / "fits" / "probe.npz", name="probe", role="identification", t=t,
                        tau=np.ones((20, a)), tau_model=np.ones((20, a)), Theta=np.zeros((20, a)))
    return folder


@pytest.mark.parametrize("name", FOLDERS)
def test_a_parameters_json_of_format_0_is_written_again_byte_for_byte_but_its_version(name):
    """Every key of today's files is a field of a record, in the order written: reading a file
    and writing its record gives the same bytes, with ``"format": 1`` first."""
    doc = _document(name)
    assert "format" not in doc
    again = file_document(of_document(ResultsFile, doc, name))
    assert list(again)[0] == "format" and again["format"] == FORMAT == 1
    assert json.dumps(again, indent=2) == json.dumps({"format": FORMAT, **doc}, indent=2)


@pytest.mark.parametrize("name", FOLDERS)
def test_a_folder_of_format_0_loads_and_saves_the_same_results(name, tmp_path):
    """load_results reads a format-0 folder (and its fits and online trace without a version) into
    the objects the report uses; saving them gives back every key of its parameters.json (but
    ``validation``, which the folder's fits give: here a probe of the fits' old format)."""
    folder = _folder(name, tmp_path)
    results = load_results(folder)
    doc = _document(name)
    assert results.actuators == tuple(a["name"] for a in doc["actuators"])
    assert [r.name for r in results.parameter_rows()] == [r["name"] for r in doc["parameters"]]
    assert results.quality is not None and results.quality.passed == doc["quality"]["passed"]
    assert [type(s) for s in results.steps] == [
        GainsStep if s.get("drive_gains") else BaseStep if "eliminated" in s else MassFitStep for s in doc["steps"]]
    assert results.fits[0].name == "probe" and results.fits[0].tau.shape == (20, len(results.actuators))
    saved = json.loads((save_results(tmp_path / "again", results) / "parameters.json").read_text())
    assert saved.pop("format") == FORMAT
    saved.pop("validation", None)
    doc.pop("validation", None)
    assert saved == doc
    assert load_fit(tmp_path / "again" / "fits" / "probe.npz").role == "identification"


def test_what_each_format_0_folder_holds_reads_into_its_records(tmp_path):
    """Spot checks of the typed values read: the main job's base fit and consistent set, the
    UR10e's imported recordings, friction grid and verdict notes, the gains step's figures, the
    2R's model comparison, and a verdict's thresholds under the results' own names."""
    main = load_results(_folder("main-job", tmp_path))
    assert main.base_fit is not None and len(main.base_fit.expressions) == 18 and main.base_fit.covariance is None
    assert main.consistent is not None and main.consistent.reproduces_base and main.consistent.bodies[0].body == "carriage"
    assert main.quality is not None and main.quality.thresholds == Thresholds()
    assert main.quality.steps["base"].cond_scaled is not None
    ur = load_results(_folder("ur10e", tmp_path))
    assert ur.friction is not None and set(ur.friction.tried) == {"presliding", "stribeck"}
    assert ur.friction.tried["stribeck"].values and ur.compared_label
    imported = ur.trajectories["excitation"].imported
    assert imported is not None and imported.rows_used == 2860 and imported.window == "rows 635..3510"
    assert ur.quality is not None and ur.quality.notes and ur.quality.not_judged
    gains = next(s for s in load_results(_folder("ur10e-gains", tmp_path)).steps if isinstance(s, GainsStep))
    assert len(gains.drive_gains.gains) == 6 and gains.drive_gains.payload_mass > 0
    two = load_results(_folder("sim-2r-online", tmp_path))
    assert two.model_comparison is not None and [f.model for f in two.model_comparison.fits] == [
        "dynamic", "power", "energy"]
    assert two.model_comparison.fits[0].H.shape == (len(two.model_comparison.fits[0].expressions), len(two.parameters.names))


def test_a_study_folder_and_drive_states_of_format_0(tmp_path):
    """A study's run file and ``study.json``, and a run's ``drives.json``, of before the version:
    read, and written again with it."""
    run = read_file(RunOutcome, FORMAT_0 / "study" / "runs" / "run-0000.json")
    assert run.index == 0 and run.error is None and run.estimates and all(
        e.dof is None or math.isfinite(e.dof) for e in run.estimates)
    write_file(tmp_path / "run.json", run, indent=1)
    written = json.loads((tmp_path / "run.json").read_text())
    original = json.loads((FORMAT_0 / "study" / "runs" / "run-0000.json").read_text())
    assert list(written)[0] == "format" and {k: v for k, v in written.items() if k != "format"} == original
    study = read_file(StudyFile, FORMAT_0 / "study" / "study.json")
    assert study.runs_finished == 2 and study.summary and study.summary[0].kind in ("physical", "base")
    assert to_json(study) == json.loads((FORMAT_0 / "study" / "study.json").read_text())
    shutil.copy(FORMAT_0 / "main-job" / "drives.json", tmp_path / "drives.json")
    states = read_drive_states(tmp_path)
    assert isinstance(states, DriveStates) and set(states.master) and states.rig is not None


def test_a_file_of_a_newer_format_is_refused_naming_it(tmp_path):
    doc = {"format": FORMAT + 1, **_document("main-job")}
    (tmp_path / "parameters.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=rf"parameters.json: format {FORMAT + 1}, newer than this ident_hw's"):
        load_results(tmp_path)
    np.savez(tmp_path / "fit.npz", format=FORMAT + 1, name="x", role="identification", t=np.zeros(2),
             tau=np.zeros((2, 1)), tau_model=np.zeros((2, 1)), Theta=np.zeros((2, 1)))
    with pytest.raises(ValueError, match="fit.npz: format"):
        load_fit(tmp_path / "fit.npz")


def test_an_online_trace_of_format_0_loads(tmp_path):
    """online.npz as the code of before wrote it (no version array)."""
    t = np.arange(5.0)
    np.savez_compressed(tmp_path / "online.npz", names=np.array(["a", "b"]), t=t, estimators=np.array(["SVD-DLS"]),
                        j_rmse=np.array([1.5]), rank=np.zeros(0), base_names=np.array(["a"]), H=np.ones((1, 2)),
                        truth=np.zeros((0, 0)), change_time=np.nan, unexcited=np.array([]),
                        diverged=np.array([np.nan]), estimates_0=np.ones((5, 2)))
    trace = load_online(tmp_path / "online.npz")
    assert trace.j_rmse == {"SVD-DLS": 1.5} and trace.change_time is None and trace.truth is None


# ----------------------------------------------------------------------------- the storage itself
@dataclasses.dataclass(frozen=True)
class _Inner:
    x: float
    note: str | None = dataclasses.field(default=None, metadata=stored(lambda v: v is None))


@dataclasses.dataclass(frozen=True)
class _Outer:
    name: str
    values: tuple[float, ...]
    inner: _Inner
    table: dict[str, _Inner]
    matrix: np.ndarray
    derived: float = dataclasses.field(default=0.0, metadata=stored(store=False))
    shown: int = dataclasses.field(default=0, metadata=stored(record=lambda r: r.name == "hidden"))


def test_a_record_s_keys_are_its_fields_and_it_reads_back():
    """Keys in field order, nested records, tuples, mappings and arrays; a key left out by its
    rule (of the value, of the record) or never stored reads as its default; NaN and infinities
    as Python's json writes them."""
    outer = _Outer("a", (1.0, math.inf), _Inner(2.0, "n"), {"k": _Inner(math.nan)}, np.eye(2), derived=5.0, shown=3)
    doc = to_json(outer)
    assert list(doc) == ["name", "values", "inner", "table", "matrix", "shown"]
    assert doc["table"] == {"k": {"x": doc["table"]["k"]["x"]}} and math.isnan(doc["table"]["k"]["x"])
    back = from_json(_Outer, json.loads(json.dumps(doc)))
    assert back.values == (1.0, math.inf) and back.inner == _Inner(2.0, "n") and back.derived == 0.0
    np.testing.assert_array_equal(back.matrix, np.eye(2))
    assert "shown" not in to_json(dataclasses.replace(outer, name="hidden"))
    with pytest.raises(ValueError, match=r"inner.x: expected a number, got 'two'"):
        from_json(_Outer, {**doc, "inner": {"x": "two"}})
    with pytest.raises(ValueError, match="missing key 'matrix'"):
        from_json(_Outer, {k: v for k, v in doc.items() if k != "matrix"})
