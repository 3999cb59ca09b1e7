"""Runs survive bad input and damage: resume conflicts, damaged checkpoints, config checks, run dirs."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest
import torch

from morl_trl.recipes import resolve_config, train
from morl_trl.runs import checkpoint_buffer, checkpoint_frames, find_checkpoint, load_checkpoint, verify_checkpoint
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from morl_trl.cli import main
from tests.runs._helpers import TINY, train_tiny, write_config


class _Out:
    def __init__(self, returncode: int, stdout: str, stderr: str) -> None:
        self.returncode, self.stdout, self.stderr = returncode, stdout, stderr


@pytest.fixture
def cli(capsys, monkeypatch, tmp_path):
    """``morl-trl ...`` in this process (the exit status and what it printed): no interpreter start per call.
    Without the published reference data (as the subprocess runs of tests/runs/test_resume.py)."""
    monkeypatch.delenv("MORL_TRL_REFERENCE", raising=False)
    monkeypatch.chdir(tmp_path)

    def run(*args) -> _Out:
        capsys.readouterr()
        try:
            rc = main([str(a) for a in args])
        except SystemExit as stop:  # (argparse's own refusals exit from inside main, as in the console script)
            rc = stop.code
        out = capsys.readouterr()
        return _Out(rc, out.out, out.err)

    return run


def _snapshot(root: Path) -> dict[str, tuple[int, int, str]]:
    """size, mtime and hash of every file under ``root``."""
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns, hashlib.sha256(p.read_bytes()).hexdigest())
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != ".lock"}  # (the lock file: not run content)


def _outputs(run: Path) -> dict[str, bytes]:
    files = [run / "eval" / "metrics.csv", run / "eval" / "episodes.csv", *sorted((run / "fronts").glob("*.csv")),
             *sorted((run / "logs").rglob("*.csv"))]
    return {str(f.relative_to(run)): f.read_bytes() for f in files}


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory) -> Path:
    """A finished 512-frame MO-LavaGrid run: evaluations at 0, 256, 512; checkpoints at 256 and 512."""
    run = tmp_path_factory.mktemp("base") / "run"
    return train_tiny(run, logger="csv")


@pytest.fixture
def run(finished_run, tmp_path) -> Path:
    copy = tmp_path / "run"
    shutil.copytree(finished_run, copy)
    return copy


# ---------------------------------------------------------------- 2. resume and the command line
@pytest.mark.parametrize("args, message", [
    (["capql", "MOHopperDR-v5"], "cannot resume: algo is 'capql' in the command line but 'envelope' in the run's "
                                 "config.json"),
    (["envelope", "MOLunarLanderDR-v0"], "env_id is 'MOLunarLanderDR-v0' in the command line but 'MOLavaGridDR-v0'"),
    (["envelope", "MOLavaGridDR-v0", "--seed", "5"], "seed is 5 in the command line but 0 in the run's config.json"),
    (["envelope", "MOLavaGridDR-v0", "--quick"], "num_envs is 16 in the --quick preset but 8 in the run's config"),
])
def test_resume_refuses_a_command_line_that_contradicts_the_run(run, args, message, cli):
    before = _snapshot(run)
    out = cli("train", *args, "--resume", run)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert message in out.stderr
    assert ("only ['frames', 'device', 'num_threads', 'logger', 'progress', 'compile', 'compile_mode', 'cudagraphs', "
            "'finite_check_interval'] may change") in out.stderr
    assert _snapshot(run) == before  # nothing touched


def test_resume_refuses_config_file_values_that_differ(run, tmp_path, cli):
    cfg = write_config(tmp_path / "c.toml", lr=0.1)
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--resume", run, "--config", cfg)
    assert out.returncode == 2
    assert f"lr is 0.1 in config file '{cfg}' but 0.0003 in the run's config.json" in out.stderr
    # the same file with the run's own values (and a new total of frames) is accepted
    same = write_config(tmp_path / "same.toml", frames=640)
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--resume", run, "--config", same)
    assert out.returncode == 0, out.stderr[-2000:]
    assert json.loads((run / "config.json").read_text())["frames"] == 640


def test_resume_with_more_frames_extends_a_finished_run(run, cli):
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--resume", run, "--frames", "768")
    assert out.returncode == 0, out.stderr[-2000:]
    metrics = (run / "eval" / "metrics.csv").read_text().splitlines()[1:]
    assert [line.split(",")[0] for line in metrics] == ["0", "0", "256", "256", "512", "512", "768", "768"]
    assert json.loads((run / "config.json").read_text())["frames"] == 768
    assert "resumed with frames 512 -> 768" in (run / "log.txt").read_text()
    assert find_checkpoint(run)[0].name == "frames_000000000768"


def test_resume_of_a_finished_run_is_a_no_op(run, cli):
    before = _snapshot(run)
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--resume", run)
    assert out.returncode == 0
    assert out.stdout.strip().endswith("already reached 512 frames (frames = 512): nothing to do; "
                                       "pass a larger frames (--frames) to extend it")
    assert _snapshot(run) == before


def test_resume_in_python_takes_only_what_may_change(run):
    cfg = resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), **{**TINY, "batch_size": 16})
    with pytest.raises(ValueError, match="batch_size is 16 in the given config but 32 in the run's config.json"):
        train(cfg, resume=run)


# ---------------------------------------------------------------- 3. damaged checkpoints
def test_checkpoints_carry_a_manifest_of_sizes_and_checksums(run):
    ckpt = run / "checkpoints" / "frames_000000000512"
    manifest = json.loads((ckpt / "manifest.json").read_text())
    assert manifest["frames"] == 512
    assert manifest["files"]["state.pt"]["size"] == (ckpt / "state.pt").stat().st_size
    assert manifest["format"] == 2 and manifest["buffer"] == "saved"
    assert sorted(manifest["files"]) == ["buffer.pt", "state.pt"]  # tensors and plain data only: no pickles
    assert verify_checkpoint(ckpt) is None


def _damage_truncate_state(ckpt: Path) -> str:
    state = ckpt / "state.pt"
    size = state.stat().st_size
    with state.open("r+b") as fh:
        fh.truncate(size // 2)
    return f"state.pt has {size // 2} bytes; {size} were written"


def _damage_remove_buffer(ckpt: Path) -> str:
    (ckpt / "buffer.pt").unlink()
    return "buffer.pt is missing"


def _damage_truncate_memmap(ckpt: Path) -> str:
    buffer = ckpt / "buffer.pt"
    size = buffer.stat().st_size
    with buffer.open("r+b") as fh:
        fh.truncate(size - 64)
    return f"buffer.pt has {size - 64} bytes; {size} were written"


def _damage_flip_a_byte(ckpt: Path) -> str:
    state = ckpt / "state.pt"
    data = bytearray(state.read_bytes())
    data[len(data) // 2] ^= 0xFF
    state.write_bytes(bytes(data))
    return "state.pt does not match its checksum"


@pytest.mark.parametrize("damage", [_damage_truncate_state, _damage_remove_buffer, _damage_truncate_memmap,
                                    _damage_flip_a_byte])
def test_verify_names_the_damage_and_changes_nothing(run, damage):
    ckpt = run / "checkpoints" / "frames_000000000512"
    problem = damage(ckpt)
    before = _snapshot(ckpt)
    assert verify_checkpoint(ckpt) == problem
    found, skipped = find_checkpoint(run)
    assert found.name == "frames_000000000256"
    assert skipped == [(ckpt, problem)]
    assert _snapshot(ckpt) == before  # read only: no file extended, zero-filled or touched


def test_resume_falls_back_to_the_newest_intact_checkpoint(run, cli):
    problem = _damage_truncate_memmap(run / "checkpoints" / "frames_000000000512")
    assert checkpoint_buffer(run / "checkpoints" / "frames_000000000256") == "pruned"
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--resume", run)
    assert out.returncode == 0, out.stderr[-2000:]
    warning = f"warning: skipped damaged checkpoint frames_000000000512: {problem}"
    assert warning in out.stdout
    log = (run / "log.txt").read_text()
    assert warning in log and "resumed from frames_000000000256 at 256 frames" in log
    # only the newest checkpoint keeps the replay buffer: the fallback says it continues without one
    empty = "warning: frames_000000000256 holds no replay buffer (only the newest checkpoint keeps it): " \
            "the run continues with an empty replay buffer"
    assert empty in out.stdout and empty in log
    metrics = (run / "eval" / "metrics.csv").read_text().splitlines()
    assert [line.split(",")[0] for line in metrics[1:]] == ["0", "0", "256", "256", "512", "512"]
    ckpts = sorted(p for p in (run / "checkpoints").glob("frames_*"))
    assert [p.name for p in ckpts] == ["frames_000000000256", "frames_000000000512"]  # the damaged one replaced
    assert all(verify_checkpoint(p) is None for p in ckpts)
    assert [checkpoint_buffer(p) for p in ckpts] == ["pruned", "saved"]


def test_only_the_newest_checkpoint_keeps_the_buffer(tmp_path):
    run = tmp_path / "run"
    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), logger="none",
                         **{**TINY, "frames": 1024, "keep_checkpoints": 3}))  # checkpoints at 0, 256, ..., 1024
    ckpts = sorted(p for p in (run / "checkpoints").glob("frames_*"))
    assert [checkpoint_frames(p) for p in ckpts] == [512, 768, 1024]
    assert [(p / "buffer.pt").is_file() for p in ckpts] == [False, False, True]
    assert [checkpoint_buffer(p) for p in ckpts] == ["pruned", "pruned", "saved"]
    assert all(verify_checkpoint(p) is None for p in ckpts)
    assert find_checkpoint(run) == (ckpts[-1], [])
    with pytest.raises(ValueError, match=r"config key 'keep_checkpoints' \(run\) is 0; valid: an int in \[1, inf\]"):
        resolve_config("envelope", "MOLavaGridDR-v0", keep_checkpoints=0)


def test_an_interrupted_buffer_prune_leaves_an_intact_checkpoint(run):
    """A kill after the manifest is rewritten but before ``buffer/`` is gone: the stray buffer is never loaded."""
    old = run / "checkpoints" / "frames_000000000256"
    new = run / "checkpoints" / "frames_000000000512"
    shutil.copy(new / "buffer.pt", old / "buffer.pt")  # as if its deletion had not happened yet
    assert verify_checkpoint(old) is None and checkpoint_buffer(old) == "pruned"
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(4096))
    load_checkpoint(old, buffer)
    assert len(buffer) == 0


def test_resume_refuses_when_no_checkpoint_is_intact(run, cli):
    _damage_truncate_state(run / "checkpoints" / "frames_000000000512")
    _damage_flip_a_byte(run / "checkpoints" / "frames_000000000256")
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--resume", run)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert (f"cannot resume '{run}': no intact checkpoint (frames_000000000512: state.pt has" in out.stderr
            and "frames_000000000256: state.pt does not match its checksum); start it again with --overwrite"
            in out.stderr)


def test_resume_refuses_a_run_without_checkpoints(run, cli):
    shutil.rmtree(run / "checkpoints")
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--resume", run)
    assert out.returncode == 2
    assert f"cannot resume '{run}': no intact checkpoint (there is none)" in out.stderr


# ---------------------------------------------------------------- 5. configs are checked
@pytest.mark.parametrize("text, message", [
    ('frames = "lots"\n', "config key 'frames' (collector) is 'lots'; valid: an int in [1, inf]"),
    ("hidden = 64\n", "config key 'hidden' (network) is 64; valid: a non-empty list of ints in [1, 65,536] (hidden layer widths)"),
    ("eval_interval = 0\n", "config key 'eval_interval' (eval) is 0; valid: an int in [1, inf]"),
])
def test_bad_config_file_values_name_the_key(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("(", r"\(").replace(")", r"\)")):
        resolve_config("envelope", "MOLavaGridDR-v0", config_file=path)


@pytest.mark.parametrize("flag, value, message", [
    ("--frames", "-100", "argument --frames: '-100' is not a frame count: give a whole number >= 1, e.g. 3000, 1e5, 100k or 3M"),
    ("--frames", "0", "argument --frames: '0' is not a frame count: give a whole number >= 1, e.g. 3000, 1e5, 100k or 3M"),
    ("--device", "gpu", "config key 'device' (run) is 'gpu'; valid: a torch device string such as 'cpu', 'cuda'"),
    ("--device", "meta", "config key 'device' (run) is 'meta'; valid: 'cpu' or 'cuda' (training runs on those)"),
    pytest.param("--device", "cuda", "config key 'device' (run) is 'cuda'; valid: 'cpu' (no CUDA device is available",
                 marks=pytest.mark.skipif(torch.cuda.is_available(), reason="a GPU is available")),
])
def test_bad_flags_exit_2_with_one_line_and_make_no_run_dir(tmp_path, flag, value, message, cli):
    out = cli("train", "envelope", "MOLavaGridDR-v0", flag, value, "--run-dir", tmp_path / "run")
    assert out.returncode == 2
    *usage, last = out.stderr.splitlines()  # one error line, after argparse's usage where argparse refused it
    assert last.startswith(f"morl-trl train: error: {message}")
    assert all(line.startswith(("usage: ", " ")) for line in usage) and (flag == "--frames") == bool(usage)
    assert "Traceback" not in out.stderr
    assert not (tmp_path / "run").exists()


# ---------------------------------------------------------------- 6. run directories
def test_a_non_empty_run_dir_is_refused_unless_resume_or_overwrite(run, tmp_path, cli):
    before = _snapshot(run)
    cfg = write_config(tmp_path / "c.toml", frames=128, init_random_frames=64)
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--config", cfg, "--run-dir", run)
    assert out.returncode == 2
    assert f"run directory '{run}' is not empty (it holds ['checkpoints', 'config.json', 'eval', 'fronts', 'log.txt']): " \
           f"continue it with --resume '{run}', replace it with --overwrite, or choose another --run-dir" in out.stderr
    assert _snapshot(run) == before
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--config", cfg, "--run-dir", run, "--overwrite")
    assert out.returncode == 0, out.stderr[-2000:]
    metrics = (run / "eval" / "metrics.csv").read_text().splitlines()[1:]
    assert [line.split(",")[0] for line in metrics] == ["0", "0", "128", "128"]  # the new run's rows only
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == ["frames_000000000000", "frames_000000000128",
                                                                        "latest"]
    assert not (run / "fronts" / "frames_000000000512.csv").exists()
    # --overwrite deletes run directories only
    other = tmp_path / "not_a_run"
    other.mkdir()
    (other / "notes.txt").write_text("keep me")
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--config", cfg, "--run-dir", other, "--overwrite")
    assert out.returncode == 2
    assert f"--overwrite replaces run directories only; '{other}' has no config.json" in out.stderr
    assert (other / "notes.txt").read_text() == "keep me"


def test_a_failed_start_leaves_no_run_dir_and_loses_nothing(run, tmp_path, monkeypatch, cli):
    import morl_trl.algorithms.envelope.recipe as envelope_recipe

    def broken(*args, **kwargs):
        raise ValueError("the env failed to build")

    monkeypatch.setattr(envelope_recipe, "make_training_env", broken)  # (the recipe's own name for it)
    fresh = tmp_path / "fresh"
    with pytest.raises(ValueError, match="the env failed to build"):
        train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(fresh), **TINY))
    assert not fresh.exists()
    before = _snapshot(run)
    with pytest.raises(ValueError, match="the env failed to build"):
        train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), **TINY), overwrite=True)
    assert _snapshot(run) == before  # --overwrite removes the old run only once the new one is built
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--logger", "wandb", "--run-dir", fresh)
    if out.returncode == 2:  # (wandb not installed here)
        assert "logger 'wandb' needs the 'wandb' package" in out.stderr
        assert not fresh.exists()
