"""What a run shows while it runs: one bar with the time left and the latest evaluation's NHGR
(the last one at the end), and log.txt with every evaluation."""

import json
from types import SimpleNamespace

from torchrl.collectors import Collector

from morl_trl.envs import domain_of, make_env
from morl_trl.evaluation import MultiContextEvaluator
from morl_trl.reporting import load_domain_reference
from morl_trl.runs import Run


def test_the_bar_ends_on_the_last_evaluation_and_log_txt_has_every_one(tmp_path, capsys):
    cfg = SimpleNamespace(algo="random", env_id="MOLavaGridDR-v0", seed=0, device="cpu", frames=96, eval_interval=64,
                          checkpoint_interval=1_000, keep_checkpoints=2, progress=True, logger="csv",
                          init_random_frames=96, eval_weights=2, run_dir=None, reference_dir=None)
    cfg.to_dict = lambda: {"frames": cfg.frames}
    cfg.save = lambda path: path.write_text(json.dumps(cfg.to_dict()))
    ref = load_domain_reference("MOLavaGridDR-v0")
    evaluator = MultiContextEvaluator("random", ["MOLavaGridRoom-v0"], weights=2, seed=0, reference=ref)
    env = make_env(cfg.env_id, num_envs=2, seed=0)
    collector = Collector(env, None, frames_per_batch=32, total_frames=cfg.frames)
    run = Run(cfg, tmp_path / "run")
    with run.session(domain_of(cfg.env_id), ref, evaluator=evaluator, snapshot=lambda: {}, collector=collector):
        for batch in collector:
            run.collected(batch)
            run.step()
    nhgr = run.summary["nhgr_mean"]
    bars = [part for part in capsys.readouterr().err.replace("\r", "\n").splitlines() if "|" in part]
    assert bars[-1].strip().startswith("100%") and "96/96" in bars[-1]
    assert bars[-1].rstrip().endswith(f"finishing, NHGR {nhgr:.3f} @ 96]")
    # the evaluation at 64 frames at once, not a batch later
    assert any(bar.rstrip().endswith("left: measuring, NHGR 0.000 @ 64]") for bar in bars)
    log = (tmp_path / "run" / "log.txt").read_text().splitlines()
    evals = [line[20:].split(" (")[0] for line in log if "[eval @ " in line]
    assert evals == ["[eval @ 0 frames", "[eval @ 64 frames", "[eval @ 96 frames"]
    assert all("s)] mean over contexts: nhgr 0, normalized_hypervolume 0" in line for line in log[1:4])
