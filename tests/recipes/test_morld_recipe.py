"""MORL/D's own recipe (recipes/morld.py: train_morld) trains exactly as the generic Agent loop
(off_policy.train_agent with agent.learn) did before it: the same members, optimizers, archive, counters,
evaluations and logs, from the same seed, on both schedules (round robin with its catch-up updates and env
resets at the exchanges, PSA's weight adaptation, concurrent)."""

import importlib.util

import pytest
import torch

from morl_trl.preferences import energy_weights
from morl_trl.recipes import off_policy, resolve_config, train
from morl_trl.recipes.morld import MORLDAgent
from tests.recipes._helpers import assert_checkpoints_equal, assert_logs_equal, last_checkpoints

# round robin: 3 members, turns of 20 frames (2 batches), 60 frames = 3 turns (one per member)
ROUND_ROBIN = dict(pop_size=3, num_envs=1, frames_per_batch=10, exchange_every=20, init_random_frames=10,
                   batch_size=8, hidden=(8,), frames=60, morld_update_passes=2, morld_eval_episodes=1,
                   eval_interval=40, eval_weights=2, checkpoint_interval=40, buffer_size=512, seed=0, progress=False,
                   eval_random_baseline=False)
LAVA = dict(target_update_period=5, eval_contexts=("MOLavaGridRoom-v0",))


def _both(tmp_path, monkeypatch, algo, env_id, **kw):
    """The checkpoints of a run through the recipe and through the Agent loop (``agent.learn`` counted)."""
    calls = []
    learn = MORLDAgent.learn
    monkeypatch.setattr(MORLDAgent, "learn", lambda self, *a: calls.append(1) or learn(self, *a))
    assert off_policy.RECIPES[algo].__name__ == "train_morld"
    train(resolve_config(algo, env_id, run_dir=str(tmp_path / "recipe"), **kw))
    assert calls == []  # (the recipe's loop is its own)
    monkeypatch.delitem(off_policy.RECIPES, algo)  # the loop of every Agent
    train(resolve_config(algo, env_id, run_dir=str(tmp_path / "agent"), **kw))
    assert calls  # (the Agent loop's)
    recipe, agent = last_checkpoints(tmp_path / "recipe", tmp_path / "agent")
    assert_checkpoints_equal(recipe, agent)
    assert_logs_equal(tmp_path / "recipe", tmp_path / "agent")
    return recipe


def _round_robin_counters(state, passes=2):
    m = state["agent"]["morld"]
    # 6 batches of 10 frames; the acting member updates once per frame after frame 10 (frames 11..59: 49);
    # at each of the 3 exchanges `passes` catch-up updates, each of the 2 other members at once
    assert (state["frames"], state["updates"]) == (60, 49 + 3 * passes)
    assert (m["exchanges"], m["env_resets"], m["active"], m["turn_frames"]) == (3, 3, 0, 0)
    assert m["frames_per_member"].tolist() == [20, 20, 20]
    # member 0: its turn's frames 11..19, then catch-ups at 2 exchanges; members 1 and 2: 20 + 2 catch-ups
    assert m["member_updates"].tolist() == [9 + 2 * passes, 20 + 2 * passes, 20 + 2 * passes]
    assert m["eval_episodes"] == 3 * 3  # one episode per member at each exchange


def test_the_morld_recipe_trains_exactly_as_the_agent_loop_round_robin(tmp_path, monkeypatch):
    state = _both(tmp_path, monkeypatch, "morld", "MOLavaGridDR-v0", **ROUND_ROBIN, **LAVA)
    _round_robin_counters(state)


@pytest.mark.slow  # (~20 s on a loaded 2-core machine: two runs, each evaluated)
def test_the_morld_psa_recipe_trains_exactly_as_the_agent_loop(tmp_path, monkeypatch):
    state = _both(tmp_path, monkeypatch, "morld_psa", "MOLavaGridDR-v0", **ROUND_ROBIN, **LAVA)
    _round_robin_counters(state)
    weights = state["agent"]["loss"]["weights"]  # (PSA moved them away from the energy weights)
    assert weights.shape == (3, 2) and not torch.equal(weights, energy_weights(2, 3, seed=0, dtype=torch.float32))


@pytest.mark.slow  # (~20 s on a loaded 2-core machine: two runs, each evaluated)
def test_the_morld_recipe_trains_exactly_as_the_agent_loop_concurrent(tmp_path, monkeypatch):
    kw = dict(ROUND_ROBIN, frames_per_batch=12, num_envs=2, frames=60, updates_per_batch=2, exchange_every=24,
              eval_interval=36, checkpoint_interval=36)
    state = _both(tmp_path, monkeypatch, "morld", "MOLavaGridDR-v0", morld_schedule="concurrent", **kw, **LAVA)
    m = state["agent"]["morld"]
    # 5 batches of 12 frames (2 per member and sub-env), 2 updates of all members per batch (all past
    # init_random_frames=10); an exchange every 24 frames
    assert (state["frames"], state["updates"], m["exchanges"], m["env_resets"]) == (60, 10, 2, 0)


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("mujoco") is None, reason="needs mujoco")
def test_the_morld_recipe_trains_exactly_as_the_agent_loop_on_hopper(tmp_path, monkeypatch):
    state = _both(tmp_path, monkeypatch, "morld", "MOHopperDR-v5", **dict(ROUND_ROBIN, eval_weights=3),
                  eval_contexts=("MOHopperDefault-v5",))
    _round_robin_counters(state)
