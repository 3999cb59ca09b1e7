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


def test_readme_example_runs_verbatim_twice_in_a_row(tmp_path, monkeypatch, capsys):
    pytest.importorskip("Box2D")
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("MORL_TRL_REFERENCE", raising=False)
    (block,) = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(block.strip().splitlines()) <= 10
    runs = []
    for _ in range(2):  # a fresh run directory each time: the second run is not refused
        ns: dict = {}
        exec(compile(block, str(README), "exec"), ns)  # noqa: S102 - the README's own code
        assert ns["td"]["next", "reward"].shape == (16, 100, 4)
        assert ns["policy"].frames == 3008 and ns["returns"].shape == (4, 2)
        runs.append(ns["trained"].run_dir)
        # it trains past its warm-up: 500 random frames, then updates (their losses)
        assert "(3,000 to go, 500 of them random before learning)" in (runs[-1] / "log.txt").read_text()
        assert len((runs[-1] / "train" / "losses.csv").read_text().splitlines()) > 1
        assert ns["trained"].report == runs[-1] / "report.md"
        out = capsys.readouterr().out
        # the report's one-line summary, not its tables
        assert f"envelope on MOLavaGridDR-v0: 3,008 frames, mean NHGR " in out and "## NHGR" not in out
        assert "| context |" not in out
    assert runs[0] != runs[1] and runs[0].parent == runs[1].parent == Path("runs")
