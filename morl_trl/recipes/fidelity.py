"""Our defaults beside the authors' record, one row per setting (``morl-trl config ALGO ENV --compare-authors``).

The record is ``hyperparameters.toml`` (every effective setting of every (method, domain) the authors ran, with its
source), shipped as ``morl_trl/recipes/data/authors_hyperparameters.toml`` (a verbatim copy of the project's
``reference/hyperparameters.toml``). Each setting maps to one rule, here and nowhere else:

* :class:`Same`: a config key that must hold the authors' value (else the row says ``differs``,
  which the all-pairs test refuses);
* :class:`Deliberate`: a key whose default differs on purpose, with the reason;
* :class:`NotApplicable`: a setting with no counterpart here (logging identity, unused arguments), with the reason;
* :class:`Code`: a mechanism our code implements (where); ``open`` names a difference that is
  known and not fixed yet: the row says ``differs: <what>`` and :func:`open_differences` lists it.

Example:
    >>> rows = compare("gpi_ls", "MOLunarLanderDR-v0")
    >>> row = next(r for r in rows if r.setting == "init.gradient_updates")
    >>> row.authors, row.our_key, row.ours, row.status
    (1, 'gpi_gradient_updates', 1, 'same')
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from morl_trl.recipes.config import TrainConfig, resolve_config
from morl_trl.algorithms.domains import MARIO, MUJOCO, RECORD_DOMAINS

__all__ = ["Same", "Deliberate", "NotApplicable", "Code", "Row", "RECORD_PATH", "METHODS", "record", "pairs",
           "compare", "open_differences", "rule_for", "format_rows", "markdown", "record_meta"]

RECORD_PATH = Path(__file__).parent / "data" / "authors_hyperparameters.toml"
#: the record's method names -> our algorithm names
METHODS = {"envelope": "envelope", "capql": "capql", "gpi_ls": "gpi_ls", "gpi_pd": "gpi_pd", "morld_sb": "morld",
           "morld_sb_psa": "morld_psa", "pcn": "pcn", "pgmorl": "pgmorl", "sac": "sac"}


# ---------------------------------------------------------------------- rules
@dataclass(frozen=True)
class Same:
    """``key`` (or ``ours(cfg)``, labelled ``key``) must equal the authors' value (or ``expect(value, cfg)``)."""

    key: str
    expect: Callable[[Any, TrainConfig], Any] | None = None
    ours: Callable[[TrainConfig], Any] | None = None


@dataclass(frozen=True)
class Deliberate:
    key: str | None
    reason: str


@dataclass(frozen=True)
class NotApplicable:
    reason: str


@dataclass(frozen=True)
class Code:
    """A mechanism implemented in code (``where``); ``open(env_id)`` (or a string) names a known
    difference that is not fixed yet."""

    where: str
    open: str | Callable[[str], str | None] | None = None


@dataclass(frozen=True)
class Row:
    method: str
    env_id: str
    setting: str
    authors: Any
    our_key: str
    ours: Any
    status: str

    def as_dict(self) -> dict[str, Any]:
        return {"setting": self.setting, "authors": self.authors, "our_key": self.our_key, "ours": self.ours,
                "status": self.status}


def _domain(cfg: TrainConfig):
    from morl_trl.envs import domain_of

    return domain_of(cfg.env_id)


def _ref(cfg: TrainConfig) -> tuple:
    """The hypervolume reference point: ``ref_point``, else the domain's."""
    return tuple(cfg.ref_point if cfg.ref_point is not None else _domain(cfg).hv_ref_point)


def _gamma(cfg: TrainConfig) -> float:
    return cfg.gamma if cfg.gamma is not None else _domain(cfg).gamma


def _continuous(env_id: str) -> bool:
    return env_id in MUJOCO


# what every script shares
_LOGGING = NotApplicable("logging identity (wandb); our runs log with the `logger` key, which does not change results")
_UNUSED = NotApplicable("unused by the authors' runs (test_generalization=True bypasses it; the record says so)")
_ONE_CALL = NotApplicable("the authors call train() once per run; so does every run here")
_SEED = NotApplicable("the run's seed: `seed` (per run, --seed); the paper's seeds are 5, 26, 47, 76, 92")
_ENV_STACK = Code("envs/ (DR context drawn at every reset) + transforms.StateActionHistory(history_len)")
_EVALUATOR = Code("evaluation.evaluator (energy weights, one episode per weight and context, discounted fronts)")

COMMON: dict[str, Any] = {
    "script": NotApplicable("the authors' launch script (provenance)"),
    "launch_algo": NotApplicable("the authors' --algo name (provenance)"),
    "algo_class": NotApplicable("the authors' class (provenance)"),
    "paper_result_label": NotApplicable("label of the paper's result files (provenance)"),
    "in_paper_results": NotApplicable("whether the paper reports the pair (provenance)"),
    "paper_note": NotApplicable("a note on the paper's data (provenance)"),
    "paper_seeds": _SEED,
    "script_seed": _SEED,
    "wandb_group": _LOGGING,
    "wandb_tags": _LOGGING,
    "test_generalization": NotApplicable("always: every run here is evaluated by the generalization evaluator"),
    "env_id": Same("env_id"),
    "test_envs": Same("eval_contexts", expect=lambda v, cfg: sorted(v),
                      ours=lambda cfg: sorted(cfg.eval_contexts or _domain(cfg).evaluation_ids)),
    "ref_point": Same("ref_point", expect=lambda v, cfg: tuple(v), ours=lambda cfg: _ref(cfg)),
    "gamma": Same("gamma", ours=_gamma),
    "num_timesteps": Same("frames"),
    "obs_shape": Code("envs/ + StateActionHistory (tests/envs check the shapes)"),
    "action_space": Code("envs/ (tests/envs check the action specs)"),
    "reward_dim": Code("envs/ (tests/envs check the reward specs)"),
    "max_episode_steps": Same("DomainSpec.max_episode_steps", ours=lambda cfg: _domain(cfg).max_episode_steps),
    "training_env": _ENV_STACK,
    "init.env": _ENV_STACK,
    "init.env_id": Same("env_id"),
    "init.gamma": Same("gamma", ours=_gamma),
    "init.seed": _SEED,
    "init.device": NotApplicable("`device` (cpu by default); the authors' 'auto' only picks the hardware"),
    "init.log": NotApplicable("the authors' evaluator runs only with log=True; ours always runs"),
    "init.project_name": _LOGGING,
    "init.experiment_name": _LOGGING,
    "init.wandb_entity": _LOGGING,
    "init.wandb_group": _LOGGING,
    "init.wandb_tags": _LOGGING,
    "init.offline_mode": _LOGGING,
    "init.id": NotApplicable("a member's index (no setting)"),
    "init.parent_rng": NotApplicable("RNG plumbing; one `seed` drives every generator here"),
    "init.rng": NotApplicable("RNG plumbing; one `seed` drives every generator here"),
    "train.total_timesteps": Same("frames"),
    "train.eval_env": _EVALUATOR,
    "train.ref_point": Same("ref_point", expect=lambda v, cfg: tuple(v), ours=lambda cfg: _ref(cfg)),
    "train.known_pareto_front": NotApplicable("no known front for these domains (None in every script)"),
    "train.test_generalization": NotApplicable("always: every run here is evaluated by the generalization evaluator"),
    "train.eval_mo_freq": Same("eval_interval"),
    "train.verbose": NotApplicable("console verbosity"),
    "train.reset_num_timesteps": _ONE_CALL,
    "train.reset_learning_starts": _ONE_CALL,
    "train.start_time": NotApplicable("wall-clock bookkeeping"),
    "train.checkpoints": NotApplicable("the authors save no checkpoints; ours (`checkpoint_interval`) do not change "
                                       "learning"),
    "train.num_eval_weights_for_front": _UNUSED,
    "train.num_eval_episodes_for_front": _UNUSED,
    "train.num_eval_weights_for_eval": _UNUSED,
    "train.num_points_pf": _UNUSED,
    # the evaluator
    "evaluator.algo_name": NotApplicable("a label in their logs"),
    "evaluator.algo_suffix": NotApplicable("a label in their logs"),
    "evaluator.seed": _SEED,
    "evaluator.test_envs": Same("eval_contexts", expect=lambda v, cfg: sorted(v),
                                ours=lambda cfg: sorted(cfg.eval_contexts or _domain(cfg).evaluation_ids)),
    "evaluator.async_envs": NotApplicable("process layout; our evaluation contexts step as one batched env"),
    "evaluator.record_video": NotApplicable("videos off in every script"),
    "evaluator.record_video_w_freq": NotApplicable("videos off in every script"),
    "evaluator.record_video_ep_freq": NotApplicable("videos off in every script"),
    "evaluator.num_eval_weights": Same("eval_weights"),
    "evaluator.num_eval_episodes": Same("eval_episodes"),
    "evaluator.fixed_weights": NotApplicable("None in every script: the energy weights below"),
    "evaluator.save_weights": NotApplicable("a logging switch"),
    "evaluator.save_metric": NotApplicable("which metric their logger saves; we record every metric"),
    "evaluator.normalization": Code("metrics/ + reporting/: normalised HV with the published min-max bounds"),
    "evaluator.recover_single_objective": Code("evaluation.evaluator records the original scalar return (f_SORL)"),
    "evaluator.generalization_algo": Same("history_len", expect=lambda v, cfg: 2 if v == "dr_state_action_history"
                                          else 0),
    "evaluator.history_len": Same("history_len", expect=lambda v, cfg: v if v > 1 else 0),
    "evaluator.eval_weights": Code("preferences.equally_spaced_weights (pymoo energy directions, seed 42)"),
    "evaluator.eval_mo_freq": Same("eval_interval"),
    "evaluator.discount_in_eval": Same("gamma", ours=_gamma),
    "evaluator.test_env_wrappers": Code("evaluation contexts are built like the training env (history as trained)"),
}

_NONE = lambda v, cfg: None if v == "None" else v  # noqa: E731  (the record writes Python's None as "None")
_NO_LN = Same("(no LayerNorm)", ours=lambda cfg: False)
_NO_DROPOUT = Same("(no dropout)", ours=lambda cfg: 0.0)
_ORTHO_ENVELOPE = Code("objectives.networks.orthogonal_init_ on every Linear and Conv2d (envelope_network='authors')")


def _net_arch(v, cfg):
    return tuple(v)


def _mario_after_cnn(v, cfg):
    """net_arch on pixels: the first width is the CNN's feature layer, ``hidden`` is what follows it."""
    return tuple(v[1:]) if cfg.env_id == MARIO else tuple(v)


def _target_frames(v, cfg):
    """A hard copy every ``v`` frames = every ``v / update_frequency`` updates."""
    return None if cfg.tau is not None and v == 1 else v // cfg.update_frequency


#: the rows the DQN family (Envelope, GPI-LS/PD) shares (their configs: ``algorithms.envelope.config``, ``algorithms.gpi.config``)
_DQN_ROWS = {
    "init.learning_rate": Same("lr"),
    "init.initial_epsilon": Same("eps_start"),
    "init.final_epsilon": Same("eps_end"),
    "init.epsilon_decay_steps": Same("eps_frames"),
    "init.tau": Same("tau", expect=lambda v, cfg: None if v == 1.0 else v),
    "init.target_net_update_freq": Same("target_update_period"),
    "init.buffer_size": Same("buffer_size"),
}

ENVELOPE = {
    **_DQN_ROWS,
    "init.net_arch": Same("hidden", expect=_mario_after_cnn),
    "init.batch_size": Same("batch_size"),
    "init.learning_starts": Same("init_random_frames"),
    "init.gradient_updates": Same("updates_per_batch", expect=lambda v, cfg: 0 if v == 1 else v),
    "init.max_grad_norm": Same("max_grad_norm"),
    "init.envelope": Code("objectives.envelope.EnvelopeQLoss (the envelope target over sampled weights)"),
    "init.dist": Same("preference_distribution"),
    "init.num_sample_w": Same("num_sampled_prefs"),
    # data.RunningMaxPrioritizedSampler: (|w . delta| + running max)^alpha, new items at the running max
    "init.per": Same("(prioritized, per_running_max)", expect=lambda v, cfg: (v, v),
                     ours=lambda cfg: (cfg.prioritized, cfg.per_running_max)),
    "init.per_alpha": Same("per_alpha"),
    "init.initial_homotopy_lambda": Same("homotopy_lambda0"),
    "init.final_homotopy_lambda": NotApplicable("never reached: homotopy_decay_steps is None, so lambda stays at its "
                                                "initial value (our homotopy_final = null)"),
    "init.homotopy_decay_steps": Same("homotopy_final", expect=lambda v, cfg: None),
    "train.weight": Same("preference_resample", expect=lambda v, cfg: "episode"),
    "train.total_episodes": NotApplicable("None: the run is bounded by frames"),
    "network.q_net": Code("objectives.networks.make_vector_q_network(preference_layer=1, init='orthogonal'); on "
                          "pixels w is concatenated after the CNN"),
    "network.q_output": Code("objectives.networks.make_vector_q_network: [actions, objectives]"),
    "network.weight_input": Same("envelope_network", expect=lambda v, cfg: "authors"),
    "network.num_hidden_layers": Same("hidden", expect=lambda v, cfg: v - (1 if cfg.env_id == MARIO else 0),
                                      ours=lambda cfg: len(cfg.hidden)),
    "network.layer_norm": _NO_LN,
    "network.dropout": _NO_DROPOUT,
    "network.init": _ORTHO_ENVELOPE,
    "network.num_q_nets": Code("one Q-network and its target (objectives.envelope)"),
    "network.optimizer": Same("lr"  , expect=lambda v, cfg: 3e-4),
    "network.replay_action_dtype": NotApplicable("storage dtype of the action; ours stores the action spec's dtype"),
    "derived.epsilon_schedule": Code("training.agent: random actions before init_random_frames, then epsilon "
                                     "linear from eps_start to eps_end over the eps_frames after it"),
    "derived.homotopy_lambda_effective": Same("homotopy_lambda0"),
    "derived.rows_per_gradient_step": Same("batch_size * num_sampled_prefs",
                                           ours=lambda cfg: cfg.batch_size * cfg.num_sampled_prefs),
    "derived.target_hard_copies_every": Same("target_update_period"),
    "derived.eval_action": Same("eval_exploration", expect=lambda v, cfg: "deterministic"),
    "derived.gradient_steps_total": Same("frames - init_random_frames + 1",
                                         ours=lambda cfg: cfg.frames - cfg.init_random_frames + 1),
    "derived.evaluations": Same("frames // eval_interval", ours=lambda cfg: cfg.frames // cfg.eval_interval),
}

_ACTOR_CRITIC_INIT = Code("objectives.networks.orthogonal_init_ (actor and critics, every critic copy)")
CAPQL = {
    "init.learning_rate": Same("lr"),
    "init.tau": Same("tau"),
    "init.buffer_size": Same("buffer_size"),
    "init.net_arch": Same("hidden", expect=_net_arch),
    "init.batch_size": Same("batch_size"),
    "init.num_q_nets": Code("objectives.capql: two critics (elementwise min per objective)"),
    "init.alpha": Same("alpha"),
    "init.learning_starts": Same("init_random_frames"),
    "init.gradient_updates": Same("updates_per_batch", expect=lambda v, cfg: 0 if v == 1 else v),
    "network.policy": Same("actor_scale", expect=lambda v, cfg: "clamped_log_std"),
    "network.q_net": Code("objectives.capql: Q([obs, action, w]) -> k values"),
    "network.weight_input": Code("w at the input of the actor ([obs, w]) and the critics ([obs, action, w])"),
    "network.num_hidden_layers": Same("hidden", ours=lambda cfg: len(cfg.hidden)),
    "network.layer_norm": _NO_LN,
    "network.dropout": _NO_DROPOUT,
    "network.init": _ACTOR_CRITIC_INIT,
    "network.num_q_nets": Code("objectives.capql: two critics"),
    "network.optimizers": Same("lr", expect=lambda v, cfg: 3e-4),
    "network.log_prob": Same("capql_log_prob", expect=lambda v, cfg: "clamped"),
    "network.critic_target": Code("objectives.capql: per-objective min of the target critics minus alpha log pi"),
    "network.policy_loss": Code("objectives.capql: alpha log pi - w . min_k Q_k"),
    "derived.weight_sampling": Same("(preference_distribution, preference_resample)", expect=lambda v, cfg:
                                    ("cone", "step"), ours=lambda cfg: (cfg.preference_distribution,
                                                                        cfg.preference_resample)),
    "derived.weight_component_range": Code("preferences: cone of 22.5 degrees around the equal-weight direction "
                                           "(tests/recipes/test_mechanisms.py checks every weight's angle)"),
    "derived.behaviour_action": Same("capql_deterministic_collection", expect=lambda v, cfg: True),
    "derived.eval_action": Same("eval_exploration", expect=lambda v, cfg: "deterministic"),
}

_SAC_ALPHA = Same("alpha", expect=lambda v, cfg: 1.0)  # autotune: the scripts' 0.2 is ignored, log alpha starts at 0
#: the authors' SAC/MOSAC actor: log_std = -5 + 3.5 (tanh(x) + 1) (actor_scale="tanh_log_std"); a
#: categorical actor on discrete actions (actor_scale unused there)
_SAC_ACTOR = Same("actor_scale", expect=lambda v, cfg: "tanh_log_std" if _continuous(cfg.env_id) else cfg.actor_scale)


# the SAC agent's arguments, the same rows for the SAC baseline (``init.*``) and for every MORL/D member
# (``policy_args.*``: MOSAC); each table adds its own net_arch row (see _sac_agent)
_SAC_ARGS = {
    "buffer_size": Same("buffer_size"),
    "tau": Same("tau", expect=lambda v, cfg: None if v == 1.0 else v),
    "batch_size": Same("batch_size"),
    "learning_starts": Same("init_random_frames"),
    "policy_lr": Same("lr"),
    "q_lr": Same("q_lr"),
    "update_frequency": Same("update_frequency"),
    "target_net_freq": Same("target_update_period", expect=_target_frames,
                            ours=lambda cfg: None if cfg.tau is not None else cfg.target_update_period),
    "alpha": _SAC_ALPHA,
    "autotune": Same("learn_alpha"),
    "target_entropy_scale": Same("target_entropy_scale"),
    # algorithms/actor_critic/recipe.py delayed_actor_step: each loss alone, the temperature (alpha_loss_form)
    # after each actor step
    "policy_freq": Same("policy_freq"),
}
# the SAC agent's networks, the same rows for the SAC baseline and MORL/D
_SAC_NETWORK = {
    "network.actor": _SAC_ACTOR,
    "network.optimizers": Same("(lr, q_lr, alpha_lr, adam_eps)",
                               expect=lambda v, cfg: (3e-4, 1e-3, 1e-3, None) if _continuous(cfg.env_id)
                               else (3e-4, 3e-4, 3e-4, 1e-4),
                               ours=lambda cfg: (cfg.lr, cfg.q_lr, cfg.alpha_lr, cfg.adam_eps)),
    "network.layer_norm": _NO_LN,
    "network.dropout": _NO_DROPOUT,
    "network.init": _ACTOR_CRITIC_INIT,
}


def _sac_agent(prefix: str, *, net_arch) -> dict[str, Any]:
    """:data:`_SAC_ARGS` under ``prefix`` (``init`` / ``policy_args``) and the table's ``net_arch`` rule."""
    return {**{f"{prefix}.{k}": rule for k, rule in _SAC_ARGS.items()},
            f"{prefix}.net_arch": Same("hidden", expect=net_arch)}


SAC = {
    **_sac_agent("init", net_arch=_mario_after_cnn),
    **_SAC_NETWORK,
    "network.critic": Code("algorithms.actor_critic.sac: two critics on the scalar reward"),
    "network.num_q_nets": Code("two critics"),
    "network.training_reward": Code("transforms: the domain's original scalar reward (SPEC §4)"),
    "derived.initial_alpha": Same("alpha"),
    "derived.target_entropy": Code("objectives: -|A| (continuous) / target_entropy_scale * ln|A| (discrete)"),
    "derived.eval_uses_weight": Code("the SAC policy takes no weight"),
    "derived.eval_action": Same("eval_exploration", expect=lambda v, cfg: "random"),
}

def _morld_turns(cfg: TrainConfig, *, frames: bool = False):
    """Round robin: the turns (or frames) of each member (:func:`morl_trl.algorithms.morld.recipe.round_robin_turns`);
    concurrent: none (every member collects at every step)."""
    if cfg.morld_schedule != "round_robin":
        return "concurrent"
    from morl_trl.algorithms.morld.recipe import round_robin_turns

    turns = round_robin_turns(cfg.frames, cfg.exchange_every, cfg.pop_size)
    return [t * cfg.exchange_every for t in turns] if frames else turns


MORLD = {
    "init.scalarization_method": Code("algorithms.morld: weighted sum w . Q"),
    "init.evaluation_mode": Code("SER: discounted vector returns, as the evaluator computes them"),
    "init.policy_name": Code("algorithms.morld: MOSAC on continuous actions, discrete MOSAC otherwise"),
    "init.policy_args": NotApplicable("the members' arguments: one row each under policy_args"),
    "init.pop_size": Same("pop_size"),
    "init.exchange_every": Same("exchange_every"),
    "init.neighborhood_size": Code("algorithms.morld (PSA: the nearest archive neighbour)"),
    "init.dist_metric": Code("algorithms.morld (squared Euclidean distance)"),
    "init.shared_buffer": Code("algorithms.morld: one buffer shared by the members"),
    "init.sharing_mechanism": NotApplicable("[] in every script: no parameter sharing"),
    "init.update_passes": Same("morld_update_passes"),  # algorithms.morld.MORLDAgent: catch-up after each exchange
    "init.weight_init_method": Code("preferences.equally_spaced_weights (the authors' 'uniform')"),
    "init.weight_adaptation_method": Same("weight_adaptation", expect=lambda v, cfg: "psa" if v == "PSA" else "none"),
    "init.asymmetric": NotApplicable("False in every script"),
    "init.history_type": NotApplicable("None in every script"),
    "policy_args.env": Code("algorithms.morld: round robin, the acting member steps the training env (num_envs = 1 "
                            "sub-env, reset at each exchange); morld_schedule='concurrent': every member steps its "
                            "own sub-envs of one batched env"),
    "policy_args.weights": Code("preferences.equally_spaced_weights(k, pop_size, seed)"),
    "policy_args.asymmetric": NotApplicable("False in every script"),
    "policy_args.scalarization": Code("algorithms.morld: w . Q"),
    **_sac_agent("policy_args", net_arch=_net_arch),
    "policy_args.gamma": Same("gamma", ours=_gamma),
    "policy_args.id": NotApplicable("a member's index (no setting)"),
    "policy_args.log": NotApplicable("logging switch"),
    "policy_args.seed": _SEED,
    "policy_args.parent_rng": NotApplicable("RNG plumbing; one `seed` drives every generator here"),
    "policy_args.device": NotApplicable("`device` (the hardware; no effect on results)"),
    "train.num_eval_episodes_for_front": Same("morld_eval_episodes"),  # algorithms.morld.MORLDAgent.evaluate_members
    **_SAC_NETWORK,
    "network.critic": Code("objectives.population: vector critics, trained on w . Q"),
    "network.num_q_nets": Code("two critics per member"),
    "network.critic_loss": Code("objectives.population: MSE of scalarised values against the min of the targets"),
    "derived.eval_action": Code("algorithms.morld.ArchiveSnapshotRouter: the nearest archive snapshot, sampled "
                                "actions"),
    # round robin (algorithms.morld; tests/recipes/test_morld_round_robin.py): turns of exchange_every frames
    "derived.exchanges_per_member": Same("round_robin_turns(frames, exchange_every, pop_size)",
                                         ours=lambda cfg: _morld_turns(cfg)),
    "derived.own_env_steps_per_member": Same("exchange_every * round_robin_turns(...)",
                                             ours=lambda cfg: _morld_turns(cfg, frames=True)),
    # each catch-up update is the member's update(): critic + (the shared step even) actor/alpha + target step
    "derived.updates_for_non_active_member_per_exchange": Same(
        "morld_update_passes", expect=lambda v, cfg: int(v.split()[0]),
        ours=lambda cfg: cfg.morld_update_passes if cfg.morld_schedule == "round_robin" else 0),
    "derived.psa_rule": Code("algorithms.morld.psa_weights (tests/recipes/test_morld.py)"),
    "derived.archive_eval_episodes_per_exchange": Same("pop_size * morld_eval_episodes",
                                                       ours=lambda cfg: cfg.pop_size * cfg.morld_eval_episodes),
    "derived.env_reset_at_each_exchange": Same("morld_schedule", expect=lambda v, cfg: "round_robin" if v else
                                               "concurrent"),  # algorithms.morld: MORLDAgent.env_reset_due
}

PCN = {
    "init.scaling_factor": Same("pcn_scaling_factor", expect=lambda v, cfg: tuple(v),
                                ours=lambda cfg: cfg.pcn_scaling_factor or (0.1,) * (len(_domain(cfg).objective_names)
                                                                                     + 1)),
    "init.learning_rate": Same("lr"),
    "init.batch_size": Same("batch_size"),
    "init.net_arch": Same("hidden", expect=_net_arch),
    "init.noise": Same("pcn_noise"),
    "init.max_return": Same("pcn_max_return", expect=lambda v, cfg: tuple(float(x) for x in v),
                            ours=lambda cfg: cfg.pcn_max_return or (100.0,) * len(_domain(cfg).objective_names)),
    "init.model_class": NotApplicable("None: the default PCN model"),
    "train.num_er_episodes": Same("pcn_er_episodes"),
    "train.num_step_episodes": Same("pcn_step_episodes"),
    "train.num_model_updates": Same("pcn_model_updates"),
    "train.max_buffer_size": Same("pcn_buffer_episodes"),
    "network.state_embedding": Code("objectives.pcn.PCNNetwork: Linear(obs, hidden[0]) + Sigmoid (the CNN first on "
                                    "pixels)"),
    "network.command_embedding": Code("objectives.pcn.PCNNetwork: scaled command -> Linear(k + 1, hidden[0]) + "
                                      "Sigmoid"),
    "network.combine": Code("objectives.pcn.PCNNetwork: elementwise product"),
    "network.head": Code("objectives.pcn.PCNNetwork: ReLU layers of hidden[1:], then the output"),
    "network.loss": Code("objectives.pcn.PCNLoss (cross-entropy / MSE)"),
    "network.train_action": Code("algorithms.pcn: sampled from the softmax / prediction + N(0, pcn_noise) per "
                                 "dimension"),
    "network.eval_action": Code("algorithms.pcn: argmax / the noiseless prediction"),
    "network.weight_input": Code("PCN is conditioned on its command, not on weights"),
    "network.num_hidden_layers": Same("hidden", ours=lambda cfg: len(cfg.hidden)),
    "network.layer_norm": _NO_LN,
    "network.dropout": _NO_DROPOUT,
    "network.init": Code("objectives.pcn (orthogonal_init_)"),
    "network.optimizer": Same("lr", expect=lambda v, cfg: 3e-4),
    "derived.returns_stored": Code("data.episode_replay: discounted returns-to-go"),
    "derived.command_choice": Code("algorithms.pcn (crowding-penalised top episodes, non-dominated, random pick)"),
    "derived.eval_commands": Code("algorithms.pcn: top-episode commands, updated after every step"),
    "derived.command_update_in_episode": Code("transforms.command: desired return -= r, horizon - 1"),
    "derived.updates_per_loop_per_episodes": Same("(pcn_model_updates, pcn_step_episodes)",
                                                  expect=lambda v, cfg: (50, 10),
                                                  ours=lambda cfg: (cfg.pcn_model_updates, cfg.pcn_step_episodes)),
}

_PPO = {
    "num_envs": Same("pgmorl_envs_per_member"),
    "steps_per_iteration": Same("frames_per_batch / num_envs", ours=lambda cfg: cfg.frames_per_batch // cfg.num_envs),
    "num_minibatches": Same("pgmorl_minibatches"),
    "update_epochs": Same("pgmorl_epochs"),
    "learning_rate": Same("lr"),
    "anneal_lr": Code("algorithms.pgmorl: a constant learning rate"),
    "clip_coef": Same("pgmorl_clip"),
    "ent_coef": Code("algorithms.pgmorl: ClipPPOLoss(entropy_bonus=False)"),
    "vf_coef": Code("algorithms.pgmorl: value loss 0.5 * 0.5 * max(unclipped, clipped)"),
    "clip_vloss": Code("algorithms.pgmorl: ClipPPOLoss(clip_value=pgmorl_clip)"),
    "max_grad_norm": Same("max_grad_norm"),
    "norm_adv": Code("algorithms.pgmorl: the scalarised advantage standardised per member and minibatch"),
    "target_kl": NotApplicable("None: no early stop on KL"),
    "gae": Code("objectives.pgmorl.vector_gae"),
    "gae_lambda": Same("pgmorl_gae_lambda"),
    "net_arch": Same("hidden", expect=_net_arch),
}
PGMORL = {
    **{f"init.{k}": v for k, v in _PPO.items()},
    **{f"moppo.{k}": v for k, v in _PPO.items() if k not in ("num_envs", "net_arch")},
    "init.origin": Same("ref_point", expect=lambda v, cfg: tuple(v), ours=lambda cfg: _ref(cfg)),
    "init.pop_size": Same("pgmorl_pop"),
    "init.warmup_iterations": Same("pgmorl_warmup"),
    "init.evolutionary_iterations": Same("pgmorl_evo_iterations"),
    "init.num_weight_candidates": Code("recipes.pgmorl_evolution: candidates from generate_weights(delta/2)"),
    "init.num_performance_buffer": Same("pgmorl_num_buffers"),
    "init.performance_buffer_size": Same("pgmorl_buffer_size"),
    "init.min_weight": Code("recipes.pgmorl_evolution: weights on the simplex"),
    "init.max_weight": Code("recipes.pgmorl_evolution: weights on the simplex"),
    "init.delta_weight": Same("pgmorl_delta_weight"),
    "init.sparsity_coef": Same("pgmorl_sparsity", expect=lambda v, cfg: float(v)),
    "init.generalization_hyperparams": NotApplicable("the evaluator's arguments: the evaluator rows"),
    "moppo.id": NotApplicable("a member's index (no setting)"),
    "moppo.networks": Code("objectives.pgmorl (batched population actor and critic)"),
    "moppo.weights": Code("algorithms.pgmorl: warm-up weights, then the task selection's"),
    "moppo.envs": Code("algorithms.pgmorl: every member steps its own sub-envs of one batched env"),
    "moppo.log": NotApplicable("logging switch"),
    "moppo.gamma": Same("gamma", ours=_gamma),
    "moppo.device": NotApplicable("`device` (the hardware; no effect on results)"),
    "moppo.seed": _SEED,
    "moppo.rng": NotApplicable("RNG plumbing; one `seed` drives every generator here"),
    "network.actor_mean": Code("objectives.pgmorl: Tanh MLP (orthogonal, gain sqrt 2 hidden, 0.01 output)"),
    "network.actor_logstd": Code("objectives.pgmorl: a state-independent log-std initialised to 0"),
    "network.critic": Code("objectives.pgmorl: Tanh MLP -> k values (orthogonal, gain sqrt 2 hidden, 1 output)"),
    "network.advantage": Code("objectives.pgmorl.vector_gae, scalarised with the member's weight"),
    "network.optimizers": Code("algorithms.pgmorl: Adam(lr, eps=1e-5) per member"),
    "network.optimizer": Code("algorithms.pgmorl: Adam(lr, eps=1e-5)"),
    "network.num_hidden_layers": Same("hidden", ours=lambda cfg: len(cfg.hidden)),
    "network.layer_norm": _NO_LN,
    "network.dropout": _NO_DROPOUT,
    "network.init": Code("objectives.pgmorl.ppo_population_mlp (orthogonal, gain sqrt 2 hidden, 1 critic output, 0.01 "
                         "actor output, zero biases)"),
    "derived.training_env_wrappers": Code("algorithms.pgmorl: VecNorm observations and rewards, clipped at +-10"),
    # algorithms.pgmorl.PGMORLAgent.reseed_env (tests/recipes/test_pgmorl.py)
    "derived.vector_env_reset_each_iteration": Same("(pgmorl_reset_each_iteration, pgmorl_reseed_each_iteration)",
                                                    expect=lambda v, cfg: (True, True),
                                                    ours=lambda cfg: (cfg.pgmorl_reset_each_iteration,
                                                                      cfg.pgmorl_reseed_each_iteration)),
    "derived.global_step_per_iteration": Same("frames_per_batch / pgmorl_pop",
                                              ours=lambda cfg: cfg.frames_per_batch // cfg.pgmorl_pop),
    "derived.ppo_batch": Same("frames_per_batch / pgmorl_pop", ours=lambda cfg: cfg.frames_per_batch // cfg.pgmorl_pop),
    "derived.ppo_minibatch": Same("frames_per_batch / pgmorl_pop / pgmorl_minibatches",
                                  ours=lambda cfg: cfg.frames_per_batch // cfg.pgmorl_pop // cfg.pgmorl_minibatches),
    "derived.warmup_weights": Code("recipes.pgmorl_evolution.generate_weights(delta_weight)[:pop]"),
    "derived.evolution_candidate_weights": Code("recipes.pgmorl_evolution.generate_weights(delta_weight / 2)"),
    "derived.actual_env_steps": Code("algorithms.pgmorl: one member's frames count against the budget (every member "
                                     "steps its sub-envs)"),
    "derived.member_evaluation": Code("algorithms.pgmorl (5 sampled episodes per member on the DR env)"),
    "derived.eval_action": Code("algorithms.pgmorl: the nearest archive snapshot, sampled actions, raw observations "
                                "(pgmorl_eval_obs='raw')"),
}

_GPI_DISCRETE_NET = Code("objectives.gpi.GPIQNetwork (state x weight features, [Linear, Dropout, LayerNorm, ReLU] "
                         "blocks)")
GPI = {
    **_DQN_ROWS,
    "init.net_arch": Same("hidden", expect=_net_arch),
    "init.num_nets": Same("gpi_num_nets"),
    "init.num_q_nets": Same("gpi_num_nets"),
    "init.batch_size": Same("batch_size"),
    "init.learning_starts": Same("init_random_frames"),
    "init.gradient_updates": Same("gpi_gradient_updates"),
    "init.max_grad_norm": Same("max_grad_norm", expect=_NONE),
    "init.use_gpi": Code("algorithms.gpi: GPI over the weight support while acting and evaluating"),
    "init.dyna": Code("algorithms.gpi: the dynamics model and rollouts for gpi_pd only",
                      open=None),
    "init.gpi_pd": Code("algorithms.gpi (gpi_pd: priorities from the GPI target)"),
    "init.per": Same("prioritized"),
    "init.alpha_per": Same("per_alpha"),
    "init.alpha": Same("per_alpha"),
    "init.min_priority": Same("gpi_min_priority"),
    "init.drop_rate": Same("gpi_dropout"),
    "init.layer_norm": Same("gpi_layer_norm"),
    "init.delay_policy_update": Same("gpi_policy_delay"),
    "init.policy_noise": Same("gpi_policy_noise"),
    "init.noise_clip": Same("gpi_noise_clip"),
    "train.timesteps_per_iter": Same("gpi_iteration_frames"),
    "train.weight_selection_algo": Code("algorithms.gpi: GPI-LS corner weights (linear support)"),
    "train.num_eval_episodes_for_front": Same("gpi_front_episodes"),
    "train_iteration.weight": Code("algorithms.gpi: the next corner weight"),
    "train_iteration.weight_support": Code("algorithms.gpi: CCS support + top-4 queued corners + w"),
    # (true: the first episode of an iteration is w's, later ones draw from M: SPEC §6; ours "w", the recipe's reset
    # at begin_iteration; false would act with w throughout, which no option of ours does)
    "train_iteration.change_w_every_episode": Same("gpi_first_episode", expect=lambda v, cfg: "w" if v else "(none)"),
    "train_iteration.change_weight_every_episode": Same("gpi_first_episode", expect=lambda v, cfg: "w" if v else "(none)"),
    "train_iteration.eval_freq": Same("eval_interval"),
    "train_iteration.reset_learning_starts": _ONE_CALL,
    "train_iteration.reset_num_timesteps": _ONE_CALL,
    "train_iteration.total_timesteps": Same("gpi_iteration_frames"),
    "train_iteration.test_generalization": NotApplicable("always: every run here is evaluated by the generalization "
                                                         "evaluator"),
    "train_iteration.verbose": NotApplicable("console verbosity"),
    "network.q_net": _GPI_DISCRETE_NET,
    "network.combine": _GPI_DISCRETE_NET,
    "network.state_features": _GPI_DISCRETE_NET,
    "network.weight_features": _GPI_DISCRETE_NET,
    "network.head": _GPI_DISCRETE_NET,
    "network.q_output": _GPI_DISCRETE_NET,
    "network.loss": Code("objectives.gpi (LAP/Huber, min_priority threshold)"),
    "network.policy": Code("objectives.gpi.GPIActor (tanh policy on [obs, w])"),
    "network.critic": Code("objectives.gpi.GPIVectorCritic (Dropout and LayerNorm per hidden layer)"),
    "network.critic_loss": Code("objectives.gpi (MSE; target of the critic with the smaller w . Q)"),
    "network.policy_loss": Code("objectives.gpi (-w . mean_i Q_i, every gpi_policy_delay steps)"),
    "network.num_hidden_layers": Same("hidden", ours=lambda cfg: len(cfg.hidden)),
    "network.num_q_nets": Same("gpi_num_nets"),
    "network.layer_norm": Same("gpi_layer_norm", expect=lambda v, cfg: bool(v) if isinstance(v, bool) else True),
    "network.dropout": Same("gpi_dropout", expect=lambda v, cfg: float(v) if not isinstance(v, str) else 0.01),
    "network.init": Code("objectives.gpi (orthogonal, zero biases)"),
    "network.optimizer": Same("lr", expect=lambda v, cfg: 3e-4),
    "network.optimizers": Same("lr", expect=lambda v, cfg: 3e-4),
    "network.eval_action": Code("algorithms.gpi: greedy GPI action"),
    "network.weight_input": Code("objectives.gpi: the weight is an input of every Q-network (and actor)"),
    "derived.epsilon_schedule": Code("training.agent: random actions before init_random_frames, then epsilon linear "
                                     "from eps_start to eps_end over the eps_frames after it"),
    "derived.ccs_values": Code("algorithms.gpi: Monte-Carlo returns of the GPI policy (gpi_front_episodes each)"),
    "derived.eval_gpi_indexing_note": Same("gpi_eval_conditioning", expect=lambda v, cfg: "authors"),
    "derived.train_action": Code("algorithms.gpi: pi(s, w) + clipped Gaussian noise"),
    "derived.eval_action": Code("algorithms.gpi: greedy GPI over the support"),
    # (the batch doubled, its first half under the iteration's w; gpi_update_weight="episode", MB's reading, differs)
    "derived.rows_per_gradient_step": Same(
        "2 * batch_size, first half under gpi_update_weight",
        ours=lambda cfg: 2 * cfg.batch_size if cfg.gpi_update_weight == "iteration"
        else f"{2 * cfg.batch_size}, the first half under the episode's weight"),
    "derived.gradient_steps_per_env_step": Same("gpi_gradient_updates"),
    "derived.iterations": Same("frames // gpi_iteration_frames", ours=lambda cfg: cfg.frames // cfg.gpi_iteration_frames),
}
GPI_PD = {
    **GPI,
    "init.dynamics_normalize_inputs": Same("gpi_dynamics_normalize"),
    "init.dynamics_uncertainty_threshold": Same("gpi_uncertainty_threshold"),
    "init.dynamics_min_uncertainty": Same("gpi_uncertainty_threshold"),
    "init.dynamics_train_freq": Same("gpi_dynamics_train_freq"),
    "init.dynamics_rollout_len": Same("gpi_dynamics_rollout_len"),
    "init.dynamics_rollout_starts": Same("gpi_dynamics_rollout_starts"),
    "init.dynamics_rollout_freq": Same("gpi_dynamics_rollout_freq"),
    "init.dynamics_rollout_batch_size": Same("gpi_dynamics_rollout_batch"),
    "init.dynamics_buffer_size": Same("gpi_dynamics_buffer"),
    "init.dynamics_net_arch": Same("gpi_dynamics_hidden", expect=_net_arch),
    "init.dynamics_lr": Same("gpi_dynamics_lr"),
    "init.dynamics_max_grad_norm": Same("gpi_dynamics_max_grad_norm", expect=_NONE),
    "init.dynamics_ensemble_size": Same("gpi_dynamics_ensemble"),
    "init.dynamics_num_elites": Same("gpi_dynamics_elites"),
    "init.dynamics_max_logvar_scale": Same("gpi_dynamics_max_logvar"),
    "init.dynamics_min_logvar_scale": Code("objectives.dynamics (log-variance bounds)"),
    "init.real_ratio": Same("gpi_real_ratio"),
    "init.dynamics_real_ratio": Same("gpi_real_ratio"),
    "network.dynamics_model": Code("objectives.dynamics (ensemble of Gaussian MLPs, elites by holdout MSE)"),
    "network.termination_fn": Code("objectives.dynamics.model_termination (gpi_model_termination='authors')"),
    "derived.rollout_start_states": Code("algorithms.gpi: start states drawn from the real buffer by PER priority"),
    "derived.first_model_fit_step": Code("algorithms.gpi (the first fit at gpi_dynamics_train_freq)"),
    "derived.first_rollout_step": Code("algorithms.gpi (the first rollout at gpi_dynamics_rollout_starts)"),
    "derived.real_samples_per_batch": Same("batch_size * gpi_real_ratio",
                                           ours=lambda cfg: int(cfg.batch_size * cfg.gpi_real_ratio)),
}
# GPI-LS: the dynamics arguments exist in the authors' class but are off (dyna=False)
for _k in list(GPI_PD):
    if _k.startswith("init.dynamics_") or _k in ("init.real_ratio",):
        GPI[_k] = NotApplicable("GPI-LS has no dynamics model (dyna=False): the argument is unused")

RULES = {"envelope": ENVELOPE, "capql": CAPQL, "gpi_ls": GPI, "gpi_pd": GPI_PD, "morld_sb": MORLD,
         "morld_sb_psa": MORLD, "pcn": PCN, "pgmorl": PGMORL, "sac": SAC}
_DERIVED = NotApplicable("a number derived from the settings above, each compared in its own row")


# ---------------------------------------------------------------------- the comparison
@cache
def _load() -> dict[str, Any]:
    with RECORD_PATH.open("rb") as f:
        return tomllib.load(f)


def record() -> dict[str, Any]:
    """The authors' record (the shipped copy of ``hyperparameters.toml``), ``{method: {domain: table}}``."""
    return {k: v for k, v in _load().items() if k != "meta"}


def record_meta() -> dict[str, Any]:
    """The record's ``[meta]`` table (repository, commit, number of pairs)."""
    return dict(_load()["meta"])


def pairs() -> list[tuple[str, str]]:
    """Every ``(our algorithm, training env id)`` the authors ran, in the record's order."""
    return [(METHODS[m], RECORD_DOMAINS[d]) for m, domains in record().items() for d in domains]


def _settings(table: dict[str, Any]):
    for k, v in table.items():
        if isinstance(v, dict):
            for kk, vv in v.items():
                yield f"{k}.{kk}", vv
        else:
            yield k, v


def rule_for(method: str, setting: str):
    """The rule of one setting of the record (``None`` when nothing maps it: the all-pairs test fails)."""
    rule = RULES[method].get(setting, COMMON.get(setting))
    if rule is None and setting.startswith("derived."):
        return _DERIVED
    return rule


def _normal(v):
    if v == "None":
        return None
    if isinstance(v, list):
        return tuple(_normal(x) for x in v)
    if isinstance(v, tuple):
        return tuple(_normal(x) for x in v)
    return v


def _equal(a, b) -> bool:
    a, b = _normal(a), _normal(b)
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b or a == b and type(a) is type(b)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=0.0)
    return a == b


def _method_of(algo: str) -> str:
    for method, ours in METHODS.items():
        if ours == algo:
            return method
    raise ValueError(f"the authors did not run {algo!r}; the record's algorithms: {sorted(set(METHODS.values()))}")


def compare(algo: str, env_id: str, cfg: TrainConfig | None = None) -> list[Row]:
    """One :class:`Row` per setting of the record for ``(algo, env_id)``, comparing ``cfg``
    (default: the resolved defaults, ``resolve_config(algo, env_id)``)."""
    method = _method_of(algo)
    domains = {ours: name for name, ours in RECORD_DOMAINS.items()}
    from morl_trl.envs import domain_of

    train_id = domain_of(env_id).train_id
    domain = domains.get(train_id)
    if domain is None or domain not in record()[method]:
        ran = [RECORD_DOMAINS[d] for d in record()[method]]
        raise ValueError(f"the authors did not run {algo} on {env_id}; they ran it on {ran}")
    cfg = resolve_config(algo, train_id) if cfg is None else cfg
    rows = []
    for setting, value in _settings(record()[method][domain]):
        rule = rule_for(method, setting)
        rows.append(_row(method, train_id, setting, value, rule, cfg))
    return rows


def _row(method: str, env_id: str, setting: str, value: Any, rule, cfg: TrainConfig) -> Row:
    def row(key, ours, status):
        return Row(METHODS[method], env_id, setting, value, key, ours, status)

    if rule is None:
        return row("", None, "unmapped: no rule maps this setting (morl_trl.recipes.fidelity)")
    if isinstance(rule, NotApplicable):
        return row("", None, f"not applicable: {rule.reason}")
    if isinstance(rule, Code):
        gap = rule.open(env_id) if callable(rule.open) else rule.open
        return row(f"code: {rule.where}", None, f"differs: {gap}" if gap else "same")
    ours = rule.ours(cfg) if getattr(rule, "ours", None) is not None else (
        getattr(cfg, rule.key) if rule.key is not None else None)
    if isinstance(rule, Deliberate):
        return row(rule.key or "", ours, f"deliberate: {rule.reason}")
    expected = rule.expect(value, cfg) if rule.expect is not None else value
    if _equal(expected, ours):
        return row(rule.key, _normal(ours), "same")
    return row(rule.key, _normal(ours), f"differs: ours {_normal(ours)!r}, the authors' {_normal(expected)!r}")


def open_differences() -> list[Row]:
    """Every known difference not fixed yet (``Code(open=...)`` rows), over every pair of the record."""
    return [r for algo, env in pairs() for r in compare(algo, env) if r.status.startswith("differs")]


def _short(v: Any, width: int = 60) -> str:
    text = "" if v is None else (v if isinstance(v, str) else repr(v))
    return text if len(text) <= width else text[: width - 3] + "..."


def format_rows(rows: list[Row]) -> str:
    """The rows as an aligned text table (``morl-trl config ALGO ENV --compare-authors``)."""
    head = ("setting (the authors)", "their value", "our key", "our value", "status")
    cells = [head] + [(r.setting, _short(r.authors, 40), _short(r.our_key, 40), _short(r.ours, 30), r.status)
                      for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(4)]
    lines = ["  ".join(c[i].ljust(widths[i]) for i in range(4)) + "  " + c[4] for c in cells]
    counts = {}
    for r in rows:
        counts[r.status.split(":")[0]] = counts.get(r.status.split(":")[0], 0) + 1
    lines.append("")
    lines.append(", ".join(f"{n} {k}" for k, n in sorted(counts.items())) + f" ({len(rows)} settings)")
    return "\n".join(lines)


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def markdown() -> str:
    """``docs/fidelity.md``: every pair's table and the open differences (regenerate with
    ``python -m morl_trl.recipes.fidelity docs/fidelity.md``)."""
    lines = ["# Fidelity: our defaults beside the authors' record", "",
             "<!-- generated by `python -m morl_trl.recipes.fidelity docs/fidelity.md`; do not edit "
             "(tests/recipes/test_fidelity.py checks it is up to date) -->", "",
             "Every setting of every (method, domain) the authors ran (`hyperparameters.toml`, shipped as "
             "`morl_trl/recipes/data/authors_hyperparameters.toml`), beside our default: `same`, "
             "`deliberate: <reason>`, `not applicable: <reason>`, or `differs: <what>` for a known difference "
             "not fixed yet (listed first). Rows identical on every domain of a method are shown once (domain "
             "`all`). One pair at a time: `morl-trl config ALGO ENV_ID --compare-authors` "
             "(`--format json`). The mapping lives in `morl_trl/recipes/fidelity.py`.", ""]
    opened = open_differences()
    lines += ["## Known open differences", "", f"{len(opened)} rows.", "", "| algorithm | domain | setting | what |",
              "|---|---|---|---|"]
    lines += [f"| {r.method} | {r.env_id} | `{r.setting}` | {_cell(r.status[len('differs: '):])} |" for r in opened]
    by_method: dict[str, list[Row]] = {}
    for algo, env in pairs():
        by_method.setdefault(algo, []).extend(compare(algo, env))
    for algo, rows in by_method.items():
        envs = list(dict.fromkeys(r.env_id for r in rows))
        lines += ["", f"## {algo}", "", f"Domains: {', '.join(envs)}.", "",
                  "| setting | domain | the authors | our key | ours | status |", "|---|---|---|---|---|---|"]
        groups: dict[str, list[Row]] = {}
        for r in rows:
            groups.setdefault(r.setting, []).append(r)
        for setting, group in groups.items():
            keyed = {(repr(r.authors), repr(r.ours), r.status, r.our_key) for r in group}
            shown = [group[0]] if len(keyed) == 1 and len(group) == len(envs) else group
            for r in shown:
                dom = "all" if shown is not group else r.env_id
                lines.append(f"| `{setting}` | {dom} | {_cell(_short(r.authors))} | {_cell(_short(r.our_key, 50))} | "
                             f"{_cell(_short(r.ours, 40))} | {_cell(r.status)} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    import sys

    text = markdown()
    if len(sys.argv) > 1:
        Path(sys.argv[1]).write_text(text)
    else:
        print(text, end="")
