"""MORL/D SB and SB+PSA (Felten et al. 2024): their keys, and the authors' values per domain.

Source: ``hyperparameters.toml`` ``[morld_sb.<domain>]`` and ``[morld_sb_psa.<domain>]`` (MOSAC on
MuJoCo, MOSACDiscrete on LunarLander and LavaGrid; ``.policy_args`` holds the members' settings);
``morl-trl config morld ENV --compare-authors`` lists each setting. Members' temperatures are
tuned from 1.0 (``autotune``; the scripts' alpha 0.2 is ignored).

Example:
    >>> MORLDConfig().exchange_every, MORLDConfig().morld_schedule, DEFAULTS[LAVA_GRID]["pop_size"]
    (20000, 'round_robin', 5)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.algorithms.domains import HALF_CHEETAH, HOPPER, HUMANOID, LAVA_GRID, LUNAR_LANDER, domain_table, frozen

__all__ = ["MORLDConfig", "MORLDPSAConfig", "SHARED_DEFAULTS", "DEFAULTS"]


@dataclass
class MORLDConfig:
    """MORL/D SB's keys (Half-Cheetah's values: ``[morld_sb.cheetah]``; the members' MOSAC settings are
    ``.policy_args``); what each means: ``KEYS``.

    Source of each default: ``[morld_sb.cheetah.<table>] <setting>`` of ``hyperparameters.toml``, or "ours".
    """

    # collector and replay: each member owns num_envs sub-envs; learning_starts on the shared frame counter;
    # one buffer shared by the members
    frames_per_batch: int = 50  # ours (50 divides every exchange_every of the record: a turn is whole batches)
    init_random_frames: int = 25_000  # policy_args.learning_starts
    buffer_size: int = 1_000_000  # policy_args.buffer_size
    batch_size: int = 256  # policy_args.batch_size
    prioritized: bool = False  # ours (MOSAC has no PER)
    # optim: actor 3e-4, critics and temperature 1e-3 (continuous)
    lr: float = 3e-4  # policy_args.policy_lr
    q_lr: float | None = 1e-3  # policy_args.q_lr
    alpha_lr: float | None = 1e-3  # network.optimizers (the temperature's Adam: q_lr)
    adam_eps: float | None = None  # network.optimizers (torch's 1e-8)
    updates_per_batch: int = 0  # ours (0: update_frequency member frames per update)
    update_frequency: int = 1  # policy_args.update_frequency
    tau: float | None = 0.005  # policy_args.tau
    target_update_period: int = 1000  # policy_args.target_net_freq
    max_grad_norm: float | None = None  # ours (the authors do not clip)
    # members' networks and temperature: tuned from 1.0 (autotune; the scripts' alpha 0.2 is ignored)
    hidden: tuple[int, ...] = (256, 256, 256, 256)  # policy_args.net_arch
    alpha: float = 1.0  # policy_args.alpha
    learn_alpha: bool = True  # policy_args.autotune
    target_entropy_scale: float = 0.3  # policy_args.target_entropy_scale
    actor_scale: str = "tanh_log_std"  # network.actor: log_std = -5 + 3.5 (tanh(x) + 1)
    policy_freq: int = 2  # policy_args.policy_freq (mosac_continuous_action.py:95-103,141,460-482)
    # MORL-Baselines' MOSAC: alpha_loss = (-self.log_alpha * (log_pi + self.target_entropy)).mean()
    # (mosac_continuous_action.py:470 in MB 1.3.0, inside the delayed-actor block the record cites as 460-482)
    alpha_loss_form: str = "log_alpha"
    joint_update: bool = False  # ours (false: the authors' order, each loss computed alone)
    # population
    pop_size: int = 6  # init.pop_size
    exchange_every: int = 20_000  # init.exchange_every
    weight_adaptation: str = "none"  # init.weight_adaptation_method (SB: fixed weights)
    psa_delta: float = 0.1  # ours (used by PSA only; MORLDPSAConfig)
    # the archive evaluation after every exchange: 5 stochastic episodes per member on a DR env of their own
    # (num_eval_episodes_for_front, morld.py:516)
    morld_eval_episodes: int = 5  # train.num_eval_episodes_for_front
    # the untrained members evaluated and archived before training (SPEC §6 MORL/D: "The archive also holds the
    # untrained initial members"; MB 1.3.0 morld.py:537-543, the __eval_all_policies call before the loop)
    morld_archive_initial: bool = True
    # the authors' round robin: one member trains exchange_every frames on the env (reset at each turn), then
    # every other member gets update_passes = 10 updates (morld.py:75,421-431,559-567; mosac_*.py train())
    morld_schedule: str = "round_robin"  # derived.env_reset_at_each_exchange
    morld_update_passes: int = 10  # init.update_passes


@dataclass
class MORLDPSAConfig(MORLDConfig):
    """MORL/D SB+PSA: SB's keys, weights adapted by Pareto simulated annealing."""

    weight_adaptation: str = "psa"


# one env, as the authors' members (MOSAC steps a single env); the concurrent schedule takes P * num_envs sub-envs
SHARED_DEFAULTS = frozen({"eval_exploration": "random", "num_envs": 1})
# MOSACDiscrete: one update per frame (the scripts' update_frequency 1), hard target copies every
# target_net_freq frames (= updates), Adam eps 1e-4 with one lr 3e-4
_DISCRETE = dict(tau=None, batch_size=128, init_random_frames=20_000, q_lr=3e-4, alpha_lr=3e-4, adam_eps=1e-4,
                 update_frequency=1, policy_freq=1,  # MOSACDiscrete steps its actor at every update
                 # -alpha (...) on the actor step's probabilities (MB 1.3.0 mosac_discrete_action.py:490-492)
                 alpha_loss_form="alpha")
DEFAULTS = domain_table({
    HOPPER: dict(init_random_frames=10_000),
    HALF_CHEETAH: dict(exchange_every=10_000),
    HUMANOID: dict(init_random_frames=5_000),
    LUNAR_LANDER: dict(_DISCRETE, target_update_period=2000, target_entropy_scale=0.3),
    LAVA_GRID: dict(_DISCRETE, pop_size=5, exchange_every=10_000, target_update_period=200, target_entropy_scale=0.89),
})
