"""Envelope's own recipe (recipes/envelope.py: train_envelope) trains exactly as the generic Agent
loop (off_policy.train_agent with agent.learn) did before it: same networks, optimizer, counters,
evaluations and logs, from the same seed."""

import csv

import numpy as np
import torch
from tensordict import TensorDictBase

from morl_trl.recipes import resolve_config, train
from morl_trl.recipes import off_policy
from morl_trl.runs import latest_checkpoint, load_checkpoint

SMALL = dict(frames=256, num_envs=4, frames_per_batch=32, init_random_frames=64, updates_per_batch=2, batch_size=16,
             hidden=(16, 16), eval_interval=128, eval_weights=2, checkpoint_interval=128, buffer_size=1024,
             eval_contexts=("MOLavaGridRoom-v0",), progress=False, eval_random_baseline=False)


def _equal(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and np.array_equal(a, b)
    if isinstance(a, TensorDictBase):
        return _equal(a.to_dict(), b.to_dict())
    if torch.is_tensor(a):
        return torch.is_tensor(b) and a.shape == b.shape and torch.equal(a, b)
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b))
    return a == b


def test_the_envelope_recipe_trains_exactly_as_the_agent_loop(tmp_path, monkeypatch):
    assert off_policy.RECIPES["envelope"].__name__ == "train_envelope"
    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(tmp_path / "recipe"), **SMALL))
    monkeypatch.delitem(off_policy.RECIPES, "envelope")  # the loop of every Agent
    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(tmp_path / "agent"), **SMALL))
    recipe, agent = (load_checkpoint(latest_checkpoint(tmp_path / name)) for name in ("recipe", "agent"))
    assert (recipe["frames"], recipe["updates"], recipe["agent"]["critic_steps"]) == (256, 14, 14)  # 2 updates per batch from 64 frames on
    assert recipe["agent"].keys() == agent["agent"].keys() == {"loss", "optimizers", "target_updater_counter",
                                                                "critic_steps"}
    for key in ("agent", "env", "carrier", "rng", "frames", "updates", "next_eval", "next_ckpt", "last_eval"):
        assert _equal(recipe[key], agent[key]), key
    for rel in ("eval/metrics.csv", "train/losses.csv"):
        assert _rows(tmp_path / "recipe" / rel) == _rows(tmp_path / "agent" / rel), rel


def _rows(path) -> list[dict]:
    with path.open() as fh:  # (the frame rate is the machine's)
        return [{k: v for k, v in row.items() if k != "frames_per_second"} for row in csv.DictReader(fh)]
