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

from morl_trl.algorithms.domains import (
    HALF_CHEETAH,
    HOPPER,
    HUMANOID,
    LAVA_GRID,
    LUNAR_LANDER,
    MARIO,
    domain_table,
    frozen,
)

__all__ = ["GPILSConfig", "GPIPDConfig", "SHARED_DEFAULTS", "DEFAULTS", "DEFAULTS_PD"]


@dataclass
class GPILSConfig:
    """GPI-LS's keys (LunarLander's values: ``[gpi_ls.lunarlander]``); what each means: ``KEYS``.

    Source of each default: ``[gpi_ls.lunarlander.<table>] <setting>`` of ``hyperparameters.toml``
    (the continuous keys: ``[gpi_ls.hopper.init]``), or "ours".
    """

    # collector and replay: PER without importance weights
    frames_per_batch: int = 64  # ours (the authors step one env between updates)
    init_random_frames: int = 100  # init.learning_starts
    buffer_size: int = 1_000_000  # init.buffer_size
    batch_size: int = 128  # init.batch_size
    prioritized: bool = True  # init.per
    per_alpha: float = 0.6  # init.alpha_per
    per_beta: float = 0.4  # ours (TorchRL's; unused: per_importance_weights is false)
    per_importance_weights: bool = False  # init.per (MB's PER without importance weights)
    # optim: hard target copies every 1000 frames
    lr: float = 3e-4  # init.learning_rate
    updates_per_batch: int = 0  # ours (0: gpi_gradient_updates per frame)
    target_update_period: int = 1000  # init.target_net_update_freq
    tau: float | None = None  # init.tau 1.0: hard copies
    max_grad_norm: float | None = None  # init.max_grad_norm
    # network: the first width is the state/weight feature width (after the CNN on pixels)
    hidden: tuple[int, ...] = (256, 256, 256, 256)  # init.net_arch
    # exploration: epsilon 1 -> 0.05 over 1M frames after learning_starts
    eps_start: float = 1.0  # init.initial_epsilon
    eps_end: float = 0.05  # init.final_epsilon
    eps_frames: int = 1_000_000  # init.epsilon_decay_steps
    # the weight support and the ensemble
    gpi_iteration_frames: int = 50_000  # train.timesteps_per_iter
    gpi_front_episodes: int = 5  # train.num_eval_episodes_for_front
    gpi_num_nets: int = 2  # init.num_nets
    gpi_dropout: float = 0.01  # init.drop_rate
    gpi_layer_norm: bool = True  # init.layer_norm
    gpi_eval_conditioning: str = "authors"  # derived.eval_gpi_indexing_note
    gpi_first_episode: str = "w"  # train_iteration.change_w_every_episode (SPEC §6: the first episode of an iteration is w's)
    gpi_update_weight: str = "iteration"  # derived.rows_per_gradient_step ("half with the iteration weight", SPEC §6)
    gpi_gradient_updates: int = 1  # init.gradient_updates (every script passes 1)
    gpi_min_priority: float = 0.01  # init.min_priority
    gpi_dynamics_rollout_starts: int = 5_000  # MB's dynamics_rollout_starts (GPI-LS: when gpi_gradient_updates starts)
    # continuous actions (TD3-style actor)
    gpi_policy_noise: float = 0.2  # init.policy_noise
    gpi_noise_clip: float = 0.5  # init.noise_clip
    gpi_policy_delay: int = 2  # init.delay_policy_update


@dataclass
class GPIPDConfig(GPILSConfig):
    """GPI-PD: GPI-LS's keys and the learned dynamics model (Dyna).

    Source of each default: ``[gpi_pd.lunarlander.init] <setting>`` of ``hyperparameters.toml``, or "ours".
    """

    gpi_dynamics_hidden: tuple[int, ...] = (256, 256, 256)  # init.dynamics_net_arch
    gpi_dynamics_ensemble: int = 5  # init.dynamics_ensemble_size
    gpi_dynamics_elites: int = 2  # init.dynamics_num_elites
    gpi_dynamics_lr: float = 1e-3  # init.dynamics_lr
    gpi_dynamics_train_freq: int = 250  # init.dynamics_train_freq
    gpi_dynamics_rollout_freq: int = 250  # init.dynamics_rollout_freq
    gpi_dynamics_rollout_batch: int = 25_000  # init.dynamics_rollout_batch_size
    gpi_dynamics_buffer: int = 100_000  # init.dynamics_buffer_size
    gpi_uncertainty_threshold: float = 1.5  # init.dynamics_uncertainty_threshold
    gpi_real_ratio: float = 0.5  # init.real_ratio
    gpi_dynamics_rollout_len: int = 1  # init.dynamics_rollout_len
    gpi_dynamics_normalize: bool = False  # init.dynamics_normalize_inputs
    gpi_dynamics_max_logvar: float = 0.5  # init.dynamics_max_logvar_scale (gpi_pd_continuous_action.py:108)
    gpi_dynamics_max_grad_norm: float | None = None  # init.dynamics_max_grad_norm (gpi_pd_continuous_action.py:110)
    gpi_model_termination: str = "authors"  # network.termination_fn (their Hopper slip: no abs)


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
