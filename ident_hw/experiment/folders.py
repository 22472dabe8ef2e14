"""Creating a results folder: a fresh timestamped directory with STATUS and the config copy;
removing it again when the run could not start."""

from __future__ import annotations

import shutil
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from ident_hw.config import Config, RobotConfig, TrajectoryConfig, resolved_yaml
from ident_hw.config.robots import DESCRIPTION_KEY
from ident_hw.results import STATUS_FILE, mark_status


#: the folder of a results folder that holds the robot's description file (a described robot)
DESCRIPTION_DIR = "description"
#: where a results folder keeps copies of the files its trajectories are read from
TRAJECTORY_DIR = "trajectories"


def new_results_folder(config: Config, out: str | Path | None, label: str) -> Path:
    """``out`` if given (must not hold results already), else ``<output.dir>/<label>-<timestamp>``
    (``-2``, ``-3``, ... appended when a run started in the same second took that name).

    The folder is claimed by creating its STATUS exclusively, so two runs started at once never
    share one. Writes STATUS ``running`` and ``config.yaml`` (the config with its bases merged in;
    a described robot's description file copied to ``description/``, and the files its streamed
    trajectories are read from (``file``, a ``joint_excitation``'s sines) to ``trajectories/``,
    the copies' paths in it: the folder's config is then self-contained).

    Raises:
        FileExistsError: ``out`` holds results (a STATUS) already.
    """
    if out is not None:
        folder = Path(out)
        if not _claim(folder):
            raise FileExistsError(f"{folder} already holds results; choose another --out")
    else:
        base = Path(config.output.dir) / f"{label}-{time.strftime('%Y%m%d-%H%M%S')}"
        folder, n = base, 1
        while not _claim(folder):
            n += 1
            folder = base.with_name(f"{base.name}-{n}")
    (folder / "data").mkdir(exist_ok=True)
    mark_status(folder, "running")
    copies = file_copies(config.robot, config.trajectories)
    for relative, original in copies.files:
        (folder / relative).parent.mkdir(exist_ok=True)
        shutil.copyfile(original, folder / relative)
    (folder / "config.yaml").write_text(resolved_yaml(config.source, copies.replace))
    return folder


@dataclass(frozen=True)
class FileCopies:
    """The files a config reads that a copy of it elsewhere (a results folder, a study's run) must
    carry, so that the copy is self-contained (:func:`file_copies`): ``files`` as (path relative to
    the copy's folder, the original's path), ``replace`` the config's dotted keys to rewrite to
    those relative paths (:func:`ident_hw.config.resolved_yaml`)."""

    files: tuple[tuple[str, str], ...]
    replace: Mapping[str, str]


def file_copies(robot: RobotConfig, trajectories: Sequence[TrajectoryConfig]) -> FileCopies:
    """What a copy of a config with this ``robot`` section and these ``trajectories`` carries:
    the robot's description file (``description/``) and the files its streamed trajectories are
    read from (``trajectories/<name><suffix>``: a ``file`` trajectory, a ``joint_excitation``'s
    sines), those that exist. A ``recorded`` trajectory's file, a recording made elsewhere, stays
    where it is."""
    files: list[tuple[str, str]] = []
    replace: dict[str, str] = {}
    if robot.description is not None:
        relative = (Path(DESCRIPTION_DIR) / Path(robot.description).name).as_posix()
        files.append((relative, str(robot.description)))
        replace[DESCRIPTION_KEY] = relative
    for index, trajectory in enumerate(trajectories):
        if trajectory.path is not None and not trajectory.recorded and Path(trajectory.path).is_file():
            relative = (Path(TRAJECTORY_DIR) / f"{trajectory.name}{Path(trajectory.path).suffix}").as_posix()
            files.append((relative, str(trajectory.path)))
            replace[f"trajectories.{index}.path"] = relative
    return FileCopies(tuple(files), replace)


def _claim(folder: Path) -> bool:
    """Create ``folder`` (if needed) and its STATUS, exclusively: False if a STATUS was there."""
    folder.mkdir(parents=True, exist_ok=True)
    try:
        (folder / STATUS_FILE).open("x").close()
    except FileExistsError:
        return False
    return True


def discard_unused(folder: Path) -> bool:
    """Remove what :func:`new_results_folder` wrote into ``folder`` (STATUS, config.yaml, an
    empty data/, the copies of the description and trajectory files) and the folder if that
    leaves it empty: a run that could not start (its bus would not open) leaves no results
    folder behind. Anything else in it stays. True if the folder is gone."""
    folder = Path(folder)
    data = folder / "data"
    if data.is_dir() and any(data.iterdir()):
        return False
    for name in ("STATUS", "config.yaml"):
        (folder / name).unlink(missing_ok=True)
    for copies in (DESCRIPTION_DIR, TRAJECTORY_DIR):
        shutil.rmtree(folder / copies, ignore_errors=True)
    for path in (data, folder):
        try:
            path.rmdir()
        except OSError:
            return False
    return True
