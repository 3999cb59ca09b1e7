"""The main job: config resolution, a short real run, the NaN guard (kill + resume: tests/runs)."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from morl_trl.recipes import TrainConfig, evaluate_run, resolve_config, train
from morl_trl.runs import latest_checkpoint, load_checkpoint

TINY = dict(
    frames=512, num_envs=8, frames_per_batch=64, init_random_frames=128, updates_per_batch=2, batch_size=32,
    hidden=(32, 32), eval_interval=256, eval_weights=3, checkpoint_interval=256, buffer_size=4096,
    eval_contexts=("MOLavaGridRoom-v0", "MOLavaGridSnake-v0"), progress=False, eval_random_baseline=False,
)


# ---------------------------------------------------------------- config
def test_config_has_the_papers_defaults_and_names_bad_keys(tmp_path):
    cfg = resolve_config("envelope", "MOLunarLanderDR-v0")
    assert (cfg.history_len, cfg.batch_size, cfg.num_sampled_prefs, cfg.homotopy_lambda0) == (2, 128, 8, 0.95)
    assert (cfg.frames, cfg.eval_interval, cfg.eval_weights, cfg.target_update_period) == (3_000_000, 50_000, 100, 1000)
    lava = resolve_config("envelope", "MOLavaGridDR-v0")
    assert (lava.history_len, lava.eps_frames, lava.target_update_period) == (0, 5_000_000, 200)
    capql = resolve_config("capql", "MOHopperDR-v5")
    assert (capql.batch_size, capql.alpha, capql.tau, capql.eval_interval) == (256, 0.2, 0.005, 100_000)
    with pytest.raises(ValueError, match=r"unknown algorithm 'dqn'; valid: \['envelope'"):
        resolve_config("dqn", "MOLavaGridDR-v0")
    with pytest.raises(ValueError, match=r"unknown config key 'learning_rate' \(did you mean 'lr'\?\)"):
        resolve_config("envelope", "MOLavaGridDR-v0", learning_rate=1e-3)
    bad = tmp_path / "bad.toml"
    bad.write_text("batchsize = 3\n")
    with pytest.raises(ValueError, match=r"unknown config key 'batchsize' \(did you mean 'batch_size'\?\)"):
        resolve_config("envelope", "MOLavaGridDR-v0", config_file=bad)
    good = tmp_path / "good.toml"
    good.write_text("batch_size = 3\nhidden = [8, 8]\n")
    assert resolve_config("envelope", "MOLavaGridDR-v0", config_file=good, seed=4).hidden == (8, 8)
    with pytest.raises(ValueError, match="unknown env id 'MOLavaGrid-v0'"):
        resolve_config("envelope", "MOLavaGrid-v0")


def test_config_round_trips(tmp_path):
    cfg = resolve_config("envelope", "MOLavaGridDR-v0", quick=True, seed=7)
    cfg.save(tmp_path / "c.json")
    assert TrainConfig.load(tmp_path / "c.json") == cfg


def test_cli_errors_name_the_valid_choices():
    out = subprocess.run([sys.executable, "-m", "morl_trl.cli", "train", "envelope", "MOLavaGridDRR-v0"],
                         capture_output=True, text=True)
    assert out.returncode == 2
    assert "unknown env id 'MOLavaGridDRR-v0' (did you mean 'MOLavaGridDR-v0'" in out.stderr
    assert "Traceback" not in out.stderr


# ---------------------------------------------------------------- a short real run
def _rows(path: Path) -> list[dict]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_short_run_writes_everything(tmp_path, reference_dir):
    # 2 sub-envs x 256 steps: every training episode ends (truncation at 256) within the run
    cfg = resolve_config("envelope", "MOLavaGridDR-v0", quick=True, run_dir=str(tmp_path / "run"),
                         reference_dir=str(reference_dir), **{**TINY, "num_envs": 2})
    summary = train(cfg)
    run = tmp_path / "run"
    assert json.loads((run / "config.json").read_text())["frames"] == 512
    metrics = _rows(run / "eval" / "metrics.csv")
    # evaluations at 0, 256 and the end (512), one row per context each
    assert [(r["frames"], r["context"]) for r in metrics] == [
        (f, c) for f in ("0", "256", "512") for c in ("MOLavaGridRoom-v0", "MOLavaGridSnake-v0")
    ]
    assert {"nhgr", "eugr", "hypervolume", "normalized_hypervolume", "eum", "cardinality", "sparsity"} <= set(metrics[0])
    assert all(0.0 <= float(r["nhgr"]) <= 1.0 for r in metrics)
    episodes = _rows(run / "eval" / "episodes.csv")
    assert len(episodes) == 3 * 2 * 3  # evaluations x contexts x weights
    assert {"return_lava", "return_time", "weight_lava", "weight_time"} <= set(episodes[0])
    fronts = _rows(run / "fronts" / "frames_000000000512.csv")
    assert set(fronts[0]) == {"context", "lava", "time"}
    train_eps = _rows(run / "train" / "episodes.csv")
    assert len(train_eps) >= 2
    assert {"context_lava_x2_y2", "preference_lava", "return_lava", "discounted_return_time"} <= set(train_eps[0])
    assert latest_checkpoint(run).name == "frames_000000000512"
    report = (run / "report.md").read_text()
    assert "MOLavaGridRoom-v0" in report and "MORL/D SB (paper, 100 weights, 5M frames)" in report
    assert "| floor: " in report  # the best trivial policy's NHGR (shipped floors.json), a column and a plot line
    assert (run / "report_fronts.png").stat().st_size > 1000
    assert "## Learning curves" in report and (run / "report_learning.png").stat().st_size > 1000
    assert 0.0 <= summary["nhgr_mean"] <= 1.0
    # morl-trl evaluate: the last checkpoint again, written beside (not over) the run's outputs
    again = evaluate_run(run, weights=3)
    assert again["frames"] == 512
    assert again["per_context"]["MOLavaGridRoom-v0"]["nhgr"] == pytest.approx(
        summary["per_context"]["MOLavaGridRoom-v0"]["nhgr"])  # same checkpoint, same seed: same numbers
    assert len(_rows(run / "reevaluation" / "eval" / "metrics.csv")) == 2
    assert len(_rows(run / "eval" / "metrics.csv")) == 6
    assert (run / "reevaluation" / "report.md").exists()


def test_non_finite_loss_stops_with_a_clear_message_and_a_good_checkpoint(tmp_path, monkeypatch):
    from morl_trl.objectives import EnvelopeQLoss
    from morl_trl.recipes import NonFiniteLossError

    forward = EnvelopeQLoss.forward
    calls = {"n": 0}
    params = {}

    def poisoned(self, td):
        out = forward(self, td)
        calls["n"] += 1
        if calls["n"] > 20:  # the 21st update: the first batch of 2 updates is at 128 frames -> 768 frames
            params.update({k: v.detach().clone() for k, v in self.state_dict().items()})  # the state before it
            out["loss_qvalue"] = out["loss_qvalue"] * float("nan")
        return out

    monkeypatch.setattr(EnvelopeQLoss, "forward", poisoned)
    cfg = resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(tmp_path / "run"), **{**TINY, "frames": 2048})
    with pytest.raises(NonFiniteLossError, match=r"non-finite loss \{'loss_qvalue': nan\}.*the last good state is "
                       r"checkpointed in .*frames_000000000768"):
        train(cfg)
    run = tmp_path / "run"
    log = (run / "log.txt").read_text()
    assert "stopped: non-finite loss {'loss_qvalue': nan}; the networks were left as they were before this update " \
           "(at 768 frames, after 20 updates)" in log
    assert "**Run stopped early.** stopped: non-finite loss" in (run / "report.md").read_text()
    last = log.strip().splitlines()[-1].split(" ", 2)[2]  # (log.txt ends with why it stopped, how to resume)
    assert last.startswith("stopped: non-finite loss {'loss_qvalue': nan}")
    assert last.endswith(f"(at 768 frames, after 20 updates); the last good state is checkpointed in "
                         f"{run / 'checkpoints' / 'frames_000000000768'}; once the cause is fixed, resume with: "
                         f"morl-trl train envelope MOLavaGridDR-v0 --resume {run}")
    ckpt = latest_checkpoint(run)
    assert ckpt.name == "frames_000000000768"  # not the last periodic checkpoint (512): nothing is lost
    state = load_checkpoint(ckpt)
    assert (state["frames"], state["updates"]) == (768, 20)
    assert state["stopped"].startswith("non-finite loss")
    saved = state["agent"]["loss"]
    assert params and all(torch.equal(saved[k], v) for k, v in params.items())  # the bad update was not applied
    assert (ckpt / "buffer.pt").is_file()


def test_non_finite_loss_exits_3_with_one_line(tmp_path):
    """The CLI: exit status 3 and one line on stderr, no traceback."""
    script = (
        "import sys\n"
        "from morl_trl.objectives import EnvelopeQLoss\n"
        "forward = EnvelopeQLoss.forward\n"
        "def poisoned(self, td):\n"
        "    out = forward(self, td)\n"
        "    out['loss_qvalue'] = out['loss_qvalue'] * float('inf')\n"
        "    return out\n"
        "EnvelopeQLoss.forward = poisoned\n"
        "from morl_trl.cli import main\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("\n".join(f"{k} = {json.dumps(list(v) if isinstance(v, tuple) else v)}" for k, v in TINY.items()))
    run = tmp_path / "run"
    out = subprocess.run([sys.executable, "-c", script, "train", "envelope", "MOLavaGridDR-v0", "--config", str(cfg),
                          "--run-dir", str(run)], capture_output=True, text=True, timeout=900)  # (a hang guard)
    assert out.returncode == 3, out.stderr[-2000:]
    assert out.stderr.startswith("morl-trl train: stopped: non-finite loss {'loss_qvalue': inf}")
    assert out.stderr.count("\n") == 1 and "Traceback" not in out.stderr
    assert latest_checkpoint(run).name == "frames_000000000128"


def test_evaluate_video_writes_one_clip_per_context(tmp_path, capsys):
    from morl_trl.cli import main

    run = tmp_path / "run"
    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), logger="none",
                         **{**TINY, "frames": 256}))
    capsys.readouterr()
    assert main(["evaluate", str(run), "--video", "--weights", "2", "--video-format", "gif"]) == 0
    clips = sorted((run / "logs" / "reevaluation" / "videos").iterdir())
    assert [c.name for c in clips] == ["MOLavaGridRoom-v0_256.gif", "MOLavaGridSnake-v0_256.gif"]
    assert all(c.stat().st_size > 0 for c in clips)
    out = capsys.readouterr().out
    assert all(f"video: {c}" in out for c in clips)
    import imageio.v2 as imageio

    frames = imageio.mimread(clips[0])
    assert len(frames) >= 2 and frames[0].shape == (208, 208, 3)
