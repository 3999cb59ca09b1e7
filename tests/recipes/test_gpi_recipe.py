"""GPI-LS / GPI-PD's own recipe (recipes/gpi.py: train_gpi) trains exactly as the generic Agent loop
(off_policy.train_agent with GPIAgent.learn) did before it: same networks, optimizers, linear support,
weight, support, iteration, dynamics model, counters, env, RNG, evaluations and logs, from the same seed."""

import pytest

from morl_trl.recipes import off_policy, resolve_config, train
from morl_trl.recipes.config import valid_keys
from morl_trl.recipes.gpi import GPIAgent
from tests.recipes._helpers import assert_checkpoints_equal, assert_logs_equal, interrupt_then_resume, last_checkpoints

# 192 frames in batches of 32: iterations end at 64, 128 and 192 (the CCS grows, w and M change), updates from
# 64 frames; GPI-PD fits its model at 128 and rolls it out every 32 frames from 64 (the updates then mix in
# model transitions); checkpoints at 128 and 192, evaluations at 0 and 192
TINY = dict(frames=192, num_envs=4, frames_per_batch=32, init_random_frames=64, updates_per_batch=2, batch_size=16,
            hidden=(16, 16), buffer_size=1024, gpi_iteration_frames=64, gpi_front_episodes=1,
            gpi_dynamics_hidden=(16,), gpi_dynamics_train_freq=128, gpi_dynamics_rollout_freq=32,
            gpi_dynamics_rollout_starts=64, gpi_dynamics_rollout_batch=50, gpi_uncertainty_threshold=1e9,
            target_update_period=64, eval_interval=192, eval_weights=2, checkpoint_interval=128,
            eval_contexts=("MOLavaGridRoom-v0",), progress=False, eval_random_baseline=False)




def _both(tmp_path, monkeypatch, algo, env_id, **kw):
    """The recipe's run and the Agent loop's run of ``algo`` on ``env_id`` (TINY + ``kw``), checked equal: every
    entry of their last checkpoints, metrics.csv and losses.csv rows, the Dyna calls. Returns the recipe's last
    checkpoint and its Dyna calls."""
    cfg = {k: v for k, v in {**TINY, **kw}.items() if k in valid_keys(algo)}
    # (report.md's figures take seconds to draw and are not compared)
    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    calls = {"fit_model": 0, "rollout_model": 0, "learn": 0}

    def counted(name):
        method = getattr(GPIAgent, name)

        def wrapped(self, *args):
            calls[name] += 1
            return method(self, *args)
        monkeypatch.setattr(GPIAgent, name, wrapped)

    for name in calls:
        counted(name)
    assert off_policy.RECIPES[algo].__name__ == "train_gpi"
    train(resolve_config(algo, env_id, run_dir=str(tmp_path / "recipe"), **cfg))
    recipe_calls = dict(calls)
    monkeypatch.delitem(off_policy.RECIPES, algo)  # the loop of every Agent, with GPIAgent.learn
    train(resolve_config(algo, env_id, run_dir=str(tmp_path / "agent"), **cfg))
    agent_calls = {k: v - recipe_calls[k] for k, v in calls.items()}
    batches = cfg["frames"] // cfg["frames_per_batch"]
    assert (recipe_calls.pop("learn"), agent_calls.pop("learn")) == (0, batches)  # (two different loops ran)
    assert agent_calls == recipe_calls  # the same Dyna in both
    recipe, agent = last_checkpoints(tmp_path / "recipe", tmp_path / "agent")
    assert_checkpoints_equal(recipe, agent)
    assert_logs_equal(tmp_path / "recipe", tmp_path / "agent")
    return recipe, recipe_calls


@pytest.mark.parametrize("algo", ["gpi_ls", "gpi_pd"])
def test_the_gpi_recipe_trains_exactly_as_the_agent_loop(tmp_path, monkeypatch, algo):
    state, calls = _both(tmp_path, monkeypatch, algo, "deep-sea-treasure-v0", eval_contexts=None)
    assert (state["frames"], state["updates"]) == (192, 10)  # 2 updates per batch from 64 frames on (5 batches)
    agent = state["agent"]
    # the iteration boundaries at 64, 128 and 192 each evaluated GPI over M at its 2 weights (added to the linear
    # support); those at 64 and 128 then, after the run's step, at the corner weights of the CCS (the next w): 5
    # evaluations; the run's last frame begins no 4th iteration (issue 48: MB begins none after its last)
    assert (agent["iteration"], agent["iteration_end"], agent["frames"], agent["evaluations"]) == (3, 256, 192, 5)
    assert agent["begin_pending"]
    assert len(agent["linear_support"]["visited"]) == 6
    # GPI-PD: one model fit (at 128) and rollouts every 32 frames from 64 (5 batches)
    assert calls == ({"fit_model": 1, "rollout_model": 5} if algo == "gpi_pd" else {"fit_model": 0, "rollout_model": 0})
    assert (agent["dynamics"] is not None) == (algo == "gpi_pd")


@pytest.mark.parametrize("algo", ["gpi_ls", "gpi_pd"])
def test_the_continuous_gpi_recipe_trains_exactly_as_the_agent_loop(tmp_path, monkeypatch, algo):
    pytest.importorskip("mujoco")
    state, calls = _both(tmp_path, monkeypatch, algo, "MOHopperDR-v5", num_envs=2, eval_weights=3,
                         eval_contexts=("MOHopperDefault-v5",), gpi_dynamics_rollout_len=2)
    assert (state["frames"], state["updates"]) == (192, 10)
    assert state["agent"]["updates"] == 10  # the continuous update count (the delayed actor's clock)
    assert (state["agent"]["iteration"], state["agent"]["iteration_end"]) == (3, 256)
    assert calls == ({"fit_model": 1, "rollout_model": 5} if algo == "gpi_pd" else {"fit_model": 0, "rollout_model": 0})


@pytest.mark.slow  # (~10 s)
def test_a_gpi_ls_run_interrupted_and_resumed_ends_as_the_uninterrupted_run(tmp_path, monkeypatch):
    """Ctrl-C after the batch at 64 frames (its updates and the first iteration's end: a checkpoint,
    RunInterrupted), then ``--resume``: MO-LavaGrid snapshots its simulator, so the run continues exactly
    (the CCS, w, M, the iteration and the CCS evaluations' seeds come back from the checkpoint)."""
    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    cfg = {k: v for k, v in TINY.items() if k in valid_keys("gpi_ls")} | dict(frames=128, eval_interval=128)
    whole, resumed = tmp_path / "whole", tmp_path / "resumed"
    train(resolve_config("gpi_ls", "MOLavaGridDR-v0", run_dir=str(whole), **cfg))
    interrupt_then_resume(monkeypatch, resolve_config("gpi_ls", "MOLavaGridDR-v0", run_dir=str(resumed), **cfg), at=64)
    log = (resumed / "log.txt").read_text()
    assert "resumed from frames_000000000064 at 64 frames" in log and "fresh episodes" not in log
    a, b = last_checkpoints(whole, resumed)
    assert (a["frames"], a["updates"], a["agent"]["iteration"]) == (128, 6, 2)  # (no iteration begins after the last frame)
    assert_checkpoints_equal(a, b)
    assert_logs_equal(whole, resumed)
