"""GPI-LS and GPI-PD (Alegre et al. 2023): their keys, and the authors' values per domain.

Source: ``hyperparameters.toml`` ``[gpi_ls.<domain>]`` and ``[gpi_pd.<domain>]`` (GPIPD on discrete
actions, GPIPDContinuousAction on MuJoCo); ``morl-trl config gpi_ls ENV --compare-authors`` lists
each setting. Every script passes ``gradient_updates 1``.

Example:
    >>> GPILSConfig().gpi_gradient_updates, DEFAULTS_PD[HOPPER]["gpi_iteration_frames"]
    (1, 25000)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.recipes.config.domains import (
    HALF_CHEETAH,
    HOPPER,
    HUMANOID,
    LAVA_GRID,
    LUNAR_LANDER,
    MARIO,
    domain_table,
    frozen,
)
from morl_trl.recipes.config.families import DQN_EXPLORATION, DQN_OPTIM, DQN_REPLAY, algorithm_config

__all__ = ["GPILSConfig", "GPIPDConfig", "SHARED_DEFAULTS", "DEFAULTS", "DEFAULTS_PD", "QUICK", "QUICK_PD"]


GPILSConfig = algorithm_config(
    "GPILSConfig", "GPI-LS's keys (LunarLander's values: ``[gpi_ls.lunarlander]``).",
    DQN_REPLAY, DQN_OPTIM,
    # the first width is the state/weight feature width (after the CNN on pixels)
    dict(hidden=(256, 256, 256, 256)),
    DQN_EXPLORATION,
    dict(gpi_iteration_frames=50_000,  # timesteps_per_iter
         gpi_front_episodes=5,  # num_eval_episodes_for_front
         gpi_num_nets=2, gpi_dropout=0.01, gpi_layer_norm=True, gpi_eval_conditioning="authors",
         gpi_gradient_updates=1, gpi_min_priority=0.01, gpi_dynamics_rollout_starts=5_000),
    # continuous actions (TD3-style actor)
    dict(gpi_policy_noise=0.2, gpi_noise_clip=0.5, gpi_policy_delay=2),
)


@dataclass
class GPIPDConfig(GPILSConfig):
    """GPI-PD: GPI-LS's keys and the learned dynamics model (Dyna)."""

    gpi_dynamics_hidden: tuple[int, ...] = (256, 256, 256)
    gpi_dynamics_ensemble: int = 5
    gpi_dynamics_elites: int = 2
    gpi_dynamics_lr: float = 1e-3
    gpi_dynamics_train_freq: int = 250
    gpi_dynamics_rollout_freq: int = 250
    gpi_dynamics_rollout_batch: int = 25_000
    gpi_dynamics_buffer: int = 100_000
    gpi_uncertainty_threshold: float = 1.5
    gpi_real_ratio: float = 0.5
    gpi_dynamics_rollout_len: int = 1
    gpi_dynamics_normalize: bool = False
    gpi_dynamics_max_logvar: float = 0.5  # dynamics_max_logvar_scale (gpi_pd_continuous_action.py:108)
    gpi_dynamics_max_grad_norm: float | None = None  # dynamics_max_grad_norm (gpi_pd_continuous_action.py:110)
    gpi_model_termination: str = "authors"


SHARED_DEFAULTS = frozen({})
# GPIPDContinuousAction: Polyak 0.005, batch 256, learning_starts 25k, min priority 0.1
_CONTINUOUS = dict(tau=0.005, batch_size=256, init_random_frames=25_000, gpi_min_priority=0.1,
                   gpi_dynamics_rollout_starts=1_000)
_CONTINUOUS_MODEL = dict(gpi_dynamics_hidden=(256, 256, 256, 256), gpi_dynamics_rollout_len=5,
                         gpi_dynamics_rollout_batch=50_000, gpi_dynamics_buffer=200_000, gpi_uncertainty_threshold=2.0,
                         gpi_dynamics_normalize=True)
DEFAULTS = domain_table({
    LUNAR_LANDER: dict(gpi_front_episodes=3),
    LAVA_GRID: dict(eps_frames=5_000_000, target_update_period=200),
    MARIO: dict(hidden=(512, 512), eps_start=0.2, eps_end=0.01, batch_size=64, init_random_frames=25_000,
                buffer_size=100_000, gpi_layer_norm=False, gpi_front_episodes=3),
    HOPPER: dict(_CONTINUOUS, gpi_iteration_frames=50_000),
    HALF_CHEETAH: dict(_CONTINUOUS, gpi_iteration_frames=25_000),
    HUMANOID: dict(_CONTINUOUS, gpi_iteration_frames=25_000),
})
DEFAULTS_PD = domain_table({
    LUNAR_LANDER: dict(gpi_front_episodes=1, gpi_uncertainty_threshold=20.0, gpi_dynamics_train_freq=5_000,
                       gpi_dynamics_rollout_freq=5_000),
    LAVA_GRID: dict(eps_frames=5_000_000, target_update_period=200, gpi_uncertainty_threshold=1e4,
                    gpi_dynamics_lr=3e-5, gpi_dynamics_hidden=(512, 512), gpi_dynamics_train_freq=5_000,
                    gpi_dynamics_rollout_freq=5_000),
    HOPPER: dict(_CONTINUOUS, **_CONTINUOUS_MODEL) | dict(gpi_iteration_frames=25_000, gpi_dynamics_train_freq=2_000,
                 gpi_dynamics_rollout_freq=2_000),
    HALF_CHEETAH: dict(_CONTINUOUS, **_CONTINUOUS_MODEL) | dict(gpi_iteration_frames=25_000, gpi_dynamics_train_freq=4_000,
                       gpi_dynamics_rollout_freq=4_000, gpi_uncertainty_threshold=10.0),
    HUMANOID: dict(_CONTINUOUS, **_CONTINUOUS_MODEL) | dict(gpi_iteration_frames=25_000, gpi_dynamics_train_freq=5_000,
                   gpi_dynamics_rollout_freq=5_000, gpi_uncertainty_threshold=1e4, gpi_dynamics_lr=3e-5,
                   gpi_dynamics_hidden=(512, 512), gpi_dynamics_max_logvar=0.1, gpi_dynamics_max_grad_norm=10.0),
})
# --quick: several weight-support iterations, cheaper model fits and rollouts
QUICK = frozen(dict(gpi_iteration_frames=10_000))
QUICK_PD = frozen(dict(gpi_iteration_frames=10_000, gpi_dynamics_train_freq=5_000, gpi_dynamics_rollout_freq=1_000,
                       gpi_dynamics_rollout_batch=5_000))
