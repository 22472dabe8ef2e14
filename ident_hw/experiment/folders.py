"""Creating a results folder: a fresh timestamped directory with STATUS and the config copy;
removing it again when the run could not start."""

from __future__ import annotations

import time
from pathlib import Path

from ident_hw.config import Config, resolved_yaml
from ident_hw.results import mark_status


def new_results_folder(config: Config, out: str | Path | None, label: str) -> Path:
    """``out`` if given (must not hold results already), else ``<output.dir>/<label>-<timestamp>``.

    Writes STATUS ``running`` and ``config.yaml`` (the config with its bases merged in).
    """
    if out is None:
        out = Path(config.output.dir) / f"{label}-{time.strftime('%Y%m%d-%H%M%S')}"
    folder = Path(out)
    if (folder / "STATUS").exists():
        raise FileExistsError(f"{folder} already holds results; choose another --out")
    (folder / "data").mkdir(parents=True, exist_ok=True)
    mark_status(folder, "running")
    (folder / "config.yaml").write_text(resolved_yaml(config.source))
    return folder


def discard_unused(folder: Path) -> bool:
    """Remove what :func:`new_results_folder` wrote into ``folder`` (STATUS, config.yaml, an
    empty data/) and the folder if that leaves it empty: a run that could not start (its bus
    would not open) leaves no results folder behind. Anything else in it stays. True if the
    folder is gone."""
    folder = Path(folder)
    data = folder / "data"
    if data.is_dir() and any(data.iterdir()):
        return False
    for name in ("STATUS", "config.yaml"):
        (folder / name).unlink(missing_ok=True)
    for path in (data, folder):
        try:
            path.rmdir()
        except OSError:
            return False
    return True
