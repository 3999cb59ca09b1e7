"""Run.session: the run management around any recipe's loop (a custom trainer's here: a random
policy, no learning), so that a new algorithm writes only its loop."""

import json
from types import SimpleNamespace

import pytest
from torchrl.collectors import Collector

from morl_trl.envs import domain_of, make_env
from morl_trl.evaluation import MultiContextEvaluator
from morl_trl.runs import Run, load_checkpoint
from morl_trl.runs.session import StopRun


class BudgetExceeded(StopRun):
    pass


def _run(tmp_path, frames=96):
    cfg = SimpleNamespace(algo="random", env_id="MOLavaGridDR-v0", seed=0, device="cpu", frames=frames,
                          eval_interval=64, checkpoint_interval=1_000, keep_checkpoints=2, progress=False,
                          logger="csv", init_random_frames=frames, eval_weights=2, run_dir=None)
    cfg.to_dict = lambda: {"frames": cfg.frames}
    cfg.save = lambda path: path.write_text(json.dumps(cfg.to_dict()))
    collector = Collector(make_env(cfg.env_id, num_envs=2, seed=0), None, frames_per_batch=32, total_frames=frames)
    evaluator = MultiContextEvaluator("random", ["MOLavaGridRoom-v0"], weights=2, seed=0)
    return Run(cfg, tmp_path / "run"), collector, evaluator


def test_a_stop_run_error_in_the_loop_checkpoints_the_last_good_state_and_says_why(tmp_path):
    run, collector, evaluator = _run(tmp_path)
    with pytest.raises(BudgetExceeded, match=r"^budget exceeded; the last good state is checkpointed in .*"
                                             r"frames_000000000064$"):
        with run.session(domain_of("MOLavaGridDR-v0"), evaluator=evaluator, snapshot=lambda: {"mine": 1},
                         collector=collector):
            for batch in collector:
                frames = run.collected(batch)
                if frames == 64:
                    err = BudgetExceeded("budget exceeded")
                    err.updates_done = 3
                    raise err
                run.step(updates=0)
    state = load_checkpoint(run.dir / "checkpoints" / "frames_000000000064")
    assert (state["frames"], state["updates"], state["stopped"], state["mine"]) == (64, 3, "budget exceeded", 1)
    assert "stopped: budget exceeded (at 64 frames, after 3 updates)" in (run.dir / "log.txt").read_text()
    assert "**Run stopped early.** stopped: budget exceeded" in (run.dir / "report.md").read_text()


def test_a_failed_first_evaluation_leaves_no_run_dir(tmp_path):
    run, collector, _ = _run(tmp_path)

    class Broken:
        def evaluate(self, *args):
            raise RuntimeError("the evaluator failed")

    with pytest.raises(RuntimeError, match="the evaluator failed"):
        with run.session(domain_of("MOLavaGridDR-v0"), evaluator=Broken(), snapshot=dict, collector=collector):
            pass
    assert not run.dir.exists()
