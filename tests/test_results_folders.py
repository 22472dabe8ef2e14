"""ident_hw.experiment.folders: a results folder belongs to one run, also when runs start at once."""

from __future__ import annotations

import threading
from pathlib import Path

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
