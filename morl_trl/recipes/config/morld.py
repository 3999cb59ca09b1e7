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

from morl_trl.recipes.config.domains import HALF_CHEETAH, HOPPER, HUMANOID, LAVA_GRID, LUNAR_LANDER, domain_table, frozen
from morl_trl.recipes.config.families import ACTOR_CRITIC, algorithm_config, pick

__all__ = ["MORLDConfig", "MORLDPSAConfig", "SHARED_DEFAULTS", "DEFAULTS", "QUICK"]


MORLDConfig = algorithm_config(
    "MORLDConfig", "MORL/D SB's keys (Half-Cheetah's member values: ``[morld_sb.cheetah.policy_args]``, MOSAC).",
    # each member owns num_envs sub-envs; frames_per_batch covers all of them; learning_starts on the shared
    # frame counter; one buffer shared by the members; actor 3e-4, critics and temperature 1e-3 (continuous);
    # MOSAC's actor: log_std = -5 + 3.5 (tanh(x) + 1); 2 actor (+ temperature) steps after every 2nd
    # critic step (mosac_continuous_action.py:95-103,141,460-482)
    # (frames_per_batch 50 divides every exchange_every of the record: a turn is whole batches)
    pick(ACTOR_CRITIC, [k for k in ACTOR_CRITIC if k not in ("per_alpha", "per_beta", "per_importance_weights")],
         frames_per_batch=50, init_random_frames=25_000, q_lr=1e-3, alpha_lr=1e-3, alpha=1.0,
         # MORL-Baselines' MOSAC: alpha_loss = (-self.log_alpha * (log_pi + self.target_entropy)).mean()
         # (mosac_continuous_action.py:470 in MB 1.3.0, inside the delayed-actor block the record cites as 460-482)
         alpha_loss_form="log_alpha"),
    # population
    # the archive evaluation after every exchange: 5 stochastic episodes per member on a DR env of their own
    # (num_eval_episodes_for_front, morld.py:516)
    # the authors' round robin: one member trains exchange_every frames on the env (reset at each turn), then
    # every other member gets update_passes = 10 updates (morld.py:75,421-431,559-567; mosac_*.py train())
    dict(pop_size=6, exchange_every=20_000, weight_adaptation="none", psa_delta=0.1, morld_eval_episodes=5,
         morld_schedule="round_robin", morld_update_passes=10),
)


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
# --quick: turns of 2000 frames (5 per member on LavaGrid in 60k frames; the authors' 10-20k would give 3)
QUICK = frozen(dict(num_envs=1, frames_per_batch=50, updates_per_batch=0, update_frequency=1, exchange_every=2_000))
