"""The real recordings the tests read: found through ``IDENT_HW_DATASETS``, the folder holding
the datasets (``ur10e/``: a UR10e's public recordings, see configs/ur10e.yaml); ``.ci/run`` sets it
to the folder beside the clone. Without it those tests skip, saying so."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

#: the environment variable naming the datasets' folder
VARIABLE = "IDENT_HW_DATASETS"


def dataset(name: str) -> Path:
    """The folder of dataset ``name`` (``ur10e``), or skip the test saying why."""
    root = os.environ.get(VARIABLE)
    if not root:
        pytest.skip(f"{VARIABLE} (the folder holding the real recordings, {name}/) is not set")
    folder = Path(root) / name
    if not folder.is_dir():
        pytest.skip(f"{VARIABLE}={root} holds no {name}/")
    return folder


def needs_datasets(config_text: str) -> bool:
    """A config that names the datasets' folder (``${IDENT_HW_DATASETS}``)."""
    return "${" + VARIABLE + "}" in config_text
