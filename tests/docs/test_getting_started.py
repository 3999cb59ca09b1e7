"""Getting started says what the code does: the run directory's name is the one a run gets."""

import re
from pathlib import Path
from types import SimpleNamespace

from morl_trl.runs import RUN_DIR_PATTERN, default_run_dir

PAGE = Path(__file__).resolve().parents[2] / "docs" / "getting-started.md"


def test_the_run_dir_pattern_and_example_are_the_real_ones(tmp_path, monkeypatch):
    text = " ".join(PAGE.read_text().split())  # (one line: the page wraps its sentences)
    assert f"`{RUN_DIR_PATTERN}/`" in text
    (example,) = re.findall(r"for example `(runs/[^`]+)/`", text)
    assert example == "runs/envelope_MOLunarLanderDR-v0_s0_20261201-213000"
    monkeypatch.chdir(tmp_path)
    made = default_run_dir(SimpleNamespace(algo="envelope", env_id="MOLunarLanderDR-v0", seed=0))
    # the same name but for the time of the run
    assert re.fullmatch(r"runs/envelope_MOLunarLanderDR-v0_s0_\d{8}-\d{6}", str(made))
    assert str(made)[:-15] == example[:-15]


def test_code_blocks_fit_at_1280_px():
    """No line of a code block on the pages a new user reads first is wider than the page's code
    column at 1280 px (81 characters of the theme's monospace font, measured in a Chromium screenshot)."""
    docs = PAGE.parent
    for page in ("index.md", "getting-started.md", "algorithms/envelope.md", "contributing.md"):
        for block in re.findall(r"```\w*\n(.*?)```", (docs / page).read_text(), flags=re.S):
            for line in block.splitlines():
                assert len(line) <= 80, f"{page}: {line}"
