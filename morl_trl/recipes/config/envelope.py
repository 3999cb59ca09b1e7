"""Envelope Q-learning (Yang et al. 2019): its keys, and the authors' values per domain.

Source of every value: ``hyperparameters.toml`` ``[envelope.<domain>]`` (the authors' scripts and
their Envelope defaults); ``morl-trl config envelope ENV --compare-authors`` lists each setting.

Example:
    >>> EnvelopeConfig().num_sampled_prefs, DEFAULTS[LAVA_GRID]["num_sampled_prefs"]
    (8, 4)
"""

from __future__ import annotations

from morl_trl.recipes.config.domains import LAVA_GRID, MARIO, domain_table, frozen
from morl_trl.recipes.config.families import DQN_EXPLORATION, DQN_OPTIM, DQN_REPLAY, algorithm_config, pick

__all__ = ["EnvelopeConfig", "SHARED_DEFAULTS", "DEFAULTS", "QUICK"]


EnvelopeConfig = algorithm_config(
    "EnvelopeConfig", "Envelope's keys (LunarLander's values: ``[envelope.lunarlander]``).",
    # collector and replay (PER without importance weights, priority from the first sampled weight;
    # MORL-Baselines' buffer: (p + running max)^alpha, new items at the max)
    DQN_REPLAY, dict(envelope_priority="first", per_running_max=True),
    # optim: one update per frame, hard target copy every 1000 updates, gradient norm 1
    pick(DQN_OPTIM, max_grad_norm=1.0),
    # network: w concatenated after the first hidden layer, orthogonal init
    dict(hidden=(256, 256, 256, 256), envelope_network="authors"),
    # exploration: epsilon 1 -> 0.05 over 1M frames after learning_starts
    DQN_EXPLORATION,
    # preferences: |N(0, I)| normalised, one per episode; 8 sampled per update; lambda fixed at 0.95
    dict(preference_distribution="gaussian", preference_resample="episode", num_sampled_prefs=8, homotopy_lambda0=0.95,
         homotopy_final=None, homotopy_frames=None),
)


SHARED_DEFAULTS = frozen({})
DEFAULTS = domain_table({
    LAVA_GRID: dict(eps_frames=5_000_000, target_update_period=200, num_sampled_prefs=4),
    MARIO: dict(batch_size=64, init_random_frames=25_000, buffer_size=100_000, eps_start=0.2, eps_end=0.01,
                hidden=(512,)),  # net_arch [512, 512]: the CNN's 512 features, then one 512 layer
})
QUICK = frozen({})
