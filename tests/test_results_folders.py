"""ident_hw.experiment.folders: a results folder belongs to one run, also when runs start at once."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest

from ident_hw.config import load_config
from ident_hw.experiment import folders
from ident_hw.experiment.folders import new_results_folder

SIM = Path(__file__).resolve().parents[1] / "configs" / "sim-3prrr.yaml"


def config_in(folder: Path):
    path = folder / "job.yaml"
    path.write_text(f"extends: {SIM}\noutput: {{dir: {folder / 'results'}}}\n")
    return load_config(path)


def test_runs_started_in_the_same_second_get_folders_of_their_own(tmp_path, monkeypatch):
    """Eight threads ask for the default folder at once, with the clock stopped on one second:
    eight folders, each with its own STATUS and config copy, numbered after the first."""
    config = config_in(tmp_path)
    monkeypatch.setattr(folders.time, "strftime", lambda fmt: "20261125-120000")
    start, got = threading.Barrier(8), []

    def claim():
        start.wait()
        got.append(new_results_folder(config, None, "run"))
    threads = [threading.Thread(target=claim) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    names = sorted(p.name for p in got)
    assert names == sorted(["run-20261125-120000"] + [f"run-20261125-120000-{n}" for n in range(2, 9)])
    for folder in got:
        assert (folder / "STATUS").read_text() == "running\n"
        assert (folder / "config.yaml").is_file() and (folder / "data").is_dir()


def test_an_out_folder_holding_results_is_refused_and_left_alone(tmp_path):
    config = config_in(tmp_path)
    first = new_results_folder(config, tmp_path / "out", "run")
    (first / "STATUS").write_text("complete\n")
    with pytest.raises(FileExistsError, match="already holds results; choose another --out"):
        new_results_folder(config, tmp_path / "out", "run")
    assert (first / "STATUS").read_text() == "complete\n"


def test_a_folder_keeps_the_files_its_trajectories_are_read_from_and_its_config_reads_them(tmp_path):
    """The Stewart's excitation is read from a sines file beside the config: the results folder
    keeps a copy under trajectories/ and its config.yaml names the copy, so the folder's config
    builds the same trajectory anywhere (before, it named the file relative to a folder that did
    not hold it). The validation (drawn, no file) and the description are as before; a run that
    could not start removes the copies with the folder."""
    from ident_hw.experiment.plan import plan
    source = Path(__file__).parents[1] / "configs" / "sim-stewart.yaml"
    config = load_config(source)
    folder = new_results_folder(config, tmp_path / "run", "run")
    copy = load_config(folder / "config.yaml")
    original = {t.name: t for t in config.trajectories}
    for t in copy.trajectories:
        if original[t.name].path is None:
            assert t.path is None
            continue
        assert Path(t.path) == folder / "trajectories" / f"{t.name}.json"
        assert Path(t.path).read_bytes() == Path(original[t.name].path).read_bytes()
    assert Path(copy.robot.description) == folder / "description" / "stewart.xml"
    mine, theirs = plan(config, ["excitation"])[0], plan(copy, ["excitation"])[0]
    assert mine.ok and theirs.ok and np.array_equal(mine.trajectory.Theta, theirs.trajectory.Theta)
    # a run that could not start leaves nothing behind, the copies included
    assert folders.discard_unused(folder) and not folder.exists()
