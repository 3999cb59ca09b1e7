"""A run started without a run directory gets a fresh one, named as the docs say."""

from types import SimpleNamespace

from morl_trl.runs import run as run_module
from morl_trl.runs import RUN_DIR_PATTERN, default_run_dir


def test_default_run_dir_is_fresh_within_the_same_second(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(run_module.time, "strftime", lambda fmt: "20261201-213000")
    cfg = SimpleNamespace(algo="envelope", env_id="MOLavaGridDR-v0", seed=3)
    first = default_run_dir(cfg)
    assert str(first) == "runs/envelope_MOLavaGridDR-v0_s3_20261201-213000"
    first.mkdir(parents=True)
    second = default_run_dir(cfg)
    assert str(second) == "runs/envelope_MOLavaGridDR-v0_s3_20261201-213000-2"
    second.mkdir()
    assert default_run_dir(cfg).name.endswith("-3")
    assert RUN_DIR_PATTERN == "runs/<algo>_<env id>_s<seed>_<YYYYmmdd-HHMMSS>"
