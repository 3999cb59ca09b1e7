"""What both libraries share in the parity benchmark: the cases, the evaluation, the result files.

Imported by ``run_parity.py`` (our python) and by ``mb_runner.py`` (MORL-Baselines' virtual
environment, which sees morl_trl through ``PYTHONPATH``): one evaluation code path for both.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np

MB_VERSION = "1.3.0"

# One case = one env, one algorithm, one set of hyperparameters given to both libraries (their
# names in each), one frame budget and one evaluation protocol. `ours` are TrainConfig keys over
# our foreign-env defaults (morl_trl.recipes.foreign_defaults: MB 1.3.0's constructor defaults),
# `mb` keyword arguments of the MORL-Baselines class over its defaults, `mb_train` of its train().
# Where a case departs from MB's defaults (smaller networks, fewer gradient updates), both sides
# get the same values: budgets were chosen so that 12 cases x 5 seeds x 2 libraries fit in about
# 90 minutes of a 2-core CPU shared with five other jobs (each run got 15-30 % of a core) (benchmarks/parity/RESULTS.md says which cases learned).
_SMALL_GPI = (dict(hidden=[64, 64], batch_size=32, gpi_gradient_updates=1),
              dict(net_arch=[64, 64], batch_size=32, gradient_updates=1))
#: CAPQL on mo-hopper-v5, learning from frame 250 on both sides (capql-hopper at 1k, 5k and 10k frames)
_CAPQL_HOPPER = dict(env="mo-hopper-v5", algo="capql", gamma=0.99, ours=dict(init_random_frames=250),
                     mb=dict(learning_starts=250), mb_train=dict())
#: the SAC baseline's task against TorchRL's SAC (sac-hopper-5k and -10k; the comment at sac-hopper-5k says why)
_SAC_HOPPER = dict(
    env="MOHopperDefault-v5", algo="sac", reference="torchrl_sac", gamma=0.99,
    ours=dict(history_len=0, eval_contexts=["MOHopperDefault-v5"], num_envs=1, frames_per_batch=1, updates_per_batch=0,
              hidden=[256, 256], batch_size=256, init_random_frames=1000, lr=3e-4, q_lr=1e-3, alpha_lr=1e-3,
              alpha=1.0, tau=0.005, joint_update=True, policy_freq=1, alpha_loss_form="log_alpha"),
    ref=dict(hidden=[256, 256], batch_size=256, init_random_frames=1000, lr=3e-4, q_lr=1e-3, alpha_lr=1e-3,
             alpha=1.0, tau=0.005),
    mb=dict(), mb_train=dict())
CASES: dict[str, dict] = {
    # GPI-LS on Deep Sea Treasure: MB's GPILS with [64, 64], batch 32, one update per step
    "gpi_ls-dst": dict(
        env="deep-sea-treasure-v0", algo="gpi_ls", frames=2_000, eval_every=1_000, gamma=0.99,
        ours=dict(_SMALL_GPI[0], gpi_iteration_frames=500), mb=dict(_SMALL_GPI[1]),
        mb_train=dict(timesteps_per_iter=500),
    ),
    # The same at a budget where MB learns: 30,000 frames in MB's default iterations of 10,000 frames
    # (GPILS.train's timesteps_per_iter; ours: gpi_iteration_frames from recipes.foreign_defaults). An
    # earlier MB seed 0 reached an HV ratio of 0.774 at 10k frames and 0.808 at 20k.
    "gpi_ls-dst-30k": dict(
        env="deep-sea-treasure-v0", algo="gpi_ls", frames=30_000, eval_every=5_000, gamma=0.99,
        ours=dict(_SMALL_GPI[0]), mb=dict(_SMALL_GPI[1]), mb_train=dict(),
    ),
    # The same with ours' GPI update under MB's reading of the update weight: the weight of the episode in
    # progress (MB 1.3.0 gpi_pd.py:763,785-786) where the record and SPEC §6 say the iteration's w (ours'
    # default): issue 48's audit found the two differ in iteration 1 (ours ~75 % of the rows on e_1, MB ~50 %)
    "gpi_ls-dst-30k-episode-w": dict(
        env="deep-sea-treasure-v0", algo="gpi_ls", frames=30_000, eval_every=5_000, gamma=0.99,
        ours=dict(_SMALL_GPI[0], gpi_update_weight="episode"), mb=dict(_SMALL_GPI[1]), mb_train=dict(),
    ),
    # Envelope on Deep Sea Treasure at MB's defaults ([256]*4, batch 256, 4 sampled weights, target copied
    # every 200 steps, homotopy 0, PER, eps 0.01) for 20,000 frames: issue 48's divergence check. Ours diverged
    # here on seed 11 (w.Q far above the largest discounted return, HV ratio 0.047); every run records its
    # largest Q estimate beside the env's bound (q_check, below)
    "envelope-dst-mb": dict(
        env="deep-sea-treasure-v0", algo="envelope", frames=20_000, eval_every=2_500, gamma=0.99,
        ours=dict(), mb=dict(), mb_train=dict(),
    ),
    # Envelope on Deep Sea Treasure, networks and batch cut as for GPI-LS (MB: [256]*4, batch 256)
    "envelope-dst": dict(
        env="deep-sea-treasure-v0", algo="envelope", frames=2_000, eval_every=1_000, gamma=0.99,
        ours=dict(hidden=[64, 64], batch_size=32), mb=dict(net_arch=[64, 64], batch_size=32), mb_train=dict(),
    ),
    # Minecart: MB's examples use gamma 0.98 (examples/envelope_minecart.py); short budget
    "envelope-minecart": dict(
        env="minecart-v0", algo="envelope", frames=1_000, eval_every=500, gamma=0.98,
        ours=dict(hidden=[64, 64], batch_size=32), mb=dict(net_arch=[64, 64], batch_size=32), mb_train=dict(),
    ),
    "gpi_ls-minecart": dict(
        env="minecart-v0", algo="gpi_ls", frames=1_000, eval_every=500, gamma=0.98,
        ours=dict(_SMALL_GPI[0], gpi_iteration_frames=500, gpi_front_episodes=1), mb=dict(_SMALL_GPI[1]),
        mb_train=dict(timesteps_per_iter=500, num_eval_episodes_for_front=1),
    ),
    # PCN at MB's defaults (gamma 1, [64], batch 256, 20 warm-up episodes, 10 episodes / 50 updates
    # a round, 100 episodes kept); MB has no default scaling factor: 0.1 for every entry on both
    "pcn-dst": dict(
        env="deep-sea-treasure-v0", algo="pcn", frames=2_000, eval_every=1_000, gamma=1.0,
        ours=dict(pcn_scaling_factor=[0.1, 0.1, 0.1]), mb=dict(scaling_factor=[0.1, 0.1, 0.1]), mb_train=dict(),
    ),
    "pcn-fruit-tree": dict(
        env="fruit-tree-v0", algo="pcn", frames=2_000, eval_every=1_000, gamma=1.0,
        ours=dict(pcn_scaling_factor=[0.1] * 7), mb=dict(scaling_factor=[0.1] * 7), mb_train=dict(),
    ),
    # continuous actions: CAPQL at MB's defaults but learning from frame 250 (MB: 1,000); short budget
    "capql-mountaincar": dict(
        env="mo-mountaincarcontinuous-v0", algo="capql", frames=1_000, eval_every=500, gamma=0.99,
        ours=dict(init_random_frames=250), mb=dict(learning_starts=250), mb_train=dict(),
    ),
    # GPILSContinuousAction with one gradient update a step (MB: 20) and [64, 64] (MB: [256, 256])
    "gpi_ls-mountaincar": dict(
        env="mo-mountaincarcontinuous-v0", algo="gpi_ls", frames=1_000, eval_every=500, gamma=0.99,
        ours=dict(hidden=[64, 64], gpi_gradient_updates=1, gpi_iteration_frames=500, gpi_front_episodes=1),
        mb=dict(net_arch=[64, 64], gradient_updates=1),
        mb_train=dict(timesteps_per_iter=500, num_eval_episodes_for_front=1),
    ),
    # MORL/D (MOSAC members, pop 6) with members exchanged every 200 steps (MB: 40,000), learning from
    # frame 250 (MB's MOSAC: 1,000)
    "morld-mountaincar": dict(
        env="mo-mountaincarcontinuous-v0", algo="morld", frames=1_200, eval_every=600, gamma=0.995,
        ours=dict(exchange_every=200, init_random_frames=250),
        mb=dict(exchange_every=200, policy_args=dict(learning_starts=250)), mb_train=dict(num_eval_episodes_for_front=1),
    ),
    # MORL/D SB (`morld`) and SB+PSA (`morld_psa`) on mo-hopper-2obj-v5 (issue 48: an informative case each): MB's
    # MORLD with MOSAC members at its defaults (pop 6 on equally_spaced_weights, [256, 256], batch 128, tau 0.005,
    # q_lr 1e-3, policy_lr 3e-4, policy_freq 2, autotuned temperature, update_passes 10, 5 stochastic episodes per
    # member for the archive after each exchange, gamma 0.995), with the authors' SB (shared_buffer=True: their
    # scripts' value, hyperparameters.toml [morld_sb.hopper.init]; MB's default False) and, for SB+PSA,
    # weight_adaptation_method="PSA" (MB's delta 0.1, as the authors' fork; [morld_sb_psa.hopper.init]; ours:
    # the registry name morld_psa, weight_adaptation "psa", psa_delta 0.1). Departures, the same on both sides:
    # exchange_every 500 (MB 40,000; the authors 20,000), so that each of the 6 members has one turn of 500 frames
    # in the 3,000-frame budget (MB trains one member per turn, round robin, as ours' default
    # morld_schedule="round_robin"); learning from the shared frame 250 (MOSAC's learning_starts, MB 1,000: at
    # exchange_every 500 members 0 and 1 would act randomly for their whole turns), half of member 0's first turn as
    # in the authors' Hopper runs (learning_starts 10,000 of exchange_every 20,000, [morld_sb.hopper.policy_args]).
    # The budget: a trial of MB on seed 900 (not a round's seed; exchange_every 1,000, learning from 500) went from
    # hypervolume 23.2k at frame 0 to 32.0k, 57.2k and 73.8k after 1,000, 2,000 and 3,000 frames (56.4k at 4,000,
    # 82.2k at 5,000, 84.6k at 6,000) and took 4 min (3.7 min of training) on the loaded machine; 6,000 frames for
    # 2 cases x 2 libraries x 5 seeds did not fit the session, 3,000 (every member one turn of 500) does.
    # Ours: alpha=1.0, MB's MOSAC autotune's start (log_alpha = 0, mosac_continuous_action.py; our foreign default
    # says 0.2). Evaluated every exchange: mb_runner hooks MB's evaluation after __eval_all_policies (the archive's
    # only update), ours evaluates after the batch whose exchange it follows.
    # Why the 2-objective Hopper (velocity, height; the control cost and the survival bonus added to both) and not
    # mo-hopper-v5: on v5 a trial (seed 900, 6,000 frames, exchange_every 1,000, learning from 500; NOTES.md)
    # stayed flat on both sides after the first exchange (MB 5.96M -> 8.21M at 1,000 frames -> 6.05M at 6,000;
    # ours 6.73M -> 3.09M -> 6.76M from 2,000 on): its energy objective
    # makes the untrained members' short episodes non-dominated, so the archive keeps them, and the evaluation
    # acts with the first (oldest) archived snapshot of the nearest weight. On 2obj a longer episode dominates. MB's
    # archive holds the untrained members from its first __eval_all_policies (before training, as the authors');
    # ours' started empty until d0bb3b8 (morld_archive_initial, now the default, archives them too): the ours runs
    # of the three MORL/D cases were made again at that change (the earlier ones kept under superseded/).
    # What MB 1.3.0 lacks of the authors' fork (SPEC §6): the history wrapper and DR env (the paper's Hopper), the
    # random tie-break among archived snapshots of the nearest weight (both sides here take the first, as the
    # shared evaluation does), asymmetric / history_type (off in the authors' runs anyway).
    **{f"{algo}-hopper-2obj": dict(
        env="mo-hopper-2obj-v5", algo=algo, frames=3_000, eval_every=500, gamma=0.995,
        ours=dict(exchange_every=500, init_random_frames=250, alpha=1.0, morld_eval_episodes=5),
        mb=dict(exchange_every=500, shared_buffer=True, policy_args=dict(learning_starts=250),
                **({"weight_adaptation_method": "PSA"} if algo == "morld_psa" else {})),
        mb_train=dict(num_eval_episodes_for_front=5),
    ) for algo in ("morld", "morld_psa")},
    # MORL/D SB as morld-hopper-2obj at twice its budget: 6,000 frames with exchange_every 1,000 and learning from the
    # shared frame 500 (each member one turn of 1,000 frames, learning from half of member 0's turn): the settings of
    # the seed-900 trial above (MB 23.2k -> 84.6k), added when the 3,000-frame case's first seeds (100, 101) showed
    # MB's gain small beside its seeds' spread (+12.7k and +3.1k on ~27k). SB only: there was no time for SB+PSA's.
    # SB+PSA at the same 6,000 frames (the settings of the SB case above, PSA added as in morld_psa-hopper-2obj),
    # added 2026-12-02 (fifth sitting) when SB+PSA's 3,000-frame case had no "both learn" left after the archive
    # fix (d0bb3b8); its budget is SB's, not chosen on its own results.
    **{f"{algo}-hopper-2obj-6k": dict(
        env="mo-hopper-2obj-v5", algo=algo, frames=6_000, eval_every=1_000, gamma=0.995,
        ours=dict(exchange_every=1_000, init_random_frames=500, alpha=1.0, morld_eval_episodes=5),
        mb=dict(exchange_every=1_000, shared_buffer=True, policy_args=dict(learning_starts=500),
                **({"weight_adaptation_method": "PSA"} if algo == "morld_psa" else {})),
        mb_train=dict(num_eval_episodes_for_front=5),
    ) for algo in ("morld", "morld_psa")},
    # GPI-PD (dynamics ensemble at MB's defaults, rollouts from frame 500: MB 5,000) with the GPI-LS
    # case's small Q networks
    "gpi_pd-dst": dict(
        env="deep-sea-treasure-v0", algo="gpi_pd", frames=2_000, eval_every=1_000, gamma=0.99,
        ours=dict(_SMALL_GPI[0], gpi_iteration_frames=500, gpi_dynamics_rollout_starts=500),
        mb=dict(_SMALL_GPI[1], dynamics_rollout_starts=500), mb_train=dict(timesteps_per_iter=500),
    ),
    # GPI-PD at a budget where MB can learn (issue 48: gpi_pd-dst's 2,000 frames left MB at the first treasure on 4
    # of seeds 100-104): 10,000 frames, i.e. one of MB's default iterations (GPIPD.train's timesteps_per_iter
    # 10,000), with the dynamics model's rollouts from MB's default frame 5,000 (dynamics_rollout_starts) and the
    # GPI-LS case's small Q networks and one update a step (the authors' gradient_updates, MB's default 20).
    # Added 2026-12-02 (eighth sitting); its budget is MB's iteration, not chosen on results. Not run to the end: at
    # MB's dynamics defaults (a fit of the ensemble on the whole buffer every 250 frames, each up to 200 epochs) both
    # libraries spent nearly all their time in the fits, whose cost grows with the buffer: after 50 CPU-minutes each,
    # MB's seed 100 was past 6,000 frames and ours' past 4,000 (about 1.5 h a seed on a free core of this machine),
    # so the case below takes the authors' dynamics schedule instead.
    "gpi_pd-dst-10k": dict(
        env="deep-sea-treasure-v0", algo="gpi_pd", frames=10_000, eval_every=2_000, gamma=0.99,
        ours=dict(_SMALL_GPI[0]), mb=dict(_SMALL_GPI[1]), mb_train=dict(),
    ),
    # The same with the dynamics settings of the authors' one discrete GPI-PD run (hyperparameters.toml
    # [gpi_pd.lunarlander.init], their script: dynamics_train_freq 5,000, dynamics_rollout_freq 5,000,
    # dynamics_uncertainty_threshold 20; gradient_updates 1 as _SMALL_GPI) on both sides: the model is fitted and
    # rolled out at frames 5,000 and 10,000, so a seed costs minutes, not hours (issue 48's informative GPI-PD case).
    # MB takes dynamics_train_freq as a callable of the step (mb_runner makes one of the int).
    "gpi_pd-dst-10k-authors": dict(
        env="deep-sea-treasure-v0", algo="gpi_pd", frames=10_000, eval_every=2_000, gamma=0.99,
        ours=dict(_SMALL_GPI[0], gpi_dynamics_train_freq=5_000, gpi_dynamics_rollout_freq=5_000,
                  gpi_uncertainty_threshold=20.0),
        mb=dict(_SMALL_GPI[1], dynamics_train_freq=5_000, dynamics_rollout_freq=5_000,
                dynamics_uncertainty_threshold=20.0),
        mb_train=dict(),
    ),
    "capql-hopper": dict(_CAPQL_HOPPER, frames=1_000, eval_every=500),
    # The same at five times the budget, so that the curve shows learning rather than one step off the
    # untrained policy (MB ~45 frames/s on a free core: ~2 min a seed; ours about 1.5x that)
    "capql-hopper-5k": dict(_CAPQL_HOPPER, frames=5_000, eval_every=1_000),
    # The same at twice that budget: added 2026-12-02 (fifth sitting) after round 2's seeds (100-104) at 5,000
    # frames left MB's gain short of significance (p 0.062; it learned on seeds 0-4), as mosac-hopper-10k was
    # added after mosac-hopper-5k: the budget doubled once, not tuned further (said in NOTES.md).
    "capql-hopper-10k": dict(_CAPQL_HOPPER, frames=10_000, eval_every=2_000),
    # MOSAC (continuous) for one fixed weight: MB 1.3.0's MOSAC (single_policy/ser/mosac_continuous_action.py) is a
    # single-policy learner whose actor and critics take no weight (its `weights` has no default), while our
    # `mosac` is preference-conditioned (trained on a Dirichlet w per episode). Both solve the same task here: MB's
    # MOSAC with `weights=weight`, ours with every training episode's and every evaluation rollout's preference
    # held at `weight` (run_parity.fixed_preference: its networks read the constant w), so the shared evaluator's
    # 16 weights are 16 sampled rollouts of one policy on both sides (MOSAC.eval samples; ours eval_exploration
    # "random"). `weight`: the centre of the simplex (no record: the authors ran MOSAC only inside MORL/D; no
    # objective left out, so longer episodes raise all three returns). At MB's defaults (batch 128, [256, 256],
    # learning_starts 1,000, policy_lr 3e-4, q_lr 1e-3 for critics and temperature, tau 0.005, policy_freq 2,
    # temperature autotuned from log_alpha = 0, i.e. 1.0: its `alpha=0.2` is unused, mosac_continuous_action.py:
    # 141-150,241-247). Ours' foreign defaults (recipes.foreign_defaults "mosac") leave q_lr / alpha_lr at lr
    # (3e-4) and the temperature at 0.2: set to MB's values here.
    "mosac-hopper-5k": dict(
        env="mo-hopper-v5", algo="mosac", frames=5_000, eval_every=1_000, gamma=0.99, weight=[1 / 3, 1 / 3, 1 / 3],
        ours=dict(q_lr=1e-3, alpha_lr=1e-3, alpha=1.0), mb=dict(), mb_train=dict(),
    ),
    # The same at twice the budget. 5,000 frames were picked on a trial seed (900: MB 4.2M -> 6.0M), but on seeds
    # 100-104 MB's hypervolume rose on three seeds and fell on two (100: 4.31M -> 3.29M, 102: 3.59M -> 3.05M; the
    # untrained stochastic policy's 16 rollouts already give 1.6M-4.3M): not a clear gain. Run again on the same
    # seeds at 10,000 frames (evaluated every 2,000), the budget not tuned further (NOTES.md, 2026-12-02).
    "mosac-hopper-10k": dict(
        env="mo-hopper-v5", algo="mosac", frames=10_000, eval_every=2_000, gamma=0.99, weight=[1 / 3, 1 / 3, 1 / 3],
        ours=dict(q_lr=1e-3, alpha_lr=1e-3, alpha=1.0), mb=dict(), mb_train=dict(),
    ),
    # The SAC baseline (ours `sac`: TorchRL's SACLoss on the domain's original scalar reward, `info['original_
    # scalar_reward']` in the authors' code, SPEC §1; it ignores the preference, so the evaluator's 16 weights are
    # 16 sampled rollouts of one policy). MB has no SAC: the reference is TorchRL's own SAC in a plain sota-style
    # loop (torchrl_sac_runner.py, library `torchrl_sac`). A foreign env has no original reward, so the task is our
    # MO-Hopper at its default context (MOHopperDefault-v5: original reward = v_x + h - 0.001 sum(a^2),
    # envs.mujoco.spec._HOPPER_SORL), trained and evaluated there, without the paper's state-action history
    # (history_len 0: the reference steps the plain Gymnasium env) and without domain randomisation. Both sides:
    # [256, 256] (the authors' SACContinuous class default; their Hopper script: [256] * 4), batch 256,
    # learning from frame 1,000, actor lr 3e-4, critics and temperature 1e-3, temperature from 1.0 tuned towards
    # -|A|, Polyak 0.005, gamma 0.99 ([sac.hopper.init] of hyperparameters.toml), one env stepped once per update.
    # The update is TorchRL's sota one on both sides: one joint step of the summed losses every frame
    # (ours: joint_update, policy_freq 1) with TorchRL's log_alpha temperature loss; ours' defaults follow the
    # authors' CleanRL-style update (policy_freq 2, each loss its own step, the alpha form), which this case does
    # not test.
    "sac-hopper-5k": dict(_SAC_HOPPER, frames=5_000, eval_every=1_000),
    # The same SAC task judged on the f_SORL return (the paper's SAC metric, SPEC §3 eval/single_objective_return:
    # the best of the evaluation's 16 episodes of the original scalar reward), which the SAC baseline optimizes;
    # the hypervolume of a policy that ignores the preference says little. 10,000 frames (chosen before any run at
    # this budget, as mosac-hopper-10k's: 9,000 updates after the 1,000 random frames); settings as sac-hopper-5k.
    "sac-hopper-10k": dict(_SAC_HOPPER, frames=10_000, eval_every=2_000, metric="sorl_return_max"),
    # PGMORL: 2 warm-up iterations, then one task selection and 1 evolutionary iteration, each iteration
    # 32 steps x 4 envs x 6 members (MB: 80 and 20 iterations of 2048 steps). `frames` and `eval_every`
    # count env steps of all members, as MB 1.3.0's global_step does (PGMORL.__train_all_agents adds
    # steps x envs per member; max_iterations divides by pop_size). Ours counts one member's steps, as
    # the authors' fork (SPEC §6): its budget is frames / ours_frame_scale and its curve's frames are
    # multiplied back, so both run 3 iterations (2,304 env steps). Two warm-up iterations, not one: ours
    # evaluates a member by the returns of its iteration's rollout (algorithms/pgmorl/recipe.py), so with one the
    # warm-up's end would reuse the untrained members' returns (prediction deltas of 0). delta_weight 0.5
    # (MB: 0.2): the task selection's 15 candidate weights instead of 66 (generate_weights(delta / 2, 3)),
    # and the 6 initial weights spread over the simplex; MB's selection refits its prediction model for
    # every (policy, candidate) pair, ~12 min of a loaded core per seed at 0.2 (NOTES.md).
    "pgmorl-hopper": dict(
        env="mo-hopper-v5", algo="pgmorl", frames=2_304, eval_every=768, gamma=0.995, ours_frame_scale=6,
        ours=dict(pgmorl_warmup=2, pgmorl_evo_iterations=1, frames_per_batch=24 * 32, pgmorl_delta_weight=0.5),
        mb=dict(warmup_iterations=2, evolutionary_iterations=1, steps_per_iteration=32, delta_weight=0.5),
        mb_train=dict(),
    ),
    # PGMORL at a budget where PPO can move off its start (NOTES.md, "PGMORL (not run)": the smallest schedule
    # worth trying): 256 steps x 4 envs per iteration, 10 warm-up iterations, then one task selection and one
    # generation of 5 evolutionary iterations: 15 iterations, 15,360 steps per member (92,160 in MB's count).
    # Evaluated after each 5 iterations (ours) / after the warm-up and the generation (MB: its archive's only
    # updates). delta_weight 0.5 as pgmorl-hopper (MB's 0.2 refits its prediction model ~4x as often).
    # MB's other settings are its defaults. Trial seed 900 (outside every round's seeds) ran first to see
    # whether the budget fits this machine; the round's seeds were not run before the budget was fixed.
    "pgmorl-hopper-92k": dict(
        env="mo-hopper-v5", algo="pgmorl", frames=92_160, eval_every=30_720, gamma=0.995, ours_frame_scale=6,
        ours=dict(pgmorl_warmup=10, pgmorl_evo_iterations=5, frames_per_batch=24 * 256, pgmorl_delta_weight=0.5),
        mb=dict(warmup_iterations=10, evolutionary_iterations=5, steps_per_iteration=256, delta_weight=0.5),
        mb_train=dict(),
    ),
}
if os.environ.get("PARITY_SMOKE"):  # a check of the machinery: every case cut to a few hundred frames
    for _c in CASES.values():
        if _c["algo"] == "pgmorl":  # one iteration is 4 envs x 6 members x steps_per_iteration
            _c.update(frames=4 * 24 * 8, eval_every=2 * 24 * 8)
            _c["ours"] = {**_c["ours"], "pgmorl_warmup": 1, "pgmorl_evo_iterations": 1, "frames_per_batch": 24 * 8}
            _c["mb"] = {**_c["mb"], "warmup_iterations": 1, "evolutionary_iterations": 1, "steps_per_iteration": 8}
            continue
        _c.update(frames=200, eval_every=100)
        if "ref" in _c:  # (a reference of our own: learning from frame 100, so that the smoke run updates)
            _c["ref"] = {**_c["ref"], "init_random_frames": 100}
            _c["ours"] = {**_c["ours"], "init_random_frames": 100}
        _c["mb_train"] = {k: (100 if k == "timesteps_per_iter" else v) for k, v in _c["mb_train"].items()}
        _c["ours"] = {**_c["ours"], **({"gpi_iteration_frames": 100} if "gpi_iteration_frames" in _c["ours"] else {}),
                      **({"exchange_every": 100} if "exchange_every" in _c["ours"] else {})}
        if "exchange_every" in _c["mb"]:
            _c["mb"] = {**_c["mb"], "exchange_every": 100}

#: a case's reference library (``case["reference"]``, default ``"mb"``) -> its name in the report
REFERENCES = {"mb": f"MORL-Baselines {MB_VERSION}",
              "torchrl_sac": "TorchRL's SAC (SACLoss, sota-style loop: torchrl_sac_runner.py)"}


def reference_of(case: dict) -> str:
    """The library a case compares ours with: MB unless the case names another (``"reference"``)."""
    return case.get("reference", "mb")


# ---------------------------------------------------------------------- the paper's own domains (issue 48)
# A paper-domain case (``paper=True``) trains on one of our domain-randomized training ids: ours through
# ``morl_trl.train``, MB's class on the same env through Gymnasium (``import morl_trl.gym``: ``morl_trl/<id>``,
# our :class:`~morl_trl.gym.MOGymnasiumEnv`, one env, a context drawn per episode) under the paper's state-action
# history (``history_len``: ``StateActionHistoryWrapper`` below, the gymnasium twin of our
# ``StateActionHistory``). Both are evaluated by our evaluator on the domain's evaluation suite (SPEC §1: the
# paper's contexts) at the same ``eval_weights`` energy weights and seed, exactly as ``morl-trl train`` evaluates a
# DR training id (``training.parts.make_evaluator``: ``compose_policy_env(make_env(id), history_len)``, the
# packaged reference bounds and specialist fronts), and judged on ``metric`` (``"nhgr"``: NHGR, the mean over the
# suite's contexts, SPEC §2) beside the floor of trivial policies at the same weights and contexts
# (``morl_trl.reporting.floors.floor_at_weights``, what a run's report_floors.json holds; ``paper_floor``).
# Budgets are cut to fit a 2-core CPU shared with three other jobs; everything else is the authors' record
# (/work/shared/reference/hyperparameters.toml, [method.domain]) where MB's class takes it, the same on both
# sides. Ours steps one env with one update per frame (num_envs=1, frames_per_batch=1, updates_per_batch=0: MB's
# and the authors' loop, SPEC §6 "one env step per loop"; our DR default is 16 envs x 64-frame batches).
_ONE_ENV = dict(num_envs=1, frames_per_batch=1, updates_per_batch=0)


#: CAPQL on the paper's MO-Hopper (capql-hopper-paper, capql-hopper-paper-10k: the comment at the first says where
#: each setting comes from); a case adds its frames and evaluation interval
_CAPQL_HOPPER_PAPER = dict(
    env="MOHopperDR-v5", algo="capql", gamma=0.99, paper=True, metric="nhgr", history_len=2, eval_weights=16,
    ours=dict(_ONE_ENV),
    mb=dict(net_arch=[256, 256, 256, 256], batch_size=256, alpha=0.2, tau=0.005, num_q_nets=2,
            learning_starts=1000, learning_rate=3e-4, buffer_size=1_000_000, gradient_updates=1),
    mb_train=dict(),
)


def _paper_envelope(env: str, gamma: float, history_len: int, eps_frames: int, **mb_per_domain) -> dict:
    """A paper-domain Envelope case at 1,000 frames (evaluated every 250 on 16 weights, NHGR): ours one env with
    MB's weight input (``envelope_network="mb"``) and eps decaying over ``eps_frames``; MB with the record's
    settings shared by [envelope.lavagrid] and [envelope.lunarlander] ([256]*4, batch 128, learning_starts 100,
    eps 1 -> 0.05 over ``eps_frames``, homotopy 0.95 never decayed, PER alpha 0.6, grad norm 1, lr 3e-4,
    buffer 1M, hard target copies, one update a step) and the domain's ``mb_per_domain`` on top."""
    return dict(env=env, algo="envelope", frames=1_000, eval_every=250, gamma=gamma, paper=True, metric="nhgr",
                history_len=history_len, eval_weights=16,
                ours=dict(_ONE_ENV, envelope_network="mb", eps_frames=eps_frames),
                mb=dict(net_arch=[256, 256, 256, 256], batch_size=128, learning_starts=100, initial_epsilon=1.0,
                        final_epsilon=0.05, epsilon_decay_steps=eps_frames, initial_homotopy_lambda=0.95, per=True,
                        per_alpha=0.6, max_grad_norm=1.0, learning_rate=3e-4, buffer_size=1_000_000, tau=1.0,
                        gradient_updates=1, **mb_per_domain),
                mb_train=dict())


PAPER_CASES: dict[str, dict] = {
    # Envelope on MO-LavaGrid, the record's [envelope.lavagrid]: [256]*4, batch 128, 4 sampled weights ('gaussian',
    # MB's only sampler), target hard copy every 200 steps, learning_starts 100, eps 1 -> 0.05 over 5M steps (cut, below),
    # homotopy 0.95 never decayed, PER
    # alpha 0.6 without IS weights, grad norm 1, lr 3e-4, buffer 1M, gamma 0.995; evaluation 16 energy weights
    # (record: 100) x 1 episode on the 8 LavaGrid contexts. Cut: frames (record 5M) and with them eps's decay,
    # which spans the whole budget as in the record's run (5M of 5M): 1 -> 0.05 over the case's frames on both
    # sides (at the record's 5M eps would stay ~1 here: random behaviour throughout). Authors' fork vs MB 1.3.0
    # (SPEC §6, Envelope) that apply: w enters after the first hidden layer in the fork, at the input in MB (both
    # sides here use MB's, ours envelope_network="mb"); everything else of SPEC §6's Envelope list is the same in
    # MB 1.3.0 (gaussian weight per episode, batch repeated per sampled weight, homotopy loss, grad clip 1, PER
    # priority from the first weight's rows with the running max, epsilon decaying after learning_starts: ours too
    # since b4b441a; this case's ours runs, made before it, decayed it from frame 0, 100 frames earlier).
    # Budget: 1,000 frames (MB ~12 frames/s on this shared CPU, trial seed 900); the paper's own Envelope scores
    # 0.02 NHGR here after 5M frames (SPEC §3): no budget that fits makes this case informative.
    "envelope-lavagrid": _paper_envelope("MOLavaGridDR-v0", 0.995, 0, 1_000, num_sample_w=4,
                                         target_net_update_freq=200),
    # Envelope on MO-LunarLander, the record's [envelope.lunarlander] (the README's main job's method): history 2
    # (obs 26), [256]*4, batch 128, 8 sampled weights, target every 1000, eps 1 -> 0.05 over 1M (cut with the
    # budget, below), homotopy 0.95, PER, gamma 0.99; 16 weights on the 8 LunarLander contexts. Cut: frames (3M)
    # and, so that exploration ends inside the budget as it does in the record's run (1M of 3M), eps decays over
    # the first third of the budget on both sides (333 of 1,000 frames). Budget: 1,000 frames (MB ~4 frames/s on
    # this shared CPU; trial seed 900: NHGR 0.283 -> 0.473 at 500 -> 0.334 at 1,000). SPEC §6's Envelope
    # differences: as for LavaGrid (w position: both sides MB's; ours' runs predate b4b441a's eps decay from learning_starts).
    "envelope-lunarlander": _paper_envelope("MOLunarLanderDR-v0", 0.99, 2, 333, num_sample_w=8,
                                            target_net_update_freq=1000),
    # CAPQL on MO-Hopper, the record's [capql.hopper]: history 2 (obs 39), [256]*4, batch 256, alpha 0.2 fixed,
    # tau 0.005, 2 Q-nets, learning_starts 1000, lr 3e-4, buffer 1M, gamma 0.99; 16 weights on the 6 Hopper
    # contexts. Cut: frames (3M): 2,000 updates after the record's 1,000 random frames (learning_starts stays: MB
    # samples a batch without replacement, so it must be at least the batch, 256). SPEC §6's CAPQL list is the
    # same in MB 1.3.0 (a cone weight per step stored with the transition, deterministic tanh(mean) collection after learning_starts and at evaluation, per-objective
    # min of the target nets minus alpha log pi, one critic + one actor step per env step, no target actor).
    "capql-hopper-paper": dict(_CAPQL_HOPPER_PAPER, frames=3_000, eval_every=750),
    # The same at 10,000 frames (9,000 updates), evaluated every 2,000: at 3,000 MB did not learn (gain 0.011, p 0.38;
    # NOTES.md, 2026-12-02), and 10,000 is the budget at which MB's CAPQL learns on MO-Gymnasium's hopper
    # (capql-hopper-10k). Chosen before any run of it, from that case, not tuned on its seeds.
    "capql-hopper-paper-10k": dict(_CAPQL_HOPPER_PAPER, frames=10_000, eval_every=2_000),
}
if os.environ.get("PARITY_SMOKE"):
    for _c in PAPER_CASES.values():
        _c.update(frames=200, eval_every=100)
CASES.update(PAPER_CASES)


def case_metric(case: dict) -> str:
    """The metric a case's verdict and summary use: ``"hypervolume"`` unless the case names one (``"nhgr"``)."""
    return case.get("metric", "hypervolume")


def case_eval_weights(case: dict) -> int:
    return int(case.get("eval_weights", EVAL_WEIGHTS))


def gym_id(env_id: str) -> str:
    """The Gymnasium id MB's class trains on: ``morl_trl/<id>`` for a paper-domain id (``import morl_trl.gym``)."""
    from morl_trl.gym import gymnasium_id

    return gymnasium_id(env_id)


class StateActionHistoryWrapper:
    """The paper's state-action history on a Gymnasium env, for MB's classes: observation
    ``[s_{t-L}, a_{t-L}, ..., s_{t-1}, a_{t-1}, s_t]``, padded at a reset with ``s_0`` and zero actions, discrete
    actions as their index (float): what our ``morl_trl.transforms.StateActionHistory`` writes (the authors'
    ``HistoryWrapper(history_len=2, state+action)``, SPEC §1.2 "History"), so that MB trains on what our evaluator
    (``compose_policy_env(..., history_len)``) shows its policy. ``length`` 0: the env as it is."""

    def __new__(cls, env, length: int):
        import gymnasium

        if not length:
            return env

        class _History(gymnasium.Wrapper):
            def __init__(self, env, length):
                super().__init__(env)
                self.length = length
                self.discrete = isinstance(env.action_space, gymnasium.spaces.Discrete)
                self.obs_dim = int(np.prod(env.observation_space.shape))
                self.act_dim = 1 if self.discrete else int(np.prod(env.action_space.shape))
                n = (length + 1) * self.obs_dim + length * self.act_dim
                self.observation_space = gymnasium.spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)

            def _obs(self):
                parts = []
                for s, a in zip(self._states[:-1], self._actions):
                    parts += [s, a]
                return np.concatenate(parts + [self._states[-1]]).astype(np.float32)

            def reset(self, **kwargs):
                obs, info = self.env.reset(**kwargs)
                s0 = np.asarray(obs, dtype=np.float32).reshape(-1)
                self._states = [s0] * (self.length + 1)
                self._actions = [np.zeros(self.act_dim, dtype=np.float32)] * self.length
                return self._obs(), info

            def step(self, action):
                obs, reward, terminated, truncated, info = self.env.step(action)
                a = np.asarray(action, dtype=np.float32).reshape(-1)
                self._states = self._states[1:] + [np.asarray(obs, dtype=np.float32).reshape(-1)]
                self._actions = self._actions[1:] + [a]
                return self._obs(), reward, terminated, truncated, info

        return _History(env, length)


def make_paper_gym_env(case: dict):
    """The Gymnasium env MB's class trains on for a paper-domain case: ``morl_trl/<env>`` under the case's history."""
    import gymnasium

    import morl_trl.gym  # noqa: F401  (registers morl_trl/<id>)

    return StateActionHistoryWrapper(gymnasium.make(gym_id(case["env"])), case.get("history_len", 0))


def context_means(per_context: dict[str, dict]) -> dict:
    """One curve point's values from the per-context metrics of an evaluation on a suite: each metric's mean over
    the contexts (what a run's log prints as "mean over contexts" and ``EvaluationResult.aggregate`` holds), and
    ``per_context`` (context -> NHGR and hypervolume)."""
    names = sorted({k for m in per_context.values() for k in m})
    out: dict = {}
    for k in names:
        vals = [m.get(k) for m in per_context.values()]
        vals = [float(v) for v in vals if v is not None and v == v]
        if len(vals) == len(per_context) and k in ("nhgr", "normalized_hypervolume", "hypervolume", "eum", "eugr",
                                                    "normalized_eum", "cardinality"):
            out[k] = float(np.mean(vals))
    out["per_context"] = {c: {k: (None if m.get(k) is None else float(m[k])) for k in ("nhgr", "hypervolume")}
                          for c, m in per_context.items()}
    return out


def evaluate_paper_policy(policy, case: dict, seed: int) -> dict:
    """``policy`` on the case's domain suite with the evaluator ``morl-trl train`` builds for a DR training id
    (``morl_trl.training.parts``: ``policy_env_factory``, ``load_reference``): the paper's contexts, the case's
    energy weights, one episode each, the case's discount and history, the run's seed."""
    from types import SimpleNamespace

    from morl_trl.envs.registry import domain_of
    from morl_trl.evaluation import MultiContextEvaluator
    from morl_trl.training.parts import load_reference, policy_env_factory

    spec = domain_of(case["env"])
    cfg = SimpleNamespace(env_id=case["env"], history_len=case.get("history_len", 0), reference_dir=None)
    ev = MultiContextEvaluator(policy, spec.train_id, weights=case_eval_weights(case), episodes=EVAL_EPISODES,
                               gamma=case["gamma"], env_factory=policy_env_factory(cfg, "cpu"),
                               reference=load_reference(cfg, spec), seed=seed)
    try:
        result = ev.evaluate()
    finally:
        ev.close()
    return context_means({c: dict(result.per_context[c].metrics) for c in result.context_names})


def paper_floor(case_name: str, out: Path) -> dict | None:
    """The floor of trivial policies for a paper-domain case: ``floor_at_weights`` (the code that writes a run's
    report_floors.json) at the case's weights on the domain's evaluation suite, cached in
    ``out/floors/<case>.json``: ``{"policy", "mean", "nhgr": {context: value}, "where"}``; ``None`` for other
    cases."""
    case = CASES[case_name]
    if not case.get("paper"):
        return None
    from types import SimpleNamespace

    from morl_trl.envs.registry import domain_of
    from morl_trl.evaluation.evaluator import suite_contexts
    from morl_trl.reporting.floors import floor_at_weights
    from morl_trl.training.parts import load_reference

    spec = domain_of(case["env"])
    _, contexts, _ = suite_contexts(spec.train_id)
    reference = load_reference(SimpleNamespace(reference_dir=None), spec)
    cache = Path(out) / "floors" / f"{case_name}.json"
    cache.parent.mkdir(parents=True, exist_ok=True)
    best, where = floor_at_weights(spec.train_id, case_eval_weights(case), list(contexts), reference, cache=cache)
    if best is None:
        return None
    return dict(policy=best.policy, mean=best.mean, nhgr=dict(best.nhgr), where=where)


PENDING: list[str] = []  # every case of issue 29 has a runner

# the shared evaluation protocol: 16 weights (MB's num_eval_weights_for_front is 100: cut for the
# CPU time, the same for both libraries); episodes 1 (these envs and the greedy policies are
# deterministic but for MuJoCo's reset noise); the evaluation discount is the case's gamma
EVAL_WEIGHTS = 16
EVAL_EPISODES = 1


def evaluate_policy(policy, env_id: str, gamma: float, seed: int) -> dict[str, float]:
    """Evaluate ``policy(td) -> td`` (``"observation"``, ``"preference"`` in, ``"action"`` out) with
    morl_trl's evaluator: hypervolume (the env's reference point), EUM, IGD and the HV ratio to the
    true front."""
    from morl_trl.evaluation import MultiContextEvaluator

    ev = MultiContextEvaluator(policy, env_id, weights=EVAL_WEIGHTS, episodes=EVAL_EPISODES, gamma=gamma, seed=seed)
    result = ev.evaluate()
    metrics = dict(result.per_context[env_id].metrics)
    ev.close()
    if result.has_sorl:  # the f_SORL return (an env with an original scalar reward): the SAC baseline's metric,
        # under the names our runs' eval/metrics.csv gives it (EvaluationResult.rows)
        best = result.sorl_best()[env_id]
        metrics.update(sorl_return_max=best["return_max"], sorl_discounted_return_max=best["discounted_return_max"])
    return {k: (None if v is None else float(v)) for k, v in metrics.items()}


# ---------------------------------------------------------------------- the floor of trivial policies
def evaluate_floor(env_id: str, gamma: float, seed: int) -> dict[str, dict[str, float]]:
    """Every trivial policy (``morl_trl.reporting.floors.trivial_policies``: the random policy and every constant
    action, continuous actions the zero action; MO-Gymnasium ids as our domains') through :func:`evaluate_policy`'s
    protocol at ``seed`` (the evaluation seed a run of that seed uses): ``name -> metrics``, what a run's finals
    are read against (``verdict.above_floor``)."""
    from morl_trl.reporting.floors import constant_policy, trivial_policies

    return {name: evaluate_policy("random" if isinstance(target, str) else constant_policy(target), env_id, gamma, seed)
            for name, target in trivial_policies(env_id).items()}


def floor_path(out: Path, case: str, seed: int) -> Path:
    """Where a case's floor at ``seed`` is cached (a subfolder: the runs' loader reads ``<case>/*.json`` only)."""
    return Path(out) / case / "floor" / f"s{seed}.json"


def case_floor(out: Path, case: str, seed: int, compute: bool = True) -> dict | None:
    """The case's floor at ``seed`` (``{"policies": name -> metrics, "commit": ...}``), from its cache file, else
    evaluated and cached when ``compute`` (a few seconds: 16 episodes per trivial policy), else ``None``."""
    import json

    path = floor_path(out, case, seed)
    if path.exists():
        return json.loads(path.read_text())
    if not compute:
        return None
    spec = CASES[case]
    data = dict(case=case, seed=seed, env=spec["env"], gamma=spec["gamma"],
                policies=evaluate_floor(spec["env"], spec["gamma"], seed))
    write_result(path, data)
    return data


def best_floor(floor: dict, metric: str = "hypervolume") -> tuple[str, float] | None:
    """``(policy, value)`` of the trivial policy with the highest ``metric`` in a :func:`case_floor` record."""
    vals = [(name, m.get(metric)) for name, m in floor["policies"].items() if m.get(metric) is not None]
    return max(vals, key=lambda nv: nv[1]) if vals else None


# ---------------------------------------------------------------------- the Q estimates' bound (issue 48)
def dst_value_bounds(gamma: float) -> dict[str, float]:
    """Deep Sea Treasure's largest discounted return per objective, by value iteration over its grid with its
    own ``step`` (each objective maximised on its own, every state, every policy): for ``w`` on the simplex,
    ``w . Q(s, a, w) <= max_i max_{s, pi} G_i``, attained at a vertex of the simplex. ``any_state``: that bound
    over every state (a true Q value can be no higher anywhere: 23.7, the deepest treasure one step away);
    ``start``: from the start state (19.78 at gamma 0.99: the deepest treasure's 23.7 discounted over its 19 steps,
    the largest entry of ``pareto_front(gamma)``)."""
    import mo_gymnasium as mo_gym

    env = mo_gym.make("deep-sea-treasure-v0").unwrapped
    env.reset(seed=0)
    start = tuple(int(x) for x in env.current_state)
    rows, cols = env.sea_map.shape
    states = [(r, c) for r in range(rows) for c in range(cols) if env._is_valid_state(np.array([r, c]))
              and env._get_map_value(np.array([r, c])) in (0, 0.0)]  # (a treasure cell ends the episode)
    model = {}
    for s in states:
        for a in range(env.action_space.n):
            env.current_state = np.array(s)
            _, r, term, _, _ = env.step(a)
            model[s, a] = (np.asarray(r, dtype=np.float64), bool(term), tuple(int(x) for x in env.current_state))
    k = len(next(iter(model.values()))[0])
    v = {s: np.zeros(k) for s in states}
    for _ in range(1_000):
        new = {s: np.max([r + (0.0 if t else gamma) * v.get(n, np.zeros(k)) for (r, t, n) in
                          (model[s, a] for a in range(env.action_space.n))], axis=0) for s in states}
        done = max(float(np.abs(new[s] - v[s]).max()) for s in states) < 1e-10
        v = new
        if done:
            break
    return dict(any_state=float(max(v[s].max() for s in states)), start=float(v[start].max()))


#: the bound per env id (``None``: not known for that env, nothing checked)
Q_BOUNDS = {"deep-sea-treasure-v0": dst_value_bounds}


def q_bounds(env_id: str, gamma: float) -> dict[str, float] | None:
    fn = Q_BOUNDS.get(env_id)
    return None if fn is None else fn(gamma)


class QEstimateLog:
    """The largest scalarized Q estimates an Envelope run's updates produced, from the online network's forward
    that the loss's gradient goes through (every state of the batch under every sampled ``w``): per update the
    greedy values ``max_a w . Q(s, a, w)``, their maximum (``max_scalarized_q``: the largest single estimate) and
    their mean over the batch (``max_mean_scalarized_q``: the largest batch mean, what the issue saw rise to
    100-200), running maxima, with their values at each evaluation point (``mark(frames)``)."""

    def __init__(self) -> None:
        self.max = self.max_mean = float("-inf")
        self.updates = 0
        self.points: list[dict] = []

    def record(self, w, q) -> None:
        """``w`` ``[..., k]``, ``q`` ``[..., |A|, k]`` with the same leading dims."""
        import torch

        with torch.no_grad():
            greedy = torch.einsum("...k,...ak->...a", w.detach().float(), q.detach().float()).max(-1).values
            top, mean = float(greedy.max()), float(greedy.mean())
        self.updates += 1
        self.max, self.max_mean = max(self.max, top), max(self.max_mean, mean)

    def _values(self) -> dict:
        seen = self.updates > 0
        return dict(max_scalarized_q=self.max if seen else None, max_mean_scalarized_q=self.max_mean if seen else None)

    def mark(self, frames: int) -> None:
        self.points.append(dict(frames=int(frames), updates=self.updates, **self._values()))

    def result(self, env_id: str, gamma: float) -> dict:
        bounds = q_bounds(env_id, gamma)
        out = dict(**self._values(), updates=self.updates, points=self.points,
                   bound_any_state=None if bounds is None else bounds["any_state"],
                   bound_start=None if bounds is None else bounds["start"])
        seen = bounds is not None and self.updates > 0
        # (a true Q value is at most bound_any_state anywhere, so either estimate above it is an overestimate)
        out["exceeds_bound"] = bool(self.max > bounds["any_state"] + 1e-4) if seen else None
        out["mean_exceeds_bound"] = bool(self.max_mean > bounds["any_state"] + 1e-4) if seen else None
        return out


def result_path(out: Path, case: str, lib: str, seed: int) -> Path:
    return Path(out) / case / f"{lib}_s{seed}.json"


#: a case's folders of runs that the tables do not use: ``earlier/`` (made at another commit than the page's
#: ``--commit``, moved aside when that commit ran the seed again) and ``superseded/`` (made before a library fix
#: that changed the method's trajectories). Each run there is listed under its case, never dropped.
SET_ASIDE = ("earlier", "superseded")


def made_at(record: dict, commit: str) -> bool:
    """Whether a result ``record`` was made at ``commit`` (a full or abbreviated SHA, at least 7 hex digits) from a
    clean checkout (a ``+dirty`` run was made by code no commit holds)."""
    made = str(record.get("commit", ""))
    if len(commit) < 7:
        raise ValueError(f"commit {commit!r}: give at least 7 hex digits of a SHA")
    return not made.endswith("+dirty") and len(made) >= 7 and (made.startswith(commit) or commit.startswith(made))


def short_commit(commit: str) -> str:
    """A recorded commit as a page shows it: 7 hex digits, ``+dirty`` kept (``2b330cb+dirty``)."""
    return commit[:7] + ("+dirty" if commit.endswith("+dirty") else "")


def set_aside(path: Path) -> Path:
    """Move the result file ``path`` into its case's ``earlier/`` folder, named by the commit that made it
    (``ours_s100@2b330cb.json``); returns the new path. A run is set aside, never deleted."""
    tag = short_commit(str(json.loads(path.read_text()).get("commit", "unknown")))
    dest = path.parent / "earlier" / f"{path.stem}@{tag}.json"
    dest.parent.mkdir(parents=True, exist_ok=True)
    n = 1
    while dest.exists():  # (the same seed set aside twice at one commit: keep both)
        dest, n = path.parent / "earlier" / f"{path.stem}@{tag}.{n}.json", n + 1
    os.replace(path, dest)
    return dest


def _own_output(path: str) -> bool:
    """Whether a repository path is what this benchmark writes itself (the page, its plots, its result files)."""
    return path == "benchmarks/parity/RESULTS.md" or (path.startswith("benchmarks/parity/") and (
        path.endswith(".png") or path.startswith("benchmarks/parity/results/")))


def current_commit() -> str:
    """The checkout's commit (``+dirty`` with uncommitted changes to tracked files other than the benchmark's own
    outputs: a long run regenerates RESULTS.md and the plots after every round), or ``"unknown"``."""
    import subprocess

    here = Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True,
                             timeout=30).stdout.strip()
        status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=here,
                                capture_output=True, text=True, timeout=30).stdout
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    dirty = [line[3:] for line in status.splitlines() if line.strip() and not _own_output(line[3:].split(" -> ")[-1])]
    return (sha + ("+dirty" if dirty else "")) if sha else "unknown"


def machine() -> str:
    """The CPU that runs this process (``/proc/cpuinfo``'s model name, else ``platform.processor()``), with its
    logical core count: float32 results differ by ~1e-7 between CPUs (AVX2 / AVX-512, AMD / Intel), which is enough
    to set an RL run on another trajectory, so a rerun on another machine is a new sample, not a check."""
    import platform

    name = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                name = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{name or platform.processor() or platform.machine()}, {os.cpu_count()} cores"


def write_result(path: Path, data: dict) -> None:
    """Atomically: a crash never leaves a half-written result that a rerun would skip. The result records
    the commit that made it (``commit``) and the machine (:func:`machine`), unless it already says."""
    data = {**data, "commit": data.get("commit") or current_commit(), "machine": data.get("machine") or machine()}
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    with os.fdopen(fd, "w") as fh:
        json.dump(data, fh, indent=1)
    os.replace(tmp, path)
