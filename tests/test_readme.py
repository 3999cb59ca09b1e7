"""The README's Python snippets run verbatim, in order, from a directory outside the repository."""

import os
import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def _python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_has_the_snippets_users_copy():
    blocks = _python_blocks()
    assert len(blocks) >= 5
    assert any("append_transform" in b for b in blocks) and any("MultiContextEvaluator" in b for b in blocks)


def test_readme_snippets_run_verbatim_from_any_directory(tmp_path, monkeypatch):
    pytest.importorskip("Box2D")
    pytest.importorskip("mujoco")
    monkeypatch.chdir(tmp_path)  # no ../shared/reference here: the shipped constants must do
    monkeypatch.delenv("MORL_TRL_REFERENCE", raising=False)
    namespace: dict = {}
    for block in _python_blocks():
        exec(compile(block, str(README), "exec"), namespace)  # noqa: S102 - the README's own code
    nhgr = namespace["result"].metric("nhgr")
    assert len(nhgr) == 8 and all(0.0 <= v <= 1.0 for v in nhgr.values())
    assert namespace["env"].rollout(3)["preference"].shape == (16, 3, 3)
    assert namespace["summary"]["frames"] == 4032
    assert os.listdir(tmp_path / "runs")
    assert namespace["vec_reward"].shape == (4,) and namespace["info"]["context"].shape == (7,)
    assert namespace["policy"].frames == 2048 and namespace["trained"].summary["frames"] == 2048
    assert namespace["episodes"]["next", "reward"].shape[0] == 4
