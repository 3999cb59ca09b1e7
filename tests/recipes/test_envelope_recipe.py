"""Envelope's recipe (algorithms/envelope/recipe.py: train_envelope) from end to end: its counters and checkpoint."""

from morl_trl.recipes import resolve_config, train
from morl_trl.algorithms.registry import REGISTRY
from tests.recipes._helpers import last_checkpoints

SMALL = dict(frames=256, num_envs=4, frames_per_batch=32, init_random_frames=64, updates_per_batch=2, batch_size=16,
             hidden=(16, 16), eval_interval=128, eval_weights=2, checkpoint_interval=128, buffer_size=1024,
             eval_contexts=("MOLavaGridRoom-v0",), progress=False, eval_random_baseline=False)


def test_the_envelope_recipe_updates_twice_per_batch_from_init_random_frames(tmp_path):
    assert REGISTRY["envelope"].train.__name__ == "train_envelope"
    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(tmp_path / "recipe"), **SMALL))
    (recipe,) = last_checkpoints(tmp_path / "recipe")
    assert (recipe["frames"], recipe["updates"], recipe["agent"]["critic_steps"]) == (256, 14, 14)  # 2 updates per batch from 64 frames on
    assert recipe["agent"].keys() == {"loss", "optimizers", "target_updater_counter", "critic_steps"}
    assert int(recipe["agent"]["optimizers"]["qvalue"]["state"][0]["step"]) == 14
