"""The documentation site builds with warnings as errors, its navigation tolerates pages that
land later, and the tutorials' code runs verbatim (the docs' snippets are tests)."""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS / "hooks"))
import nav  # noqa: E402  (docs/hooks/nav.py)

# pages whose ```python blocks run, in order, each page in a fresh namespace
RUNNABLE = [
    "getting-started.md",
    "gymnasium.md",
    "concepts/evaluation.md",
    "tutorials/compose-transforms.md",
    "tutorials/own-trainer.md",
    "tutorials/ray-grid.md",
]


def _blocks(page: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", (DOCS / page).read_text(), flags=re.S)


def _run_page(page: str, cwd: Path) -> dict:
    namespace: dict = {"__name__": f"docs:{page}"}
    for block in _blocks(page):
        exec(compile(block, str(DOCS / page), "exec"), namespace)  # noqa: S102 - the docs' own code
    return namespace


@pytest.fixture
def outside_repo(tmp_path, monkeypatch):
    """Run from a directory outside the repository (with the examples the tutorials name), with
    no published reference data: the shipped constants must do."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("MORL_TRL_REFERENCE", raising=False)
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    return tmp_path


def test_strict_build(tmp_path):
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings_handlers.python")
    site = tmp_path / "site"
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)], cwd=ROOT,
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-4000:]
    index = (site / "index.html").read_text()
    assert "Getting started" in index and "API reference" in index
    # a generated table and an API page
    hopper = (site / "domains" / "hopper" / "index.html").read_text()
    assert "mass_torso" in hopper and "LowDamping" in hopper
    assert "MultiContextEvaluator" in (site / "reference" / "evaluation" / "index.html").read_text()
    assert "none" in (site / "concepts" / "contexts" / "index.html").read_text()


def test_nav_lists_only_pages_that_exist(tmp_path):
    for page in ["index.md", "getting-started.md", "tutorials/ray-grid.md", "reference/envs.md", "extra.md"]:
        (tmp_path / page).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / page).write_text("# x\n")
    built = nav.build_nav(tmp_path)
    assert built[:2] == [{"Home": "index.md"}, {"Getting started": "getting-started.md"}]
    assert {"Tutorials": ["tutorials/ray-grid.md"]} in built          # own-domain.md absent: not listed
    assert {"API reference": ["reference/envs.md"]} in built          # found, though not in the layout
    assert {"More": ["extra.md"]} in built
    (tmp_path / "tutorials" / "own-domain.md").write_text("# y\n")     # a page that lands later
    assert {"Tutorials": ["tutorials/own-domain.md", "tutorials/ray-grid.md"]} in nav.build_nav(tmp_path)


def test_links_to_missing_optional_pages_become_text(tmp_path):
    (tmp_path / "algorithms").mkdir()
    (tmp_path / "speed.md").write_text("# speed\n")

    class Page:
        class file:
            src_uri = "algorithms/envelope.md"

    md = "see [the fidelity table](../fidelity.md#top), [speed](../speed.md) and [x](../other.md)"
    out = nav.on_page_markdown(md, Page, {"docs_dir": str(tmp_path)}, None)
    assert out == "see the fidelity table, [speed](../speed.md) and [x](../other.md)"


def test_getting_started_runs(outside_repo):
    pytest.importorskip("Box2D")
    pytest.importorskip("mujoco")
    ns = _run_page("getting-started.md", outside_repo)
    assert ns["td"]["next", "reward"].shape == (16, 100, 4)
    assert ns["policy"].frames == 3008 and ns["trained"].summary["frames"] == 3008
    assert ns["episodes"]["next", "reward"].shape[:2] == (4, 256)
    run = outside_repo / "runs" / "lava-quick"
    assert ("start: envelope on MOLavaGridDR-v0, seed 0, cpu: frame budget 3,000 (3,000 to go, 500 of them random"
            in (run / "log.txt").read_text())
    report = (run / "report.md").read_text()
    # a quick run evaluates 8 weights: its floor is at 8 weights (the shipped floors are at 100)
    assert "| floor: forward (8 weights) |" in report and "at this run's 8 evaluation weights" in report
    assert (run / "report_training.png").is_file() and (run / "train" / "losses.csv").is_file()
    nhgr = ns["result"].metric("nhgr")
    assert len(nhgr) == 8 and all(0.0 <= v <= 1.0 for v in nhgr.values())


def test_gymnasium_page_runs(outside_repo):
    pytest.importorskip("Box2D")
    pytest.importorskip("mo_gymnasium")
    ns = _run_page("gymnasium.md", outside_repo)
    assert ns["vec_reward"].shape == (4,) and ns["info"]["context"].shape == (7,)


def test_evaluation_page_runs(outside_repo):
    pytest.importorskip("Box2D")
    pytest.importorskip("mo_gymnasium")
    ns = _run_page("concepts/evaluation.md", outside_repo)
    hv = ns["gym_result"].metric("hypervolume")
    assert list(hv) == ["default"] and hv["default"] > 0


def test_compose_transforms_tutorial_runs(outside_repo):
    pytest.importorskip("mujoco")
    pytest.importorskip("Box2D")
    ns = _run_page("tutorials/compose-transforms.md", outside_repo)
    assert ns["td"]["observation"].shape == (16, 5, 39) and ns["td"]["preference"].shape == (16, 5, 3)
    assert ns["step"]["next", "reward"].shape == (4, 3, 2) and ns["step"]["next", "scalar_reward"].shape[:2] == (4, 3)
    assert ns["train_env"].reset()["observation"].shape == (8, 26)


def test_own_trainer_tutorial_runs(outside_repo):
    ns = _run_page("tutorials/own-trainer.md", outside_repo)
    nhgr = ns["own_result"].metric("nhgr")
    assert len(nhgr) == 8 and all(0.0 <= v <= 1.0 for v in nhgr.values())


def test_ray_grid_tutorial_runs(outside_repo):
    ns = _run_page("tutorials/ray-grid.md", outside_repo)
    assert len(ns["cells"]) == 195 and len({(c.algo, c.env_id) for c in ns["cells"]}) == 39


def test_tutorials_are_listed():
    present = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")}
    assert set(RUNNABLE) <= present
    assert all(_blocks(p) for p in RUNNABLE)
    assert importlib.util.find_spec("yaml") is None or (ROOT / "mkdocs.yml").is_file()
