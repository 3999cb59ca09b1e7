"""The actor-critics' recipe (algorithms/actor_critic/recipe.py: train_actor_critic, for capql, mosac, mosac_discrete and
sac) from end to end: its updates, actor turns and temperature steps, and an interrupted run resumed exactly."""

import pytest

from morl_trl.recipes import resolve_config, train
from morl_trl.algorithms.actor_critic import recipe as actor_critic
from morl_trl.algorithms.registry import REGISTRY
from morl_trl.recipes.config import valid_keys
from tests.recipes._helpers import assert_checkpoints_equal, assert_logs_equal, interrupt_then_resume, last_checkpoints

# 128 frames in batches of 32, updates from 64 frames on (3 batches), checkpoints at 64 and 128, evaluations at
# 0 and 128. 3 updates per batch: with policy_freq 2 the actor turns (2 actor + 2 temperature steps each) fall
# on the 2nd, 4th, 6th and 8th updates, across batch boundaries, with critic-only updates between them
TINY = dict(frames=128, num_envs=2, frames_per_batch=32, init_random_frames=64, updates_per_batch=3, batch_size=16,
            hidden=(16, 16), buffer_size=1024, eval_interval=128, eval_weights=2, eval_episodes=1,
            checkpoint_interval=64, progress=False, eval_random_baseline=False)
HOPPER = dict(eval_contexts=("MOHopperDefault-v5",), eval_weights=3)
# (hard target copies every 4 updates, so that the 9 or 24 updates make some)
LAVA = dict(eval_contexts=("MOLavaGridRoom-v0",), target_update_period=4)

CASES = {  # id: (algo, env id, config changes, updates (= critic steps), actor steps)
    # policy_freq 2 (the authors' continuous SAC and MOSAC): 4 actor turns of 2 actor steps
    "sac-continuous": ("sac", "MOHopperDR-v5", HOPPER, 9, 8),
    # the authors' discrete SAC: one update per update_frequency=4 frames (8 per batch), an actor turn at each
    "sac-discrete": ("sac", "MOLavaGridDR-v0", dict(LAVA, updates_per_batch=0), 24, 24),
    # CAPQL: policy_freq 1 (an actor step at every update), fixed temperature; with PER
    "capql": ("capql", "MOHopperDR-v5", dict(HOPPER, prioritized=True), 9, 9),
    "mosac": ("mosac", "MOHopperDR-v5", HOPPER, 9, 8),
    # one step of the summed losses per update
    "mosac-joint": ("mosac", "MOHopperDR-v5", dict(HOPPER, policy_freq=1, joint_update=True), 9, 9),
    "mosac_discrete": ("mosac_discrete", "MOLavaGridDR-v0", dict(LAVA, prioritized=True), 9, 9),
}




@pytest.mark.parametrize("case", list(CASES))
def test_the_actor_critic_recipe_counts_its_updates_and_actor_steps(tmp_path, monkeypatch, case):
    algo, env_id, changes, updates, actor_steps = CASES[case]
    if env_id.startswith("MOHopper"):
        pytest.importorskip("mujoco")
    cfg = {k: v for k, v in {**TINY, **changes}.items() if k in valid_keys(algo)}
    assert set(changes) - {"eval_contexts"} <= set(cfg)  # (every change is a key of the algorithm)
    # (report.md's figures take seconds to draw and are not checked)
    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    calls = []
    real = actor_critic.update
    monkeypatch.setattr(actor_critic, "update", lambda agent, buffer: calls.append(1) or real(agent, buffer))
    assert REGISTRY[algo].train.func is actor_critic.train_actor_critic  # (bound to the algorithm's builder)
    assert REGISTRY[algo].train.keywords["make_agent"] is REGISTRY[algo].build_agent
    train(resolve_config(algo, env_id, run_dir=str(tmp_path / "recipe"), **cfg))
    assert len(calls) == updates  # (the loop's updates are the module's one update)
    (recipe,) = last_checkpoints(tmp_path / "recipe")
    assert (recipe["frames"], recipe["updates"], recipe["agent"]["critic_steps"]) == (128, updates, updates)
    # the critics' Adam stepped once per update, the actor's policy_freq times per actor turn
    steps = {name: int(opt["state"][0]["step"]) for name, opt in recipe["agent"]["optimizers"].items()}
    assert (steps["qvalue"], steps["actor"]) == (updates, actor_steps)
    if "alpha" in steps:  # (a learned temperature: one step after each actor step)
        assert steps["alpha"] == actor_steps


def test_a_mosac_run_interrupted_and_resumed_ends_as_the_uninterrupted_run(tmp_path, monkeypatch):
    """Ctrl-C after the batch at 96 frames (6 updates: actor turns at the 2nd, 4th and 6th; a checkpoint,
    RunInterrupted), then ``--resume``: MuJoCo snapshots its simulator, so the run continues exactly (the
    delayed actor's clock, critic_steps, comes back from the checkpoint: the 8th update is again an actor turn)."""
    pytest.importorskip("mujoco")
    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    cfg = {k: v for k, v in {**TINY, **HOPPER}.items() if k in valid_keys("mosac")}
    whole, resumed = tmp_path / "whole", tmp_path / "resumed"
    train(resolve_config("mosac", "MOHopperDR-v5", run_dir=str(whole), **cfg))
    interrupt_then_resume(monkeypatch, resolve_config("mosac", "MOHopperDR-v5", run_dir=str(resumed), **cfg), at=96)
    assert "resumed from frames_000000000096 at 96 frames" in (resumed / "log.txt").read_text()
    a, b = last_checkpoints(whole, resumed)
    assert (a["frames"], a["updates"], a["agent"]["critic_steps"]) == (128, 9, 9)
    assert_checkpoints_equal(a, b)
    assert_logs_equal(whole, resumed)
