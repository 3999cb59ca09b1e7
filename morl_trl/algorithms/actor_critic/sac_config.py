"""SAC, the single-objective baseline trained on the domain's original scalar reward (SPEC §4).

Source: ``hyperparameters.toml`` ``[sac.<domain>]`` (SACContinuous on MuJoCo, SACDiscrete on
LunarLander, LavaGrid and Mario); ``morl-trl config sac ENV --compare-authors`` lists each setting.
The authors' temperature is tuned from 1.0 (their scripts' alpha 0.2 is ignored, ``autotune``).

Example:
    >>> SACConfig().init_random_frames, DEFAULTS[LUNAR_LANDER]["update_frequency"]
    (1000, 4)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.algorithms.domains import LAVA_GRID, LUNAR_LANDER, MARIO, domain_table, frozen

__all__ = ["SACConfig", "SHARED_DEFAULTS", "DEFAULTS"]


@dataclass
class SACConfig:
    """SAC's keys (MuJoCo's values: ``[sac.hopper]``, SACContinuous); what each means: ``KEYS``.

    Source of each default: ``[sac.hopper.<table>] <setting>`` of ``hyperparameters.toml``, or "ours".
    """

    # collector and replay
    frames_per_batch: int = 64  # ours (the authors step one env between updates)
    init_random_frames: int = 1000  # init.learning_starts
    buffer_size: int = 1_000_000  # init.buffer_size
    batch_size: int = 256  # init.batch_size
    prioritized: bool = False  # ours (no PER in SAC)
    per_alpha: float = 0.6  # ours (used only with prioritized)
    per_beta: float = 0.4  # ours (used only with prioritized)
    # optim: actor 3e-4, critics and temperature 1e-3; Polyak 0.005 every update
    lr: float = 3e-4  # init.policy_lr
    q_lr: float | None = 1e-3  # init.q_lr
    alpha_lr: float | None = 1e-3  # network.optimizers (the temperature's Adam: q_lr)
    adam_eps: float | None = None  # network.optimizers (torch's 1e-8)
    updates_per_batch: int = 0  # ours (0: update_frequency frames per update)
    update_frequency: int = 1  # init.update_frequency
    tau: float | None = 0.005  # init.tau
    target_update_period: int = 1000  # init.target_net_freq
    max_grad_norm: float | None = None  # ours (the authors do not clip)
    # networks and temperature: tuned from 1.0 (target entropy -|A|; discrete: target_entropy_scale * ln|A|)
    hidden: tuple[int, ...] = (256, 256, 256, 256)  # init.net_arch
    alpha: float = 1.0  # init.alpha (autotune starts from 1.0)
    learn_alpha: bool = True  # init.autotune
    target_entropy_scale: float = 0.3  # init.target_entropy_scale
    actor_scale: str = "tanh_log_std"  # network.actor: log_std = -5 + 3.5 (tanh(x) + 1)
    policy_freq: int = 2  # init.policy_freq: 2 actor steps after every 2nd critic step (sac_continuous.py:134,435-456)
    alpha_loss_form: str = "alpha"  # the authors' CleanRL-style SAC: -alpha (log pi + target)
    joint_update: bool = False  # ours (false: the authors' order, each loss computed alone)
    # preferences (SAC trains on the scalar reward; the env still carries a preference)
    preference_distribution: str = "dirichlet"  # ours
    preference_resample: str = "episode"  # ours


SHARED_DEFAULTS = frozen({"eval_exploration": "random"})
# SACDiscrete: one update every 4 frames after 20k random frames, hard target copies every
# target_net_freq FRAMES (= target_net_freq / 4 updates), Adam eps 1e-4, one lr 3e-4
_DISCRETE = dict(init_random_frames=20_000, batch_size=128, tau=None, q_lr=3e-4, alpha_lr=3e-4, adam_eps=1e-4,
                 update_frequency=4, policy_freq=1)  # SACDiscrete steps its actor at every update
DEFAULTS = domain_table({
    LUNAR_LANDER: dict(_DISCRETE, target_update_period=2000 // 4, target_entropy_scale=0.3),
    LAVA_GRID: dict(_DISCRETE, target_update_period=200 // 4, target_entropy_scale=0.89),
    MARIO: dict(_DISCRETE, batch_size=64, buffer_size=100_000, target_update_period=1000 // 4,
                target_entropy_scale=0.5, hidden=(512,)),  # net_arch [512, 512]: the CNN's 512, then 512
})
