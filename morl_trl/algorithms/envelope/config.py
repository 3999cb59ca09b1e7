"""Envelope Q-learning (Yang et al. 2019): its keys, and the authors' values per domain.

Source of every value: ``hyperparameters.toml`` ``[envelope.<domain>]`` (the authors' scripts and
their Envelope defaults); ``morl-trl config envelope ENV --compare-authors`` lists each setting.

Example:
    >>> EnvelopeConfig().num_sampled_prefs, DEFAULTS[LAVA_GRID]["num_sampled_prefs"]
    (8, 4)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.algorithms.domains import LAVA_GRID, MARIO, domain_table, frozen

__all__ = ["EnvelopeConfig", "SHARED_DEFAULTS", "DEFAULTS"]


@dataclass
class EnvelopeConfig:
    """Envelope's keys (LunarLander's values: ``[envelope.lunarlander]``); what each means: ``KEYS``.

    Source of each default: ``[envelope.lunarlander.<table>] <setting>`` of ``hyperparameters.toml``,
    "MB" (MORL-Baselines' class default, which the record lists), or "ours" (no counterpart).
    """

    # collector and replay
    frames_per_batch: int = 64  # ours (the authors step one env between updates)
    init_random_frames: int = 100  # init.learning_starts
    buffer_size: int = 1_000_000  # init.buffer_size
    batch_size: int = 128  # init.batch_size
    prioritized: bool = True  # init.per
    per_alpha: float = 0.6  # init.per_alpha
    per_beta: float = 0.4  # ours (TorchRL's; unused: per_importance_weights is false)
    per_importance_weights: bool = False  # init.per (MB's PER without importance weights)
    envelope_priority: str = "first"  # init.per_alpha's note: |w.TD| under the first sampled weight
    per_running_max: bool = True  # init.per: MB's buffer, (p + running max)^alpha, new items at the max
    # optim
    lr: float = 3e-4  # init.learning_rate
    updates_per_batch: int = 0  # init.gradient_updates 1: one update per frame
    target_update_period: int = 1000  # init.target_net_update_freq
    tau: float | None = None  # init.tau 1.0: hard copies
    max_grad_norm: float | None = 1.0  # init.max_grad_norm
    # network
    hidden: tuple[int, ...] = (256, 256, 256, 256)  # init.net_arch
    envelope_network: str = "authors"  # network.weight_input: w after the first hidden layer, orthogonal init
    # exploration: epsilon 1 -> 0.05 over 1M frames after learning_starts
    eps_start: float = 1.0  # init.initial_epsilon
    eps_end: float = 0.05  # init.final_epsilon
    eps_frames: int = 1_000_000  # init.epsilon_decay_steps
    # preferences
    preference_distribution: str = "gaussian"  # init.dist (|N(0, I)| normalised)
    preference_resample: str = "episode"  # train.weight None: a new weight per episode
    num_sampled_prefs: int = 8  # init.num_sample_w
    homotopy_lambda0: float = 0.95  # init.initial_homotopy_lambda
    homotopy_final: float | None = None  # init.homotopy_decay_steps None: lambda stays at homotopy_lambda0
    homotopy_frames: int | None = None  # ours (used only with homotopy_final)


SHARED_DEFAULTS = frozen({})
DEFAULTS = domain_table({
    LAVA_GRID: dict(eps_frames=5_000_000, target_update_period=200, num_sampled_prefs=4),
    MARIO: dict(batch_size=64, init_random_frames=25_000, buffer_size=100_000, eps_start=0.2, eps_end=0.01,
                hidden=(512,)),  # net_arch [512, 512]: the CNN's 512 features, then one 512 layer
})
