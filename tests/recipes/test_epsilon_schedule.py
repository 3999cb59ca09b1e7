"""ε-greedy's schedule starts at the learning start, as the authors' and MB's ``linearly_decaying_value(initial,
decay_steps, global_step, learning_starts, final)`` (SPEC §6 Envelope: ε ends at 0.050019 after LavaGrid's 5M frames)."""

import pytest
import torch

from morl_trl.algorithms.envelope.recipe import schedules as envelope_schedules
from morl_trl.algorithms.gpi.recipe import schedules as gpi_schedules
from morl_trl.recipes import build_agent, build_training_env, resolve_config


@pytest.mark.parametrize("algo, schedules", [("envelope", envelope_schedules), ("gpi_ls", gpi_schedules)])
def test_the_decay_starts_at_init_random_frames(algo, schedules):
    cfg = resolve_config(algo, "deep-sea-treasure-v0", hidden=[8], batch_size=4, init_random_frames=100,
                         eps_start=1.0, eps_end=0.1, eps_frames=1_000, seed=0)
    env = build_training_env(cfg, torch.device("cpu"))
    agent = build_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
    try:
        seen = {}
        for frames in (50, 100, 600, 1_100, 5_000):
            schedules(agent, frames)
            seen[frames] = round(float(agent.exploration_module.eps), 6)
        # 1.0 until the learning starts (frame 100), halfway at 100 + 500, eps_end from 100 + 1,000 on
        assert seen == {50: 1.0, 100: 1.0, 600: 0.55, 1_100: 0.1, 5_000: 0.1}
    finally:
        env.close()
