"""Envelope's own recipe (recipes/envelope.py: train_envelope) trains exactly as the generic Agent
loop (off_policy.train_agent with agent.learn) did before it: same networks, optimizer, counters,
evaluations and logs, from the same seed."""

from morl_trl.recipes import resolve_config, train
from morl_trl.recipes import off_policy
from tests.recipes._helpers import assert_checkpoints_equal, assert_logs_equal, last_checkpoints

SMALL = dict(frames=256, num_envs=4, frames_per_batch=32, init_random_frames=64, updates_per_batch=2, batch_size=16,
             hidden=(16, 16), eval_interval=128, eval_weights=2, checkpoint_interval=128, buffer_size=1024,
             eval_contexts=("MOLavaGridRoom-v0",), progress=False, eval_random_baseline=False)



def test_the_envelope_recipe_trains_exactly_as_the_agent_loop(tmp_path, monkeypatch):
    assert off_policy.RECIPES["envelope"].__name__ == "train_envelope"
    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(tmp_path / "recipe"), **SMALL))
    monkeypatch.delitem(off_policy.RECIPES, "envelope")  # the loop of every Agent
    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(tmp_path / "agent"), **SMALL))
    recipe, agent = last_checkpoints(tmp_path / "recipe", tmp_path / "agent")
    assert (recipe["frames"], recipe["updates"], recipe["agent"]["critic_steps"]) == (256, 14, 14)  # 2 updates per batch from 64 frames on
    assert recipe["agent"].keys() == agent["agent"].keys() == {"loss", "optimizers", "target_updater_counter",
                                                                "critic_steps"}
    assert_checkpoints_equal(recipe, agent)
    assert_logs_equal(tmp_path / "recipe", tmp_path / "agent")

