"""The replay buffer keeps what the loss reads, nothing more (issue 31: a one-env run stores every frame)."""

import pytest
import torch

from morl_trl.recipes import build_agent, build_training_env, resolve_config
from morl_trl.algorithms.registry import algorithm
from morl_trl.training.parts import make_collector, make_replay_buffer

CPU = torch.device("cpu")


@pytest.mark.parametrize("algo, env_id", [("envelope", "deep-sea-treasure-v0"), ("gpi_ls", "deep-sea-treasure-v0"),
                                          ("capql", "mo-mountaincarcontinuous-v0")])
def test_the_buffer_stores_exactly_the_entries_the_loss_reads(algo, env_id):
    cfg = resolve_config(algo, env_id, hidden=[8], batch_size=4, frames=6, init_random_frames=100,
                         buffer_size=100)
    env = build_training_env(cfg, CPU)
    agent = build_agent(cfg, env, gamma=0.99, device=CPU)
    buffer = make_replay_buffer(cfg, CPU)
    collector = make_collector(cfg, env, agent.explore_policy, CPU)
    batches = []
    for batch in collector:
        batches.append(batch)
        algorithm(algo).on_batch(agent, batch, buffer, sum(b.numel() for b in batches))
    collector.shutdown()
    stored = set(buffer.storage[torch.arange(len(buffer))].keys(True, True)) - {"index"}
    assert agent.replay_keys == list(agent.loss.in_keys)
    assert stored == set(agent.loss.in_keys)
    assert len(set(batches[0].keys(True, True))) > len(stored) + 5  # (episode returns, "next" preference, ...)
    # the stored values are the collected ones
    for key in agent.loss.in_keys:
        assert torch.equal(buffer.storage[torch.arange(6)][key], torch.cat([b[key].reshape(-1, *b[key].shape[2:])
                                                                           for b in batches]))
    sample = buffer.sample()
    assert set(agent.loss.in_keys) <= set(sample.keys(True, True))


def test_collected_batches_carry_no_trajectory_ids():
    """``track_traj_ids=False``: TorchRL's per-step trajectory bookkeeping, which nothing here reads, is off."""
    cfg = resolve_config("envelope", "deep-sea-treasure-v0", hidden=[8], frames=3, init_random_frames=0)
    env = build_training_env(cfg, CPU)
    agent = build_agent(cfg, env, gamma=0.99, device=CPU)
    collector = make_collector(cfg, env, agent.explore_policy, CPU)
    batch = next(iter(collector))
    collector.shutdown()
    assert ("collector", "traj_ids") not in batch.keys(True, True)
    assert {"observation", "action", ("next", "reward"), ("next", "episode_return")} <= set(batch.keys(True, True))
