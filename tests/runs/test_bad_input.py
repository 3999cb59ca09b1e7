"""Bad input to runs gets one clear error naming the value and what is valid, and loses nothing."""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import pytest

from morl_trl.cli import main
from morl_trl.recipes import load_policy, resolve_config, train
from morl_trl.runs import find_checkpoint, verify_checkpoint
from tests.runs._helpers import TINY


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("bad") / "run"
    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), logger="csv", **{**TINY, "frames": 256}))
    return run


@pytest.fixture
def run(finished, tmp_path) -> Path:
    copy = tmp_path / "run"
    shutil.copytree(finished, copy)
    return copy


@pytest.fixture
def cli(capsys, monkeypatch, tmp_path):
    monkeypatch.delenv("MORL_TRL_REFERENCE", raising=False)
    monkeypatch.chdir(tmp_path)

    def call(*args):
        capsys.readouterr()
        rc = main([str(a) for a in args])
        out = capsys.readouterr()
        return rc, out.out, out.err

    return call


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
            and p.name != ".lock"}


@pytest.mark.parametrize("text, problem", [
    ("{", "unreadable manifest.json: Expecting property name enclosed in double quotes: line 1 column 2 (char 1)"),
    ("[1, 2]", "unreadable manifest.json: list indices must be integers or slices, not str"),
    ('{"files": [1]}', "unreadable manifest.json: 'files' is not a mapping of file -> size and sha256"),
    ('{"files": {"state.pt": 7}}', "unreadable manifest.json: 'files' is not a mapping of file -> size and sha256"),
    ('{"files": {"other": {}}}', "manifest.json lists no state.pt"),
])
def test_a_malformed_manifest_is_named_and_skipped(run, text, problem):
    ckpt = run / "checkpoints" / "frames_000000000256"
    (ckpt / "manifest.json").write_text(text)
    assert verify_checkpoint(ckpt) == problem
    found, skipped = find_checkpoint(run)
    assert found.name == "frames_000000000000" and skipped == [(ckpt, problem)]
    assert load_policy(run).frames == 0  # the newest intact one


def test_a_run_dir_that_cannot_be_written_is_refused_before_anything_is_built(tmp_path, cli):
    (tmp_path / "afile").write_text("x")
    rc, _, err = cli("train", "envelope", "MOLavaGridDR-v0", "--run-dir", tmp_path / "afile" / "run")
    assert rc == 2 and err.strip() == (f"morl-trl train: error: run directory '{tmp_path / 'afile' / 'run'}' cannot be "
                                       f"made: '{tmp_path / 'afile'}' is a file, not a folder")
    rc, _, err = cli("train", "envelope", "MOLavaGridDR-v0", "--run-dir", tmp_path / "afile")
    assert rc == 2 and err.strip() == f"morl-trl train: error: run directory '{tmp_path / 'afile'}' is a file"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_run_dir_is_refused(run, cli):
    before = _files(run)
    os.chmod(run, 0o555)
    try:
        rc, _, err = cli("train", "envelope", "MOLavaGridDR-v0", "--resume", run, "--frames", "512")
        assert rc == 2 and f"'{run}' cannot be written: '{run}' is read-only for this user" in err
    finally:
        os.chmod(run, 0o755)
    assert _files(run) == before


@pytest.mark.parametrize("override, message", [
    ({"seed": 2**32}, "config key 'seed' (run) is 4294967296; valid: an int in [0, 4294967295]"),
    ({"eval_weights": 1}, "config key 'eval_weights' (eval) is 1; valid: an int >= 2 (the evaluation weights include "
                          "the 2 corners of the simplex of the objectives ['lava', 'time'])"),
    ({"compile_mode": "bogus"}, "config key 'compile_mode' (compile) is 'bogus'; valid: null or one of ['default', "),
])
def test_bad_values_fail_before_the_run_starts(tmp_path, override, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(tmp_path / "r"), **{**TINY, **override}))
    assert not (tmp_path / "r").exists()


def test_a_config_file_for_another_env_is_refused(tmp_path, cli):
    config = tmp_path / "c.toml"
    config.write_text('env_id = "MOLunarLanderDR-v0"\n')
    rc, _, err = cli("train", "envelope", "MOLavaGridDR-v0", "--config", config, "--run-dir", tmp_path / "r")
    assert rc == 2 and err.strip() == (f"morl-trl train: error: config file '{config}' is for env_id "
                                       f"'MOLunarLanderDR-v0' but the command line gives 'MOLavaGridDR-v0': give the "
                                       f"same id (or drop env_id from the file)")
    assert not (tmp_path / "r").exists()


def test_quick_with_a_set_value_resumes_as_it_started(tmp_path, cli):
    run = tmp_path / "r"
    args = ["envelope", "MOLavaGridDR-v0", "--quick", "--set", "eval_interval=128", "--no-progress", "--logger", "none",
            "frames=128", "num_envs=4", "frames_per_batch=64", "init_random_frames=64", "eval_weights=2",
            "eval_contexts=['MOLavaGridRoom-v0']", "eval_random_baseline=false", "hidden=[16]", "buffer_size=1024"]
    rc, _, err = cli("train", *args, "--run-dir", run)
    assert rc == 0, err[-2000:]
    rc, out, err = cli("train", *args, "--resume", run, "--frames", "192")
    assert rc == 0, err[-2000:]
    assert json.loads((run / "config.json").read_text())["eval_interval"] == 128


def test_evaluate_writes_nothing_when_it_fails(run, cli):
    before = _files(run)
    rc, _, err = cli("evaluate", run, "--weights", "1")
    assert rc == 2 and "config key 'eval_weights' (eval) is 1; valid: an int >= 2" in err
    rc, _, err = cli("evaluate", run, "--video", "--video-weight", "0.2,0.3,0.5")
    assert rc == 2 and "the video weight has 3 entries; MO-LavaGrid has 2 objectives ['lava', 'time']" in err
    rc, _, err = cli("evaluate", run, "--video", "--video-weight", "0.9,0.9")
    assert rc == 2 and "video weight" in err
    assert _files(run) == before and not (run / "reevaluation").exists()
