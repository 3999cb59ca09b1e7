"""Hyperparameters for an env outside the paper's domains: MORL-Baselines 1.3.0's constructor defaults.

A foreign env (a MO-Gymnasium id, a user's TorchRL env; :mod:`morl_trl.envs.foreign`) has no
paper record, so each algorithm starts from the defaults of the MORL-Baselines (MB) class its
users know (``morl_baselines==1.3.0``; the class and file are named per algorithm), translated
to our keys. What MB runs as one env stepped once between updates is ``num_envs=1,
frames_per_batch=1, updates_per_batch=0`` (one update per frame) here. ``morl-trl config ALGO
ENV`` prints the result; flags and config files override it as for any domain.

Where MB has no default (PCN's ``scaling_factor``), the note in :data:`FOREIGN_NOTES` says
what we use.
"""

from __future__ import annotations

from typing import Any

__all__ = ["FOREIGN_DEFAULTS", "FOREIGN_DEFAULTS_CONTINUOUS", "FOREIGN_NOTES", "MB_VERSION"]

MB_VERSION = "1.3.0"

# MB evaluates a multi-policy run on 100 weights ("num_eval_weights_for_front") x 5 episodes
# ("num_eval_episodes_for_front") (Envelope.train, GPIPD.train, CAPQL.train, MORLD.train).
_EVAL = dict(eval_weights=100, eval_episodes=5, eval_interval=10_000)  # (eval_freq / eval_mo_freq 10_000)
_ONE_ENV = dict(num_envs=1, frames_per_batch=1, updates_per_batch=0)

FOREIGN_DEFAULTS: dict[str, dict[str, Any]] = {
    # morl_baselines/multi_policy/envelope/envelope.py: Envelope.__init__
    "envelope": dict(**_ONE_ENV, **_EVAL, lr=3e-4, eps_start=0.01, eps_end=0.01, tau=None, target_update_period=200,
                     buffer_size=1_000_000, hidden=(256, 256, 256, 256), batch_size=256, init_random_frames=100,
                     gamma=0.99, max_grad_norm=1.0, num_sampled_prefs=4, prioritized=True, per_alpha=0.6,
                     per_importance_weights=False, homotopy_lambda0=0.0, homotopy_final=None,
                     preference_distribution="gaussian", preference_resample="episode",
                     # its QNet: w at the input, layer_init's orthogonal weights (the paper's domains keep the
                     # authors' form, w after the first hidden layer, which diverged on deep-sea-treasure at
                     # these settings: issue 48)
                     envelope_network="mb"),
    # morl_baselines/multi_policy/gpi_pd/gpi_pd.py: GPIPD.__init__ (GPILS: dyna and gpi_pd off) and
    # GPIPD.train (timesteps_per_iter 10_000, num_eval_episodes_for_front 5)
    **{algo: dict(**_ONE_ENV, **_EVAL, lr=3e-4, eps_start=0.01, eps_end=0.01, tau=None, target_update_period=1000,
                  buffer_size=1_000_000, hidden=(256, 256, 256, 256), gpi_num_nets=2, batch_size=128,
                  init_random_frames=100, gpi_gradient_updates=20, gamma=0.99, max_grad_norm=None, prioritized=True,
                  per_alpha=0.6, per_importance_weights=False, gpi_min_priority=0.01, gpi_dropout=0.01,
                  gpi_layer_norm=True, gpi_iteration_frames=10_000, gpi_front_episodes=5)
       for algo in ("gpi_ls", "gpi_pd")},
    # morl_baselines/multi_policy/capql/capql.py: CAPQL.__init__
    "capql": dict(**_ONE_ENV, **_EVAL, lr=3e-4, gamma=0.99, tau=0.005, buffer_size=1_000_000, hidden=(256, 256),
                  batch_size=128, alpha=0.2, learn_alpha=False, init_random_frames=1000, prioritized=False),
    # morl_baselines/multi_policy/pcn/pcn.py: PCN.__init__ and PCN.train (one env, its command updated
    # after every episode: the parity benchmark found 16 sub-envs sharing stale commands learning slower)
    # (hidden [64, 64]: MB's hidden_dim 64, the embedding width and one hidden layer of it)
    "pcn": dict(num_envs=1, frames_per_batch=1, lr=1e-3, gamma=1.0, batch_size=256, hidden=(64, 64), pcn_noise=0.1,
                pcn_er_episodes=20, pcn_step_episodes=10, pcn_model_updates=50, pcn_buffer_episodes=100,
                eval_weights=100, eval_episodes=1),
    # morl_baselines/multi_policy/morld/morld.py: MORLD.__init__ (pop 6, exchange every 40_000 steps,
    # gamma 0.995, no shared buffer, no weight adaptation) with its default policy
    # single_policy/ser/mosac_continuous_action.py: MOSAC.__init__ (batch 128, learning_starts 1000,
    # [256, 256], tau 0.005, critics' lr q_lr 1e-3; the temperature autotuned from log_alpha = 0, i.e. 1.0,
    # with Adam at q_lr: its `alpha=0.2` is unused with autotune, mosac_continuous_action.py:144-150, 257-260)
    # (its round robin: one member on one env for exchange_every steps; frames_per_batch 50 divides them)
    **{algo: dict(**_EVAL, num_envs=1, frames_per_batch=50, updates_per_batch=0, update_frequency=1, gamma=0.995,
                  pop_size=6, exchange_every=40_000, batch_size=128, init_random_frames=1000, hidden=(256, 256),
                  tau=0.005, alpha=1.0, learn_alpha=True, q_lr=1e-3, alpha_lr=1e-3, buffer_size=1_000_000,
                  prioritized=False, weight_adaptation="none" if algo == "morld" else "psa", eval_exploration="random")
       for algo in ("morld", "morld_psa")},
    # morl_baselines/multi_policy/pgmorl/pgmorl.py: PGMORL.__init__ (4 envs per member, 6 members,
    # 2048 steps per iteration, [64, 64], gamma 0.995)
    "pgmorl": dict(num_envs=24, frames_per_batch=24 * 2048, pgmorl_envs_per_member=4, pgmorl_pop=6, pgmorl_warmup=80,
                   pgmorl_evo_iterations=20, pgmorl_num_buffers=100, pgmorl_buffer_size=2, pgmorl_delta_weight=0.2,
                   pgmorl_sparsity=-1.0, gamma=0.995, hidden=(64, 64), pgmorl_minibatches=32, pgmorl_epochs=10,
                   lr=3e-4, pgmorl_clip=0.2, max_grad_norm=0.5, pgmorl_gae_lambda=0.95, eval_weights=100,
                   eval_episodes=1, eval_exploration="random",
                   # (MO-PPO's envs.reset(seed) at every train(): a wrapped Gymnasium env's sub-envs cannot be
                   # re-seeded one by one here, algorithms.pgmorl.PGMORLAgent.reseed_env)
                   pgmorl_reseed_each_iteration=False),
    # single_policy/ser/mosac_continuous_action.py: MOSAC.__init__ (one fixed weight in MB; here
    # preference-conditioned; the temperature autotuned from 1.0 at q_lr 1e-3, as above)
    "mosac": dict(**_ONE_ENV, **_EVAL, gamma=0.99, tau=0.005, batch_size=128, init_random_frames=1000, hidden=(256, 256),
                  alpha=1.0, learn_alpha=True, q_lr=1e-3, alpha_lr=1e-3, buffer_size=1_000_000, prioritized=False,
                  eval_exploration="random"),
    # single_policy/ser/mosac_discrete_action.py: MOSACDiscrete.__init__ (the temperature autotuned from
    # log_alpha = 0, i.e. 1.0: its `alpha=0.2` is unused with autotune, :143, 258-262)
    "mosac_discrete": dict(**_EVAL, num_envs=1, frames_per_batch=4, updates_per_batch=1, gamma=0.99, tau=None,
                           target_update_period=2000, batch_size=128, init_random_frames=20_000, hidden=(256, 256),
                           alpha=1.0, learn_alpha=True, target_entropy_scale=0.89, buffer_size=1_000_000,
                           prioritized=False, eval_exploration="random"),
}

# morl_baselines/multi_policy/gpi_pd/gpi_pd_continuous_action.py: GPIPDContinuousAction.__init__ (GPILSContinuousAction:
# dyna off), for an env with continuous actions (applied over the discrete values above)
_CONTINUOUS_GPI = dict(tau=0.005, buffer_size=400_000, hidden=(256, 256), batch_size=128, gpi_num_nets=2,
                       gpi_policy_delay=2, init_random_frames=100, gpi_gradient_updates=20, gpi_policy_noise=0.2,
                       gpi_noise_clip=0.5, prioritized=True, gpi_min_priority=0.1, per_alpha=0.6,
                       gpi_dynamics_rollout_starts=1000)
# the dynamics model's settings: GPI-PD's only (GPI-LS has none of these keys, and refuses them)
_CONTINUOUS_DYNAMICS = dict(gpi_dynamics_hidden=(200, 200, 200, 200), gpi_dynamics_train_freq=250,
                            gpi_dynamics_rollout_len=5, gpi_dynamics_rollout_freq=250,
                            gpi_dynamics_rollout_batch=50_000, gpi_dynamics_buffer=200_000,
                            gpi_uncertainty_threshold=2.0, gpi_real_ratio=0.1)
FOREIGN_DEFAULTS_CONTINUOUS: dict[str, dict[str, Any]] = {
    "gpi_ls": dict(_CONTINUOUS_GPI),
    "gpi_pd": dict(_CONTINUOUS_GPI, **_CONTINUOUS_DYNAMICS),
}

FOREIGN_NOTES: dict[str, str] = {
    "pcn": "MB's PCN has no default scaling_factor; pcn_scaling_factor null uses 0.1 for every entry of the command (as for our domains without a record)",
    "sac": "sac trains on the env's original scalar reward, which a foreign env does not have",
    "morld": "MB's MOSAC updates every step per member; frames_per_batch = one frame per member",
}
