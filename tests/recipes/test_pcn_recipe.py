"""PCN's own recipe (recipes/pcn.py: train_pcn) trains exactly as the generic Agent loop (off_policy.train_agent
with PCNAgent.learn) did before it: same network, optimizer, episode replay, unfinished episodes, command, counters,
env, RNG, evaluations and logs, from the same seed."""

import pytest

from morl_trl.recipes import off_policy, resolve_config, train
from morl_trl.recipes.config import valid_keys
from morl_trl.recipes.pcn import PCNAgent
from tests.recipes._helpers import assert_checkpoints_equal, assert_logs_equal, interrupt_then_resume, last_checkpoints

# batches of 64 frames from 4 sub-envs; the warm-up is the first 2 finished episodes, then a round of 3 updates
# (and a new command) after every 2 more; checkpoints every 128 frames, evaluations at 0 and at the end
TINY = dict(num_envs=4, frames_per_batch=64, pcn_er_episodes=2, pcn_step_episodes=2, pcn_model_updates=3,
            batch_size=16, hidden=(16, 16), eval_weights=2, checkpoint_interval=128, progress=False,
            eval_random_baseline=False)




def _both(tmp_path, monkeypatch, env_id, **kw):
    """The recipe's run and the Agent loop's run of PCN on ``env_id`` (TINY + ``kw``), checked equal: every entry
    of their last checkpoints, metrics.csv and losses.csv rows. Returns the recipe's last checkpoint."""
    cfg = {k: v for k, v in {**TINY, **kw}.items() if k in valid_keys("pcn")}
    # (report.md's figures take seconds to draw and are not compared)
    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    calls = {"learn": 0}
    learn = PCNAgent.learn

    def counted(self, *args):
        calls["learn"] += 1
        return learn(self, *args)
    monkeypatch.setattr(PCNAgent, "learn", counted)
    assert off_policy.RECIPES["pcn"].__name__ == "train_pcn"
    train(resolve_config("pcn", env_id, run_dir=str(tmp_path / "recipe"), **cfg))
    assert calls["learn"] == 0  # (two different loops ran)
    monkeypatch.delitem(off_policy.RECIPES, "pcn")  # the loop of every Agent, with PCNAgent.learn
    train(resolve_config("pcn", env_id, run_dir=str(tmp_path / "agent"), **cfg))
    assert calls["learn"] == cfg["frames"] // cfg["frames_per_batch"]
    recipe, agent = last_checkpoints(tmp_path / "recipe", tmp_path / "agent")
    assert_checkpoints_equal(recipe, agent)
    assert_logs_equal(tmp_path / "recipe", tmp_path / "agent")
    return recipe


def test_the_pcn_recipe_trains_exactly_as_the_agent_loop(tmp_path, monkeypatch):
    state = _both(tmp_path, monkeypatch, "MOLavaGridDR-v0", num_envs=2, frames_per_batch=128, frames=1024,
                  eval_interval=1024, checkpoint_interval=512, eval_contexts=("MOLavaGridRoom-v0",))
    agent = state["agent"]
    # the 2 sub-envs' random episodes are truncated at 256 steps (512 frames): the warm-up's 2 episodes, a round
    # (3 updates, a command); the next 2 (acting on the command) end at 1024 frames: the second round
    assert (state["frames"], state["updates"]) == (1024, 6)
    assert (agent["episodes"], agent["rounds"], agent["next_round"]) == (4, 2, 6)
    assert agent["random_actions"] is False and agent["pending"] == {}
    assert agent["command"][1].item() == 254.0  # the chosen episode's length - 2
    assert sorted(agent["replay"]["length"].tolist()) == [256] * 4


def test_the_continuous_pcn_recipe_trains_exactly_as_the_agent_loop(tmp_path, monkeypatch):
    pytest.importorskip("mujoco")
    state = _both(tmp_path, monkeypatch, "MOHopperDR-v5", num_envs=2, frames=512, eval_interval=512, eval_weights=3,
                  eval_contexts=("MOHopperDefault-v5",))
    agent = state["agent"]
    # Hopper's episodes are short (it falls): 40 episodes in 512 frames, a round every 2 after the warm-up's 2
    assert (state["frames"], state["updates"]) == (512, 24)
    assert (agent["episodes"], agent["rounds"], agent["next_round"]) == (40, 8, 42)
    assert agent["random_actions"] is False
    # sub-env 1's unfinished episode: 9 steps so far
    assert {i: piece["reward"].shape for i, piece in agent["pending"].items()} == {1: (9, 3)}


@pytest.mark.slow  # (three short runs)
def test_a_pcn_run_interrupted_and_resumed_ends_as_the_uninterrupted_run(tmp_path, monkeypatch):
    """Ctrl-C after the batch at 512 frames (the warm-up's episodes and the first round: a checkpoint,
    RunInterrupted), then ``--resume``: MO-LavaGrid snapshots its simulator, so the run continues exactly (the
    replay, the unfinished episodes, the command and the generator come back from the checkpoint)."""



    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    cfg = {k: v for k, v in TINY.items() if k in valid_keys("pcn")} | dict(
        num_envs=2, frames_per_batch=128, frames=1024, eval_interval=1024, checkpoint_interval=512,
        eval_contexts=("MOLavaGridRoom-v0",))
    whole, resumed = tmp_path / "whole", tmp_path / "resumed"
    train(resolve_config("pcn", "MOLavaGridDR-v0", run_dir=str(whole), **cfg))
    interrupt_then_resume(monkeypatch, resolve_config("pcn", "MOLavaGridDR-v0", run_dir=str(resumed), **cfg), at=512)
    log = (resumed / "log.txt").read_text()
    assert "resumed from frames_000000000512 at 512 frames" in log and "fresh episodes" not in log
    a, b = last_checkpoints(whole, resumed)
    assert (a["frames"], a["updates"], a["agent"]["rounds"]) == (1024, 6, 2)
    assert_checkpoints_equal(a, b)
    assert_logs_equal(whole, resumed)
