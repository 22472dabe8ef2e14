"""The benchmarks page and README's Status read as tables of short cells (issue 49 item 8).

Each cell of a table in ``benchmarks/README.md`` and in README's Status holds one figure with its
date: at most 150 characters, and no commit hash (a figure's history is in the commit messages,
its explanation in ``docs/benchmark-notes.md``).
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MAX_CELL = 150
# a commit hash as the project writes it: 7 to 40 hex digits with at least one letter and one digit
COMMIT = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b")


def table_cells(text: str) -> list[tuple[int, str]]:
    """Every cell of every markdown table in ``text`` as (line number, stripped text).

    A cell ends at an unescaped ``|``; ``\\|`` inside a cell is text."""
    cells = []
    for number, line in enumerate(text.splitlines(), start=1):
        if line.startswith("|"):
            parts = re.split(r"(?<!\\)\|", line.strip())[1:-1]
            cells.extend((number, part.strip()) for part in parts)
    return cells


def status_section(readme: str) -> str:
    """README's ``## Status`` section, up to the next second-level heading."""
    start = readme.index("\n## Status\n")
    end = readme.find("\n## ", start + 1)
    return readme[start:end if end >= 0 else None]


def test_table_cells_split_on_unescaped_bars_only():
    cells = table_cells("text\n| a | b \\| c |\n|---|---|\n")
    assert [cell for _, cell in cells] == ["a", "b \\| c", "---", "---"]
    assert COMMIT.search("at 4f8222a") and COMMIT.search("d62279c")
    assert not COMMIT.search("0x8130 1e-4 2,500 cycles/s facade")


@pytest.mark.parametrize("name, text", [
    ("benchmarks/README.md", (ROOT / "benchmarks" / "README.md").read_text(encoding="utf-8")),
    ("README.md Status", status_section((ROOT / "README.md").read_text(encoding="utf-8"))),
])
def test_every_cell_is_short_and_without_history(name, text):
    cells = table_cells(text)
    assert len(cells) > 20, f"{name}: no tables found"
    long = [(line, len(cell)) for line, cell in cells if len(cell) > MAX_CELL]
    assert not long, f"{name}: cells over {MAX_CELL} characters (line, length): {long}"
    hashes = [(line, m.group()) for line, cell in cells for m in [COMMIT.search(cell)] if m]
    assert not hashes, f"{name}: commit hashes in cells (line, hash): {hashes}"
