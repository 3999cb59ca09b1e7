"""Every configuration key, defined once: its section, type, meaning and check.

Which keys an algorithm has, and their defaults, are in that algorithm's module
(:mod:`morl_trl.algorithms.envelope.config`, ...); the shared sections are in
:mod:`morl_trl.recipes.config.sections`. A key's ``check`` returns ``None`` for a valid value and
otherwise a description of the valid values (the error names the key, the value and that).

Example:
    >>> KEYS["lr"].check(0.0)
    'a number in (0.0, 1.0]'
    >>> KEYS["batch_size"].section
    'replay_buffer'
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

__all__ = ["coerce_values", "ALGORITHMS", "Key", "KEYS", "KEY_ALIASES", "NOT_SET", "LOGGERS", "SHARED_SECTIONS",
           "unknown_keys_message"]

ALGORITHMS = ("envelope", "capql", "mosac", "mosac_discrete", "morld", "morld_psa", "sac", "pcn", "pgmorl",
              "gpi_ls", "gpi_pd")
#: the sections every algorithm has (the rest of a config is the algorithm's own table)
SHARED_SECTIONS = ("run", "env", "eval", "logging", "compute")
LOGGERS = ("csv", "tensorboard", "wandb", "none")
#: a key's ``inert`` when it has none: reading the key on an algorithm without it is an error
NOT_SET = object()


@dataclass(frozen=True)
class Key:
    """One configuration key.

    ``section``: where it is printed (a shared section, or a group of the algorithm's table);
    ``inert``: the value that means "this mechanism is off", which shared code reads when the
    algorithm has no such key (e.g. ``prioritized`` for PCN is ``False``).
    """

    section: str  # its group in error messages and in an algorithm's table (the names of earlier versions)
    type: str
    help: str
    check: Callable[[Any], str | None] | None = None
    inert: Any = NOT_SET

    def problem(self, value: Any) -> str | None:
        return None if self.check is None else self.check(value)


# ---------------------------------------------------------------------- value checks
def _int(lo: int, hi: float = math.inf, *, optional: bool = False):
    def check(v):
        if v is None and optional:
            return None
        if isinstance(v, bool) or not isinstance(v, int):
            return f"an int in [{lo}, {hi}]" + (" or null" if optional else "")
        if not lo <= v <= hi:
            return f"an int in [{lo}, {hi}]" + (" or null" if optional else "")
        return None

    return check


def _float(lo: float, hi: float, *, optional: bool = False, open_low: bool = False):
    interval = f"{'(' if open_low else '['}{lo}, {hi}]"

    def check(v):
        if v is None and optional:
            return None
        what = f"a number in {interval}" + (" or null" if optional else "")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            return what
        if v < lo or v > hi or (open_low and v == lo):
            return what
        return None

    return check


def _bool(v):
    return None if isinstance(v, bool) else "true or false"


def _choice(options):
    def check(v):
        return None if v in options else f"one of {list(options)}"

    return check


def _str(optional: bool = False):
    def check(v):
        if v is None and optional:
            return None
        return None if isinstance(v, str) and v else "a non-empty string" + (" or null" if optional else "")

    return check


#: the widest hidden layer a config may ask for, and the most weights between its hidden layers
#: (checked before anything is allocated: a config from elsewhere may ask for terabytes)
MAX_HIDDEN_WIDTH = 65_536
MAX_HIDDEN_WEIGHTS = 2**28  # (1 GiB of float32 per network)


def _hidden(v):
    ok = isinstance(v, tuple) and len(v) > 0 and all(
        isinstance(x, int) and not isinstance(x, bool) and 1 <= x <= MAX_HIDDEN_WIDTH for x in v)
    if ok and sum(a * b for a, b in zip(v, v[1:])) > MAX_HIDDEN_WEIGHTS:
        ok = False
    return None if ok else (f"a non-empty list of ints in [1, {MAX_HIDDEN_WIDTH:,}] (hidden layer widths), e.g. "
                            f"[256, 256], with at most {MAX_HIDDEN_WEIGHTS:,} weights between consecutive layers")


def _floats(v):
    if v is None:
        return None
    ok = isinstance(v, tuple) and len(v) > 0 and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)
    return None if ok else "a non-empty list of finite numbers, or null"


def _contexts(v):
    if v is None:
        return None
    ok = isinstance(v, tuple) and len(v) > 0 and all(isinstance(x, str) for x in v)
    return None if ok else "a non-empty list of env ids of the training domain, or null for its evaluation suite"


def _modules(v):
    ok = isinstance(v, tuple) and all(isinstance(x, str) and x for x in v)
    return None if ok else "a list of importable module names (e.g. ['my_pkg.domains'])"


def _device(v):
    import torch

    if not isinstance(v, str) or not v:
        return "a torch device string such as 'cpu' or 'cuda'"
    try:
        dev = torch.device(v)
    except (RuntimeError, ValueError):
        return "a torch device string such as 'cpu', 'cuda' or 'cuda:0'"
    if dev.type == "cpu":
        return None
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            return "'cpu' (no CUDA device is available on this machine)"
        if dev.index is not None and dev.index >= torch.cuda.device_count():
            return f"'cuda' or 'cuda:0'..'cuda:{torch.cuda.device_count() - 1}'"
        return None
    return "'cpu' or 'cuda' (training runs on those)"


# fmt: off
KEYS: dict[str, Key] = {
    'algo': Key('run', 'str', 'algorithm', _choice(ALGORITHMS)),
    'env_id': Key('run', 'str', 'training env id (a *DR-* id trains under domain randomization)', _str()),
    'seed': Key('run', 'int', 'one seed for contexts, preferences, networks and evaluation (below 2**32: NumPy)',
                _int(0, 2**32 - 1)),
    'device': Key('run', 'str', 'torch device of envs, replay buffer and networks', _device),
    'num_threads': Key('run', 'int', "torch CPU threads (1 avoids OpenMP oversubscription with small nets; 0: torch's default)", _int(0, 4096)),
    'run_dir': Key('run', 'str | None', 'where the run is written (null: runs/<algo>_<env>_s<seed>_<time>)', _str(optional=True)),
    'checkpoint_interval': Key('run', 'int', 'frames between checkpoints', _int(1)),
    'keep_checkpoints': Key('run', 'int', 'checkpoints kept (the newest holds the replay buffer, the older ones only the state)', _int(1)),
    'logger': Key('run', 'str', 'TorchRL logger', _choice(LOGGERS)),
    'progress': Key('run', 'bool', 'show a progress bar', _bool),
    'num_envs': Key('env', 'int', 'sub-environments stepped together', _int(1, 1 << 20)),
    'history_len': Key('env', 'int', 'StateActionHistory length (the paper: 2 for LunarLander and MuJoCo)', _int(0, 64)),
    'gamma': Key('env', 'float | None', "discount (null: the domain's evaluation discount)", _float(0.0, 1.0, optional=True)),
    'preference_distribution': Key('env', 'str', "training preferences: 'dirichlet' (uniform on the simplex), 'gaussian' (|N(0,I)| normalised; the authors' Envelope) or 'cone' (22.5 degrees around the equal-weight direction; the authors' CAPQL)", _choice(("dirichlet", "gaussian", "cone")), inert="dirichlet"),
    'preference_resample': Key('env', 'str', "a new training preference per 'episode' or per 'step' (the authors' CAPQL: step)", _choice(("episode", "step")), inert="episode"),
    'frames': Key('collector', 'int', 'environment frames to train for', _int(1)),
    'frames_per_batch': Key('collector', 'int', 'frames per collector batch (all sub-envs)', _int(1), inert=64),
    'init_random_frames': Key('collector', 'int', "uniformly random actions before learning starts (MORL-Baselines' learning_starts)", _int(0), inert=0),
    'buffer_size': Key('replay_buffer', 'int', 'transitions kept', _int(1), inert=1_000_000),
    'batch_size': Key('replay_buffer', 'int', 'transitions per update', _int(1), inert=128),  # (the unused buffer of PGMORL)
    'prioritized': Key('replay_buffer', 'bool', "prioritized replay (keyed by the loss's td_error)", _bool, inert=False),
    'per_alpha': Key('replay_buffer', 'float', 'priority exponent', _float(0.0, 1.0), inert=0.6),
    'per_beta': Key('replay_buffer', 'float', 'importance-sampling exponent', _float(0.0, 1.0), inert=0.4),
    'per_importance_weights': Key('replay_buffer', 'bool', "weight the loss by PER's importance-sampling weights (the authors' Envelope: false)", _bool, inert=True),
    'lr': Key('optim', 'float', 'Adam learning rate', _float(0.0, 1.0, open_low=True)),
    'q_lr': Key('optim', 'float | None', "critics' Adam learning rate (null: lr; the authors' SAC and MOSAC: 1e-3 on continuous actions)", _float(0.0, 1.0, optional=True, open_low=True), inert=None),
    'alpha_lr': Key('optim', 'float | None', "temperature's Adam learning rate (null: lr; the authors' SAC and MOSAC: q_lr)", _float(0.0, 1.0, optional=True, open_low=True), inert=None),
    'adam_eps': Key('optim', 'float | None', "Adam's eps (null: torch's 1e-8; the authors' discrete SAC and MOSAC: 1e-4)", _float(0.0, 1.0, optional=True, open_low=True), inert=None),
    'updates_per_batch': Key('optim', 'int', 'gradient updates per collected batch (0: one per frame)', _int(0), inert=0),
    'target_update_period': Key('optim', 'int', 'updates between hard target copies (when tau is null)', _int(1)),
    'tau': Key('optim', 'float | None', 'Polyak coefficient of the targets (null: hard copies)', _float(0.0, 1.0, optional=True, open_low=True), inert=None),
    'max_grad_norm': Key('optim', 'float | None', "clip each optimizer's gradient norm to this (null: no clipping; the authors' Envelope: 1.0)", _float(0.0, 1e12, optional=True, open_low=True), inert=None),
    'fused_optimizer': Key('optim', 'bool', "fused Adam (one kernel for all parameters, ~4x faster per step on a CPU core; the same arithmetic up to float rounding, which a seed's trajectory amplifies); false: torch's default per-tensor Adam, as the authors", _bool),
    'compile': Key('compile', 'bool', 'torch.compile the update step (loss, backward, optimizer, Polyak target); the non-finite guard then stays on the device', _bool),
    'compile_mode': Key('compile', 'str | None', "torch.compile mode (null: the default; 'reduce-overhead', 'max-autotune', ...)", _str(optional=True)),
    'cudagraphs': Key('compile', 'bool', 'replay the update step as a CUDA graph (tensordict.nn.CudaGraphModule; device cuda only)', _bool),
    'capture_sampling': Key('compile', 'bool', "with compile/cudagraphs and prioritized replay on the pure-torch sampler: sampling and priority writes inside the captured update (one CUDA graph per update, no host read); same draws and arithmetic", _bool),
    'finite_check_interval': Key('compile', 'int', "captured update and accelerators: updates between host reads of the device's count of skipped non-finite updates (the eager CPU update checks every one before applying it)", _int(1)),
    'hidden': Key('network', 'tuple[int, ...]', 'hidden layer widths of every MLP (PCN: the embedding width, then its hidden layers; Mario: after the CNN)', _hidden),
    'eps_start': Key('exploration', 'float', 'initial epsilon', _float(0.0, 1.0)),
    'eps_end': Key('exploration', 'float', 'final epsilon', _float(0.0, 1.0)),
    'eps_frames': Key('exploration', 'int', 'frames over which epsilon decays linearly', _int(1)),
    'num_sampled_prefs': Key('envelope', 'int', 'preferences sampled per transition in the loss', _int(1)),
    'homotopy_lambda0': Key('envelope', 'float', 'initial homotopy lambda', _float(0.0, 1.0)),
    'homotopy_final': Key('envelope', 'float | None', 'anneal lambda linearly to this value (null: lambda stays at homotopy_lambda0, as the authors)', _float(0.0, 1.0, optional=True)),
    'homotopy_frames': Key('envelope', 'int | None', 'frames of the homotopy schedule when homotopy_final is set (null: the whole run)', _int(1, optional=True)),
    'per_running_max': Key('replay_buffer', 'bool', "PER priorities as MORL-Baselines' buffer (the authors' Envelope): an update writes (p + M)^per_alpha, M the running maximum written priority (1e-5 at first), new items at M; false: TorchRL's (p + eps)^per_alpha, new items at the largest priority", _bool, inert=False),
    'envelope_priority': Key('envelope', 'str', "PER priority: |w.TD| under the 'first' sampled preference (the authors) or the 'mean' over all of them", _choice(("first", "mean"))),
    'envelope_network': Key('envelope', 'str', "Q-network form: 'authors' (w concatenated after the first hidden layer, orthogonal init; the paper's domains), 'mb' (w at the input, orthogonal init: MORL-Baselines 1.3.0's QNet; a foreign env's default) or 'input' (w at the input, PyTorch's init)", _choice(("authors", "mb", "input"))),
    'alpha': Key('actor_critic', 'float', 'entropy temperature (initial value when learned)', _float(0.0, 1e6)),
    'learn_alpha': Key('actor_critic', 'bool', 'learn the temperature', _bool),
    'target_entropy_scale': Key('actor_critic', 'float', 'discrete MOSAC: target entropy as a fraction of the maximum', _float(0.0, 1.0)),
    'actor_scale': Key('actor_critic', 'str', "Gaussian actor's scale: 'softplus' (TorchRL's biased softplus), 'clamped_log_std' (exp of the log-std clamped to [-20, 2]; the authors' CAPQL) or 'tanh_log_std' (log-std = -5 + 3.5 (tanh(x) + 1); the authors' SAC and MOSAC)", _choice(("softplus", "clamped_log_std", "tanh_log_std"))),
    'policy_freq': Key('actor_critic', 'int', "SAC/MOSAC delayed actor: every policy_freq-th critic step is followed by policy_freq actor (and temperature, on a fresh sample after each actor step) steps on the same batch, each loss computed alone; the others are critic-only (the authors' continuous SAC and MOSAC: 2); 1: a critic, an actor and a temperature step at every update (the authors' discrete SAC/MOSAC and CAPQL)", _int(1, 1000), inert=1),
    'joint_update': Key('actor_critic', 'bool', "actor-critics: one backward of the summed critic, actor and temperature losses per update, the actor seeing the critics before their step (our earlier update; policy_freq must be 1); false: the authors' order, the critic step, then the actor step(s) on the updated critics, then the temperature, each loss computed alone", _bool, inert=False),
    'alpha_loss_form': Key('actor_critic', 'str', "the learned temperature's loss: 'alpha' (-alpha (log pi + target); the authors' CleanRL-style SAC and MORL-Baselines' discrete MOSAC) or 'log_alpha' (-log alpha (log pi + target); TorchRL's and MORL-Baselines' continuous MOSAC, mosac_continuous_action.py:470)", _choice(("alpha", "log_alpha")), inert="log_alpha"),
    'loss_fresh_preferences': Key('actor_critic', 'bool', 'CAPQL/MOSAC losses draw fresh preferences per sample instead of the stored ones (the authors: false)', _bool),
    'pcn_scaling_factor': Key('pcn', 'tuple[float, ...] | None', 'scale of the command [desired return (k), horizon] (null: 0.1 each)', _floats),
    'pcn_max_return': Key('pcn', 'tuple[float, ...] | None', 'upper clip of the desired return while acting (null: 100 per objective)', _floats),
    'pcn_buffer_episodes': Key('pcn', 'int', 'episodes in the episode replay (max_buffer_size)', _int(1)),
    'pcn_er_episodes': Key('pcn', 'int', 'random warm-up episodes, and the best episodes commands are chosen from (num_er_episodes)', _int(1)),
    'pcn_step_episodes': Key('pcn', 'int', 'episodes per command (num_step_episodes)', _int(1)),
    'pcn_model_updates': Key('pcn', 'int', 'supervised updates per command (num_model_updates)', _int(1)),
    'pcn_noise': Key('pcn', 'float', 'std of the Gaussian noise on continuous actions', _float(0.0, 1e6)),
    'pgmorl_pop': Key('pgmorl', 'int', 'population size (one PPO task per member)', _int(1)),
    'pgmorl_envs_per_member': Key('pgmorl', 'int', 'sub-envs per member (num_envs must be pgmorl_pop times this; frames_per_batch / num_envs = steps per iteration)', _int(1)),
    'pgmorl_warmup': Key('pgmorl', 'int', 'warm-up iterations', _int(1)),
    'pgmorl_evo_iterations': Key('pgmorl', 'int', 'iterations between task selections', _int(1)),
    'pgmorl_num_buffers': Key('pgmorl', 'int', 'bins of the performance buffer (num_performance_buffer)', _int(2)),
    'pgmorl_buffer_size': Key('pgmorl', 'int', 'policies per bin (performance_buffer_size)', _int(1)),
    'pgmorl_delta_weight': Key('pgmorl', 'float', 'weight grid step (candidates: half of it)', _float(0.0, 1.0, open_low=True)),
    'pgmorl_sparsity': Key('pgmorl', 'float', 'sparsity coefficient of the task selection', _float(-1e12, 1e12)),
    'pgmorl_epochs': Key('pgmorl', 'int', 'PPO epochs per iteration', _int(1)),
    'pgmorl_minibatches': Key('pgmorl', 'int', 'PPO minibatches per epoch and member', _int(1)),
    'pgmorl_clip': Key('pgmorl', 'float', 'PPO ratio and value clip', _float(0.0, 10.0, open_low=True)),
    'pgmorl_gae_lambda': Key('pgmorl', 'float', 'GAE lambda', _float(0.0, 1.0)),
    'pgmorl_reset_each_iteration': Key('pgmorl', 'bool', "reset every sub-env at the start of each iteration, abandoning the running episodes (the authors' envs.reset at each member's train(), mo_ppo.py:628); false: episodes continue across iterations", _bool, inert=False),
    'pgmorl_reseed_each_iteration': Key('pgmorl', 'bool', "at that reset, re-seed member p's sub-env i with its seed + i (the run's seed, 42 once the task selection made the member a copy), as the authors' envs.reset(seed=member.seed) (mo_ppo.py:628; the simulators' initial-state noise repeats each iteration, the DR contexts do not); false: one stream per sub-env for the whole run", _bool, inert=False),
    'pgmorl_eval_obs': Key('pgmorl', 'str', "observations of the evaluated policy: 'raw' (the authors: normalised policies fed raw observations) or 'normalized' (the training normalisation, frozen)", _choice(("raw", "normalized"))),
    'pop_size': Key('morld', 'int', 'population size P (concurrent schedule: each member owns num_envs sub-envs, P * num_envs in all)', _int(1, 4096)),
    'exchange_every': Key('morld', 'int', 'frames between exchanges (archive update, weight adaptation); round robin: the frames of one member\'s turn', _int(1)),
    'morld_schedule': Key('morld', 'str', "'round_robin' (the authors': one member at a time steps num_envs sub-envs for exchange_every frames with its own updates, the env reset at each exchange, then morld_update_passes catch-up updates of the others; morld.py:421-431,559-567) or 'concurrent' (all members collect on their own sub-envs and update together in one batched step: faster, most of all on a GPU; not the authors')", _choice(("round_robin", "concurrent"))),
    'morld_update_passes': Key('morld', 'int', "round robin: updates every other member gets after each exchange (the authors' update_passes: 10)", _int(0, 1_000_000)),
    'weight_adaptation': Key('morld', 'str', "'none' (MORL/D SB: fixed weights) or 'psa' (Pareto simulated annealing, MORL/D SB+PSA)", _choice(("none", "psa"))),
    'morld_eval_episodes': Key('morld', 'int', "episodes per member (sampled actions, a DR env of their own, not training frames) whose mean discounted return is the member's archive evaluation after every exchange (the authors' num_eval_episodes_for_front: 5); 0: the mean return of its training episodes since the last exchange", _int(0, 10_000)),
    'morld_archive_initial': Key('morld', 'bool', "the untrained members are evaluated (morld_eval_episodes each) and archived before training, so that the archive (the evaluation's policies) holds them from frame 0 (the authors' and MORL-Baselines': SPEC §6); needs morld_eval_episodes > 0; false: the archive starts empty and takes the members at the first exchange", _bool),
    'psa_delta': Key('morld', 'float', 'PSA step: a weight is multiplied or divided by 1 + psa_delta', _float(0.0, 10.0, open_low=True)),
    'update_frequency': Key('optim', 'int', "frames (MORL/D: member frames) per gradient update when updates_per_batch is 0 (the authors' discrete SAC: 4)", _int(1), inert=1),
    'gpi_iteration_frames': Key('gpi', 'int', 'frames per weight-support iteration (timesteps_per_iter)', _int(1)),
    'gpi_front_episodes': Key('gpi', 'int', 'episodes per weight when the GPI policy is evaluated on the support and the corner weights (LunarLander: 3)', _int(1, 10_000)),
    'gpi_num_nets': Key('gpi', 'int', 'Q-networks in the ensemble', _int(1, 64)),
    'gpi_dropout': Key('gpi', 'float', "dropout rate of the Q-networks' hidden layers", _float(0.0, 0.99)),
    'gpi_layer_norm': Key('gpi', 'bool', "LayerNorm in the Q-networks' hidden layers", _bool),
    'capql_log_prob': Key('actor_critic', 'str', "CAPQL's log pi of a tanh-Gaussian action: 'clamped' (the authors: the Normal's log-density minus sum log(scale (1 - tanh^2) + 1e-6), clamped to [-1000, 1000]; their capql.py:149-155) or 'exact' (TorchRL's TanhNormal: the exact Jacobian)", _choice(("clamped", "exact"))),
    'capql_deterministic_collection': Key('collector', 'bool', "CAPQL collects with the deterministic action tanh(mean) after init_random_frames (the authors' capql.py:454-459); false: sampled actions", _bool),
    'gpi_model_termination': Key('gpi', 'str', "GPI-PD's Hopper termination of imagined transitions: 'authors' (state[1:] < 100, their slip: no abs; what produced the paper's numbers) or 'corrected' (|state[1:]| < 100)", _choice(("authors", "corrected")), inert="authors"),
    'gpi_eval_conditioning': Key('gpi', 'str', "continuous GPI at evaluation: the critic's conditioning weight for support row i: 'authors' (their vectorised evaluator's w_floor((e*M+i)/E) for evaluation context e of E, which produced the paper's numbers) or 'support' (w_i, their single-env path)", _choice(("authors", "support"))),
    'gpi_first_episode': Key('gpi', 'str', "GPI-LS/GPI-PD's first episode of an iteration: 'w' (the authors: every sub-env resets when an iteration begins and acts with the new corner weight w until that episode ends, later episodes draw from the support M; SPEC §6, hyperparameters.toml train_iteration.change_w_every_episode) or 'support' (the episode in progress goes on; every new episode draws from M)", _choice(("w", "support"))),
    'gpi_update_weight': Key('gpi', 'str', "GPI-LS/GPI-PD's weight for the first half of each update's batch (the TD loss and the PER priorities): 'iteration' (the iteration's corner weight w: SPEC §6 and the record's rows_per_gradient_step) or 'episode' (MORL-Baselines 1.3.0: the weight of the episode in progress at the update, sub-env 0's; gpi_pd.py:763,785-786)", _choice(("iteration", "episode"))),
    'gpi_gradient_updates': Key('gpi', 'int', 'gradient updates per frame once frames reach gpi_dynamics_rollout_starts (1 before; updates_per_batch > 0 overrides both; the authors: 1)', _int(1)),
    'gpi_min_priority': Key('gpi', 'float', 'Huber threshold and minimum PER priority', _float(0.0, 1e6, open_low=True)),
    'gpi_dynamics_hidden': Key('gpi', 'tuple[int, ...]', 'GPI-PD: hidden widths of the dynamics ensemble', _hidden),
    'gpi_dynamics_ensemble': Key('gpi', 'int', 'GPI-PD: dynamics ensemble members', _int(1, 64)),
    'gpi_dynamics_elites': Key('gpi', 'int', 'GPI-PD: elite members sampled from', _int(1, 64)),
    'gpi_dynamics_lr': Key('gpi', 'float', 'GPI-PD: dynamics learning rate', _float(0.0, 1.0, open_low=True)),
    'gpi_dynamics_train_freq': Key('gpi', 'int', 'GPI-PD: frames between dynamics fits', _int(1)),
    'gpi_dynamics_rollout_freq': Key('gpi', 'int', 'GPI-PD: frames between model rollouts', _int(1)),
    'gpi_dynamics_rollout_starts': Key('gpi', 'int', 'GPI-PD: frames before the first rollout (also when gpi_gradient_updates starts, for GPI-LS too)', _int(0)),
    'gpi_dynamics_rollout_batch': Key('gpi', 'int', 'GPI-PD: observations rolled out per rollout', _int(1)),
    'gpi_dynamics_buffer': Key('gpi', 'int', 'GPI-PD: model transitions kept', _int(1)),
    'gpi_uncertainty_threshold': Key('gpi', 'float', 'GPI-PD: model transitions kept only below this uncertainty', _float(0.0, 1e12, open_low=True)),
    'gpi_real_ratio': Key('gpi', 'float', 'GPI-PD: fraction of real transitions per batch', _float(0.0, 1.0)),
    'gpi_dynamics_rollout_len': Key('gpi', 'int', 'GPI-PD: model steps per rollout (continuous: 5)', _int(1, 1000)),
    'gpi_dynamics_max_logvar': Key('gpi', 'float', "GPI-PD: initial value of the model's learned upper bound of the log-variance (the authors' dynamics_max_logvar_scale: 0.5, Humanoid 0.1)", _float(-20.0, 20.0)),
    'gpi_dynamics_max_grad_norm': Key('gpi', 'float | None', "GPI-PD: clip the dynamics model's gradient norm to this in every fit step (null: no clipping; the authors' Humanoid: 10)", _float(0.0, 1e12, optional=True, open_low=True)),
    'gpi_dynamics_normalize': Key('gpi', 'bool', "GPI-PD: standardise the model's inputs (continuous: true)", _bool),
    'gpi_policy_noise': Key('gpi', 'float', "continuous: std of the actor's exploration and target-smoothing noise", _float(0.0, 1e3)),
    'gpi_noise_clip': Key('gpi', 'float', 'continuous: that noise clipped to +-this', _float(0.0, 1e3)),
    'gpi_policy_delay': Key('gpi', 'int', 'continuous: critic updates per actor update', _int(1)),
    'eval_interval': Key('eval', 'int', 'frames between evaluations', _int(1)),
    'eval_weights': Key('eval', 'int', 'evaluation weights (energy weights; the paper: 100, Mario 32)', _int(1, 100_000)),
    'eval_episodes': Key('eval', 'int', 'episodes per (context, weight)', _int(1, 10_000)),
    'eval_exploration': Key('eval', 'str', "evaluation actions: 'deterministic' (greedy / mean) or 'random' (sampled; the paper's MORL/D and SAC)", _choice(("deterministic", "random"))),
    'eval_contexts': Key('eval', 'tuple[str, ...] | None', "evaluation env ids (null: the domain's suite)", _contexts),
    'reference_dir': Key('eval', 'str | None', "the published data for NHGR/EUGR and the paper's baselines (null: the bounds and specialist fronts shipped with the package, no baselines)", _str(optional=True)),
    'eval_random_baseline': Key('eval', 'bool', 'also evaluate a uniformly random policy at the end', _bool),
    'ref_point': Key('eval', 'tuple[float, ...] | None', "hypervolume reference point, one number per objective (null: the domain's; a foreign env without a documented one needs it)", _floats),
    'domain_modules': Key('env', 'tuple[str, ...]', 'Python modules imported before env_id is looked up (each registers domains, e.g. a module with SPECS; --domain-module)', _modules),
}
# fmt: on

_TUPLE_KEYS = frozenset(k for k, key in KEYS.items() if key.type.startswith("tuple"))
_FLOAT_KEYS = frozenset(k for k, key in KEYS.items() if key.type.split(" |")[0] == "float")
#: keys of earlier versions that are renamed (what they map to: ``train_config.RENAMED``)
RENAMED_KEYS = frozenset({"pcn_hidden"})

#: other names for our keys (MORL-Baselines' and common ones), for "did you mean" on an unknown key
KEY_ALIASES = {
    "learning_rate": "lr", "net_arch": "hidden", "hidden_dim": "hidden", "hidden_sizes": "hidden",
    "total_timesteps": "frames", "timesteps": "frames", "steps": "frames", "num_frames": "frames",
    "learning_starts": "init_random_frames", "initial_epsilon": "eps_start", "final_epsilon": "eps_end",
    "epsilon_decay_steps": "eps_frames", "target_net_update_freq": "target_update_period",
    "target_net_freq": "target_update_period", "per": "prioritized", "gradient_updates": "gpi_gradient_updates",
    "num_eval_weights_for_front": "eval_weights", "num_eval_episodes_for_front": "eval_episodes",
    "eval_freq": "eval_interval", "eval_mo_freq": "eval_interval", "discount": "gamma",
    "clip_grad_norm": "max_grad_norm", "max_grad_norm_clip": "max_grad_norm", "scaling_factor": "pcn_scaling_factor",
    "num_sample_w": "num_sampled_prefs", "initial_homotopy_lambda": "homotopy_lambda0", "envs": "num_envs",
}


def unknown_keys_message(unknown, valid, source: str = "", algo: str | None = None) -> str:
    """``overrides: unknown config key 'learning_rate' (did you mean 'lr'?); ...``: each unknown key
    with the valid keys it most likely meant (:data:`KEY_ALIASES`, close spellings), and where to
    see all of them, instead of the whole list.

    Example:
        >>> unknown_keys_message(["learning_rate"], ["lr", "gamma"], "overrides", "envelope")
        "overrides: unknown config key 'learning_rate' (did you mean 'lr'?); morl-trl config envelope ENV_ID prints every key of envelope"
    """
    from morl_trl._suggest import did_you_mean

    unknown = sorted(unknown)
    # (a key of another algorithm is no misspelling: no suggestion for it)
    named = ", ".join(f"{k!r}{'' if k in KEYS else did_you_mean(k, valid, KEY_ALIASES)}" for k in unknown)
    plural = len(unknown) > 1
    if algo and all(k in KEYS for k in unknown):
        what = f"config key{'s' if plural else ''} {named} {'are not settings' if plural else 'is not a setting'} of {algo}"
    else:
        what = f"unknown config key{'s' if plural else ''} {named}"
    where = f"morl-trl config {algo} ENV_ID prints every key of {algo}" if algo else \
        "morl-trl config ALGO ENV_ID prints every key of ALGO"
    return f"{source + ': ' if source else ''}{what}; {where}"


def coerce_values(values: dict[str, Any]) -> dict[str, Any]:
    """TOML/JSON values as the config holds them: ``"null"`` -> None, lists -> tuples, ints -> floats
    for float keys. Unknown keys are an error listing the known ones."""
    unknown = sorted(set(values) - set(KEYS) - set(RENAMED_KEYS))
    if unknown:
        raise ValueError(unknown_keys_message(unknown, KEYS))
    out = {}
    for k, v in values.items():
        if v == "null":  # TOML has no null: a file or a key=value flag writes the string
            v = None
        if k in _TUPLE_KEYS and isinstance(v, list):
            v = tuple(v)
        elif k in _FLOAT_KEYS and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        out[k] = v
    return out
