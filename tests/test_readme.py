"""The README: two screens, the two commands CI runs, and its example runs verbatim.

The longer snippets moved to the documentation, whose pages run as tests (tests/test_docs.py)."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def test_readme_fits_on_two_screens():
    assert len(README.read_text().splitlines()) < 150


def test_readme_commands_are_the_ones_ci_runs():
    text = README.read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    assert 'pip install -q torch==2.13.0' in ci and 'pip install -q -e ".[all]"' in ci
    assert 'pip install torch==2.13.0 && pip install -e ".[all]"' in text
    assert "python -m pytest -q" in text and "python -m pytest -q" in ci
    assert "arxiv.org/abs/2503.00799" in text and "@inproceedings{teoh2025generalization" in text


def test_readme_links_exist():
    for target in re.findall(r"\]\(((?:docs/|LICENSE|CHANGELOG)[^)#]*)\)", README.read_text()):
        assert (ROOT / target).exists(), target


def test_readme_example_runs_verbatim(tmp_path, monkeypatch):
    pytest.importorskip("Box2D")
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("MORL_TRL_REFERENCE", raising=False)
    (block,) = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(block.strip().splitlines()) <= 10
    ns: dict = {}
    exec(compile(block, str(README), "exec"), ns)  # noqa: S102 - the README's own code
    assert ns["td"]["next", "reward"].shape == (16, 100, 4)
    assert ns["policy"].frames == 2048 and ns["returns"].shape == (4, 2)
