"""No write leaves the run directory (issue 44, finding 2): a symlink planted at any path the
library writes, a file or a parent folder, is refused with one clear error, and its target is
untouched. Planted as found: ``run/.lock`` -> a user's file and ``run/reevaluation/report.md`` ->
another, then ``evaluate``, ``--resume`` and ``convert-run``; then each writer on its own (the
``O_NOFOLLOW`` opens behind the run-wide check)."""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

import pytest
import torch

from morl_trl.recipes import TrainConfig, evaluate_run, load_policy, train
from morl_trl.recipes.convert import convert_run
from morl_trl.runs import RunLock, save_checkpoint
from morl_trl.runs.atomic import atomic_write_text
from morl_trl.runs.nofollow import SymlinkRefusedError
from morl_trl.runs.run_dir import NewRunDir
from morl_trl.runs.run_log import _append_rows
from tests.runs._helpers import cli, train_tiny


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("links") / "run"
    train_tiny(run)
    evaluate_run(run)  # (reevaluation/ exists, as in the report)
    return run


@pytest.fixture
def run(finished, tmp_path) -> Path:
    shutil.copytree(finished, tmp_path / "run", symlinks=True)
    return tmp_path / "run"


@pytest.fixture
def victim(tmp_path) -> Path:
    """A user's file and folder outside the run."""
    victim = tmp_path / "victim"
    (victim / "victim_dir").mkdir(parents=True)
    (victim / "victim_dir" / "notes.txt").write_text("precious folder")
    (victim / "victim.txt").write_text("precious")
    return victim


def _state(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and not p.is_symlink()}


def _plant(run: Path, rel: str, victim: Path) -> Path:
    link = run / rel
    if link.is_dir() and not link.is_symlink():
        shutil.rmtree(link)
        os.symlink(victim / "victim_dir", link)
    else:
        link.unlink(missing_ok=True)
        link.parent.mkdir(parents=True, exist_ok=True)
        os.symlink(victim / "victim.txt", link)
    return link


def _resume(run: Path):
    return train(TrainConfig.load(run / "config.json").replace(frames=576), resume=run)


COMMANDS = {"evaluate": evaluate_run, "resume": _resume, "convert-run": convert_run}
PLANTS = [
    (".lock", "evaluate"), (".lock", "resume"), (".lock", "convert-run"),
    ("reevaluation/report.md", "evaluate"), ("reevaluation", "evaluate"), ("reevaluation/eval", "evaluate"),
    ("log.txt", "resume"), ("report.md", "resume"), ("eval/metrics.csv", "resume"), ("eval", "resume"),
    ("train", "resume"), ("fronts", "resume"), ("checkpoints/latest", "resume"), ("checkpoints", "resume"),
    ("config.json", "resume"),
]


@pytest.mark.parametrize("rel, command", PLANTS, ids=[f"{c}:{r}" for r, c in PLANTS])
def test_a_planted_symlink_is_refused_and_its_target_untouched(run, victim, rel, command):
    if rel == "config.json":  # (a config it can read: only the write would reach the target)
        shutil.copy(run / "config.json", victim / "victim.txt")
    link = _plant(run, rel, victim)
    before = _state(victim)
    with pytest.raises(SymlinkRefusedError) as err:
        COMMANDS[command](run)
    assert str(err.value) == (
        f"refusing to write through a symbolic link: {str(link)!r} -> {os.readlink(link)!r} (a write would change the "
        f"link's target, outside the run); remove the link (rm {str(link)!r}), then try again")
    assert _state(victim) == before


def test_the_cli_says_it_in_one_line(run, victim):
    link = _plant(run, ".lock", victim)
    out = cli("evaluate", run)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.strip() == (f"morl-trl evaluate: error: refusing to write through a symbolic link: "
                                  f"{str(link)!r} -> {str(victim / 'victim.txt')!r} (a write would change the link's "
                                  f"target, outside the run); remove the link (rm {str(link)!r}), then try again")
    assert (victim / "victim.txt").read_text() == "precious"


# ---------------------------------------------------------------- each writer on its own (no run-wide check)
def test_the_lock_file_is_opened_without_following_a_link(tmp_path, victim):
    run = tmp_path / "r"
    run.mkdir()
    os.symlink(victim / "victim.txt", run / ".lock")
    with pytest.raises(SymlinkRefusedError, match="'.*/r/.lock' -> "):
        RunLock(run, "evaluating", check_links=False).acquire()
    assert (victim / "victim.txt").read_text() == "precious"


def _log(run: Path):
    from morl_trl.envs import domain_of
    from morl_trl.runs import RunLog

    return RunLog(run, TrainConfig.load(run / "config.json"), domain_of("MOLavaGridDR-v0"), tag="reevaluation")


@pytest.mark.parametrize("rel, write", [
    ("log.txt", lambda run: _log(run).note("x")),
    ("reevaluation/report.md", lambda run: _log(run).report_stop("x")),
    ("reevaluation/eval/metrics.csv", lambda run: _append_rows(run / "reevaluation/eval/metrics.csv", [{"a": 1}], run)),
    ("reevaluation/eval", lambda run: _append_rows(run / "reevaluation/eval/new.csv", [{"a": 1}], run)),
    ("checkpoints/latest", lambda run: save_checkpoint(run, 1024, {"x": torch.zeros(1)})),
    ("checkpoints", lambda run: save_checkpoint(run, 1024, {"x": torch.zeros(1)})),
    ("config.json", lambda run: atomic_write_text(run / "config.json", "{}", root=run)),
])
def test_each_writer_refuses_a_link(run, victim, rel, write):
    link = _plant(run, rel, victim)
    before = _state(victim)
    with pytest.raises(SymlinkRefusedError, match=f"symbolic link: {str(link)!r}"):
        write(run)
    assert _state(victim) == before


def test_a_planted_temporary_file_is_replaced_not_followed(tmp_path, victim):
    target = tmp_path / "config.json"
    os.symlink(victim / "victim.txt", tmp_path / f".config.json.tmp{os.getpid()}")
    atomic_write_text(target, "{}")
    assert target.read_text() == "{}" and not target.is_symlink()
    assert (victim / "victim.txt").read_text() == "precious"


def test_a_planted_staging_folder_is_removed_not_followed(tmp_path, victim):
    staging = tmp_path / f".new.starting-{os.getpid()}"
    os.symlink(victim / "victim_dir", staging)
    start = NewRunDir(tmp_path / "new", overwrite=False)
    start.start().release()
    assert (tmp_path / "new" / ".lock").is_file() and not (tmp_path / "new").is_symlink()
    assert sorted(p.name for p in (victim / "victim_dir").iterdir()) == ["notes.txt"]


def test_export_refuses_a_link_at_its_output(run, victim, tmp_path):
    out = tmp_path / "policy.pt"
    os.symlink(victim / "victim.txt", out)
    with pytest.raises(SymlinkRefusedError, match=f"symbolic link: {str(out)!r}"):
        load_policy(run).save(out)
    assert (victim / "victim.txt").read_text() == "precious"


def test_the_run_directory_itself_may_be_a_link(run, tmp_path):
    link = tmp_path / "scratch_link"
    os.symlink(run, link)  # (e.g. runs/ on a scratch disk: the user's own choice, outside the run)
    assert evaluate_run(link)["frames"] == 512
    assert (run / "reevaluation" / "report.md").is_file()
