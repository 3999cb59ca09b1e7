"""docs/concepts/architecture.md says what the code is: its layer table is the one tests/test_layers.py
enforces, and its package table names every sub-package there is."""

import re
from pathlib import Path

from tests.test_layers import ALLOWED, PACKAGE

PAGE = Path(__file__).resolve().parents[2] / "docs" / "concepts" / "architecture.md"


def _section(title: str) -> str:
    text = PAGE.read_text()
    start = text.index(f"## {title}")
    end = text.find("\n## ", start + 1)
    return text[start:end if end != -1 else None]


def _rows(section: str) -> list[list[str]]:
    """The body rows of the section's Markdown table, cells stripped."""
    rows = [line.strip().strip("|").split("|") for line in section.splitlines() if line.startswith("|")]
    return [[cell.strip() for cell in row] for row in rows[2:]]


def test_layer_table_is_the_enforced_one():
    page = {}
    for package, allowed in _rows(_section("Layers point down only")):
        page[package.strip("`")] = set(re.findall(r"`(\w+)`", allowed))
    assert page == ALLOWED


def test_package_table_names_every_sub_package():
    listed = {cell.strip("`").rstrip("/") for cell, _ in _rows(_section("The package"))}
    packages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    assert packages == {"algorithms", "data", "envs", "evaluation", "grid", "gym", "metrics", "objectives",
                        "preferences", "recipes", "reporting", "runs", "training", "transforms"}
    assert packages <= listed
    assert listed - packages == {"cli.py"}
