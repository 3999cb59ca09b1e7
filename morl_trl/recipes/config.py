"""The configuration of a recipe: one dataclass, grouped, with the paper's defaults per (algorithm, domain).

Resolution order (later wins): the domain's protocol (its :class:`~morl_trl.envs.DomainSpec`:
frames, history, evaluation period and weights) -> the algorithm's defaults (SPEC §4) ->
(algorithm, domain) overrides -> the ``quick`` preset (if asked) -> a TOML/JSON config file
-> command-line flags.

The keys are grouped as TorchRL's sota recipes group theirs (``run``, ``env``, ``collector``,
``replay_buffer``, ``optim``, ``compile``, ``network``, ``exploration``, ``envelope``, ``actor_critic``,
``pcn``, ``pgmorl``, ``morld``, ``gpi``, ``eval``): a config file may use ``[group]`` tables or flat keys, and
``TrainConfig.to_toml()`` (``morl-trl train ... --print-config``) writes the complete grouped
config. Every value is checked (type and range) when the config is built: a bad one raises a
``ValueError`` naming the key, the value and what is valid; an unknown key lists the valid ones.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["TrainConfig", "ALGORITHMS", "GROUPS", "RESUME_MAY_CHANGE", "resolve_config", "load_config_file",
           "resume_config", "quick_preset", "config_values"]

ALGORITHMS = ("envelope", "capql", "mosac", "mosac_discrete", "morld", "morld_psa", "sac", "pcn", "pgmorl",
              "gpi_ls", "gpi_pd")
LOGGERS = ("csv", "tensorboard", "wandb", "none")


def _key(group: str, default: Any, help: str, check: Callable[[Any], str | None] | None = None):
    return field(default=default, metadata={"group": group, "help": help, "check": check})


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


def _hidden(v):
    ok = isinstance(v, tuple) and len(v) > 0 and all(
        isinstance(x, int) and not isinstance(x, bool) and x >= 1 for x in v)
    return None if ok else "a non-empty list of positive ints (hidden layer widths), e.g. [256, 256]"


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


@dataclass
class TrainConfig:
    """Every knob of a training run, by group (see :func:`resolve_config` for where values come from).

    Example:
        >>> cfg = TrainConfig(frames=1000)
        >>> cfg.group("replay_buffer")["batch_size"]
        128
        >>> TrainConfig(frames=-100).validate()
        Traceback (most recent call last):
        ...
        ValueError: config key 'frames' (collector) is -100; valid: an int in [1, inf]
    """

    # run
    algo: str = _key("run", "envelope", "algorithm", _choice(ALGORITHMS))
    env_id: str = _key("run", "MOLavaGridDR-v0", "training env id (a *DR-* id trains under domain randomization)",
                       _str())
    seed: int = _key("run", 0, "one seed for contexts, preferences, networks and evaluation", _int(0, 2**63 - 1))
    device: str = _key("run", "cpu", "torch device of envs, replay buffer and networks", _device)
    num_threads: int = _key("run", 1, "torch CPU threads (1 avoids OpenMP oversubscription with small nets; "
                            "0: torch's default)", _int(0, 4096))
    run_dir: str | None = _key("run", None, "where the run is written (null: runs/<algo>_<env>_s<seed>_<time>)",
                               _str(optional=True))
    checkpoint_interval: int = _key("run", 50_000, "frames between checkpoints", _int(1))
    keep_checkpoints: int = _key("run", 2, "checkpoints kept (the newest holds the replay buffer, the older "
                                 "ones only the state)", _int(1))
    logger: str = _key("run", "csv", "TorchRL logger", _choice(LOGGERS))
    progress: bool = _key("run", True, "show a progress bar", _bool)
    # env
    num_envs: int = _key("env", 16, "sub-environments stepped together", _int(1, 1 << 20))
    history_len: int = _key("env", 0, "StateActionHistory length (the paper: 2 for LunarLander and MuJoCo)",
                            _int(0, 64))
    gamma: float | None = _key("env", None, "discount (null: the domain's evaluation discount)",
                               _float(0.0, 1.0, optional=True))
    preference_distribution: str = _key("env", "dirichlet", "training preferences: 'dirichlet' (uniform on the "
                                        "simplex), 'gaussian' (|N(0,I)| normalised; the authors' Envelope) or "
                                        "'cone' (22.5 degrees around the equal-weight direction; the authors' CAPQL)",
                                        _choice(("dirichlet", "gaussian", "cone")))
    preference_resample: str = _key("env", "episode", "a new training preference per 'episode' or per 'step' "
                                    "(the authors' CAPQL: step)", _choice(("episode", "step")))
    # collector
    frames: int = _key("collector", 1_000_000, "environment frames to train for", _int(1))
    frames_per_batch: int = _key("collector", 64, "frames per collector batch (all sub-envs)", _int(1))
    init_random_frames: int = _key("collector", 1_000, "uniformly random actions before learning starts "
                                   "(MORL-Baselines' learning_starts)", _int(0))
    # replay buffer
    buffer_size: int = _key("replay_buffer", 1_000_000, "transitions kept", _int(1))
    batch_size: int = _key("replay_buffer", 128, "transitions per update", _int(1))
    prioritized: bool = _key("replay_buffer", True, "prioritized replay (keyed by the loss's td_error)", _bool)
    per_alpha: float = _key("replay_buffer", 0.6, "priority exponent", _float(0.0, 1.0))
    per_beta: float = _key("replay_buffer", 0.4, "importance-sampling exponent", _float(0.0, 1.0))
    per_importance_weights: bool = _key("replay_buffer", True, "weight the loss by PER's importance-sampling "
                                        "weights (the authors' Envelope: false)", _bool)
    # optim
    lr: float = _key("optim", 3e-4, "Adam learning rate", _float(0.0, 1.0, open_low=True))
    updates_per_batch: int = _key("optim", 0, "gradient updates per collected batch (0: one per frame)", _int(0))
    target_update_period: int = _key("optim", 1000, "updates between hard target copies (when tau is null)",
                                     _int(1))
    tau: float | None = _key("optim", None, "Polyak coefficient of the targets (null: hard copies)",
                             _float(0.0, 1.0, optional=True, open_low=True))
    max_grad_norm: float | None = _key("optim", None, "clip each optimizer's gradient norm to this (null: no "
                                       "clipping; the authors' Envelope: 1.0)",
                                       _float(0.0, 1e12, optional=True, open_low=True))
    fused_optimizer: bool = _key("optim", True, "fused Adam (one kernel for all parameters, ~4x faster per step on "
                                 "a CPU core; the same arithmetic up to float rounding, which a seed's trajectory "
                                 "amplifies); false: torch's default per-tensor Adam, as the authors", _bool)
    # compile (the captured update: morl_trl.recipes.capture)
    compile: bool = _key("compile", False, "torch.compile the update step (loss, backward, optimizer, Polyak "
                         "target); the non-finite guard then stays on the device", _bool)
    compile_mode: str | None = _key("compile", None, "torch.compile mode (null: the default; 'reduce-overhead', "
                                    "'max-autotune', ...)", _str(optional=True))
    cudagraphs: bool = _key("compile", False, "replay the update step as a CUDA graph (tensordict.nn."
                            "CudaGraphModule; device cuda only)", _bool)
    capture_sampling: bool = _key("compile", False, "with compile/cudagraphs and prioritized replay on the "
                                  "pure-torch sampler: sampling and priority writes inside the captured update "
                                  "(one CUDA graph per update, no host read); same draws and arithmetic", _bool)
    finite_check_interval: int = _key("compile", 100, "captured update and accelerators: updates between host "
                                      "reads of the device's count of skipped non-finite updates (the eager CPU "
                                      "update checks every one before applying it)", _int(1))
    # network
    hidden: tuple[int, ...] = _key("network", (256, 256, 256, 256), "hidden layer widths of every MLP", _hidden)
    # exploration (epsilon-greedy)
    eps_start: float = _key("exploration", 1.0, "initial epsilon", _float(0.0, 1.0))
    eps_end: float = _key("exploration", 0.05, "final epsilon", _float(0.0, 1.0))
    eps_frames: int = _key("exploration", 1_000_000, "frames over which epsilon decays linearly", _int(1))
    # envelope
    num_sampled_prefs: int = _key("envelope", 8, "preferences sampled per transition in the loss", _int(1))
    homotopy_lambda0: float = _key("envelope", 0.95, "initial homotopy lambda", _float(0.0, 1.0))
    homotopy_final: float | None = _key("envelope", None, "anneal lambda linearly to this value (null: lambda "
                                        "stays at homotopy_lambda0, as the authors)",
                                        _float(0.0, 1.0, optional=True))
    homotopy_frames: int | None = _key("envelope", None, "frames of the homotopy schedule when homotopy_final is "
                                       "set (null: the whole run)", _int(1, optional=True))
    envelope_priority: str = _key("envelope", "first", "PER priority: |w.TD| under the 'first' sampled preference "
                                  "(the authors) or the 'mean' over all of them", _choice(("first", "mean")))
    envelope_network: str = _key("envelope", "authors", "Q-network form: 'authors' (w concatenated after the first "
                                 "hidden layer, orthogonal init) or 'input' (w at the input, PyTorch's init)",
                                 _choice(("authors", "input")))
    # actor-critic (CAPQL, MOSAC)
    alpha: float = _key("actor_critic", 0.2, "entropy temperature (initial value when learned)",
                        _float(0.0, 1e6))
    learn_alpha: bool = _key("actor_critic", False, "learn the temperature", _bool)
    target_entropy_scale: float = _key("actor_critic", 0.3, "discrete MOSAC: target entropy as a fraction of "
                                       "the maximum", _float(0.0, 1.0))
    actor_scale: str = _key("actor_critic", "softplus", "Gaussian actor's scale: 'softplus' or 'clamped_log_std' "
                            "(exp of the log-std clamped to [-20, 2]; the authors' CAPQL)",
                            _choice(("softplus", "clamped_log_std")))
    loss_fresh_preferences: bool = _key("actor_critic", False, "CAPQL/MOSAC losses draw fresh preferences per "
                                        "sample instead of the stored ones (the authors: false)", _bool)
    # PCN (Reymond et al. 2022; MORL-Baselines' defaults, SPEC §4 per domain)
    pcn_scaling_factor: tuple[float, ...] | None = _key("pcn", None, "scale of the command [desired return (k), "
                                                        "horizon] (null: 0.1 each)", _floats)
    pcn_max_return: tuple[float, ...] | None = _key("pcn", None, "upper clip of the desired return while acting "
                                                    "(null: 100 per objective)", _floats)
    pcn_buffer_episodes: int = _key("pcn", 100, "episodes in the episode replay (max_buffer_size)", _int(1))
    pcn_er_episodes: int = _key("pcn", 20, "random warm-up episodes, and the best episodes commands are "
                                "chosen from (num_er_episodes)", _int(1))
    pcn_step_episodes: int = _key("pcn", 10, "episodes per command (num_step_episodes)", _int(1))
    pcn_model_updates: int = _key("pcn", 50, "supervised updates per command (num_model_updates)", _int(1))
    pcn_noise: float = _key("pcn", 0.1, "std of the Gaussian noise on continuous actions", _float(0.0, 1e6))
    pcn_hidden: int | None = _key("pcn", None, "PCN's network: null = the widths of 'hidden' (the authors' net_arch: "
                                  "embedding hidden[0], a Linear+ReLU per further width); an int h = embedding h and "
                                  "one hidden layer h (MORL-Baselines' hidden_dim)", _int(1, optional=True))
    # PGMORL (Xu et al. 2020; MORL-Baselines' defaults, SPEC §4 per domain)
    pgmorl_pop: int = _key("pgmorl", 6, "population size (one PPO task per member)", _int(1))
    pgmorl_envs_per_member: int = _key("pgmorl", 4, "sub-envs per member (num_envs must be pgmorl_pop times this; "
                                       "frames_per_batch / num_envs = steps per iteration)", _int(1))
    pgmorl_warmup: int = _key("pgmorl", 80, "warm-up iterations", _int(1))
    pgmorl_evo_iterations: int = _key("pgmorl", 20, "iterations between task selections", _int(1))
    pgmorl_num_buffers: int = _key("pgmorl", 100, "bins of the performance buffer (num_performance_buffer)",
                                   _int(2))
    pgmorl_buffer_size: int = _key("pgmorl", 2, "policies per bin (performance_buffer_size)", _int(1))
    pgmorl_delta_weight: float = _key("pgmorl", 0.2, "weight grid step (candidates: half of it)",
                                      _float(0.0, 1.0, open_low=True))
    pgmorl_sparsity: float = _key("pgmorl", -1.0, "sparsity coefficient of the task selection", _float(-1e12, 1e12))
    pgmorl_epochs: int = _key("pgmorl", 10, "PPO epochs per iteration", _int(1))
    pgmorl_minibatches: int = _key("pgmorl", 32, "PPO minibatches per epoch and member", _int(1))
    pgmorl_clip: float = _key("pgmorl", 0.2, "PPO ratio and value clip", _float(0.0, 10.0, open_low=True))
    pgmorl_gae_lambda: float = _key("pgmorl", 0.95, "GAE lambda", _float(0.0, 1.0))
    pgmorl_eval_obs: str = _key("pgmorl", "raw", "observations of the evaluated policy: 'raw' (the authors: "
                                "normalised policies fed raw observations) or 'normalized' (the training "
                                "normalisation, frozen)", _choice(("raw", "normalized")))
    # MORL/D (morld, morld_psa)
    pop_size: int = _key("morld", 6, "population size P (each member owns num_envs sub-envs: P * num_envs in all)",
                         _int(1, 4096))
    exchange_every: int = _key("morld", 20_000, "frames between exchanges (archive update, weight adaptation)", _int(1))
    weight_adaptation: str = _key("morld", "none", "'none' (MORL/D SB: fixed weights) or 'psa' (Pareto simulated "
                                  "annealing, MORL/D SB+PSA)", _choice(("none", "psa")))
    psa_delta: float = _key("morld", 0.1, "PSA step: a weight is multiplied or divided by 1 + psa_delta",
                            _float(0.0, 10.0, open_low=True))
    update_frequency: int = _key("morld", 1, "member frames per gradient update when updates_per_batch is 0 (the "
                                 "authors' discrete MOSAC: 4)", _int(1))
    # GPI-LS / GPI-PD (the authors' GPIPD defaults; SPEC §4 per domain)
    gpi_iteration_frames: int = _key("gpi", 50_000, "frames per weight-support iteration (timesteps_per_iter)", _int(1))
    gpi_front_episodes: int = _key("gpi", 5, "episodes per weight when the GPI policy is evaluated on the support "
                                   "and the corner weights (LunarLander: 3)", _int(1, 10_000))
    gpi_num_nets: int = _key("gpi", 2, "Q-networks in the ensemble", _int(1, 64))
    gpi_dropout: float = _key("gpi", 0.01, "dropout rate of the Q-networks' hidden layers", _float(0.0, 0.99))
    gpi_layer_norm: bool = _key("gpi", True, "LayerNorm in the Q-networks' hidden layers", _bool)
    capql_deterministic_collection: bool = _key("collector", True, "CAPQL collects with the deterministic action "
                                                "tanh(mean) after init_random_frames (the authors' capql.py:454-459); "
                                                "false: sampled actions", _bool)
    gpi_model_termination: str = _key("gpi", "authors", "GPI-PD's Hopper termination of imagined transitions: "
                                      "'authors' (state[1:] < 100, their slip: no abs; what produced the paper's "
                                      "numbers) or 'corrected' (|state[1:]| < 100)", _choice(("authors", "corrected")))
    gpi_eval_conditioning: str = _key("gpi", "authors", "continuous GPI at evaluation: the critic's conditioning "
                                      "weight for support row i: 'authors' (their vectorised evaluator's "
                                      "w_floor((e*M+i)/E) for evaluation context e of E, which produced the paper's "
                                      "numbers) or 'support' (w_i, their single-env path)",
                                      _choice(("authors", "support")))
    gpi_gradient_updates: int = _key("gpi", 20, "gradient updates per frame once frames reach "
                                     "gpi_dynamics_rollout_starts (1 before; updates_per_batch > 0 overrides both)",
                                     _int(1))
    gpi_min_priority: float = _key("gpi", 0.01, "Huber threshold and minimum PER priority",
                                   _float(0.0, 1e6, open_low=True))
    gpi_dynamics_hidden: tuple[int, ...] = _key("gpi", (256, 256, 256), "GPI-PD: hidden widths of the dynamics "
                                                "ensemble", _hidden)
    gpi_dynamics_ensemble: int = _key("gpi", 5, "GPI-PD: dynamics ensemble members", _int(1, 64))
    gpi_dynamics_elites: int = _key("gpi", 2, "GPI-PD: elite members sampled from", _int(1, 64))
    gpi_dynamics_lr: float = _key("gpi", 1e-3, "GPI-PD: dynamics learning rate", _float(0.0, 1.0, open_low=True))
    gpi_dynamics_train_freq: int = _key("gpi", 250, "GPI-PD: frames between dynamics fits", _int(1))
    gpi_dynamics_rollout_freq: int = _key("gpi", 250, "GPI-PD: frames between model rollouts", _int(1))
    gpi_dynamics_rollout_starts: int = _key("gpi", 5_000, "GPI-PD: frames before the first rollout (also when "
                                            "gpi_gradient_updates starts, for GPI-LS too)", _int(0))
    gpi_dynamics_rollout_batch: int = _key("gpi", 25_000, "GPI-PD: observations rolled out per rollout", _int(1))
    gpi_dynamics_buffer: int = _key("gpi", 100_000, "GPI-PD: model transitions kept", _int(1))
    gpi_uncertainty_threshold: float = _key("gpi", 1.5, "GPI-PD: model transitions kept only below this "
                                            "uncertainty", _float(0.0, 1e12, open_low=True))
    gpi_real_ratio: float = _key("gpi", 0.5, "GPI-PD: fraction of real transitions per batch", _float(0.0, 1.0))
    gpi_dynamics_rollout_len: int = _key("gpi", 1, "GPI-PD: model steps per rollout (continuous: 5)", _int(1, 1000))
    gpi_dynamics_normalize: bool = _key("gpi", False, "GPI-PD: standardise the model's inputs (continuous: true)",
                                        _bool)
    gpi_policy_noise: float = _key("gpi", 0.2, "continuous: std of the actor's exploration and target-smoothing "
                                   "noise", _float(0.0, 1e3))
    gpi_noise_clip: float = _key("gpi", 0.5, "continuous: that noise clipped to +-this", _float(0.0, 1e3))
    gpi_policy_delay: int = _key("gpi", 2, "continuous: critic updates per actor update", _int(1))
    # evaluation
    eval_interval: int = _key("eval", 50_000, "frames between evaluations", _int(1))
    eval_weights: int = _key("eval", 100, "evaluation weights (energy weights; the paper: 100, Mario 32)",
                             _int(1, 100_000))
    eval_episodes: int = _key("eval", 1, "episodes per (context, weight)", _int(1, 10_000))
    eval_exploration: str = _key("eval", "deterministic", "evaluation actions: 'deterministic' (greedy / mean) "
                                 "or 'random' (sampled; the paper's MORL/D and SAC)",
                                 _choice(("deterministic", "random")))
    eval_contexts: tuple[str, ...] | None = _key("eval", None, "evaluation env ids (null: the domain's suite)",
                                                 _contexts)
    reference_dir: str | None = _key("eval", None, "the published data for NHGR/EUGR and the paper's baselines (null: the bounds and "
                                     "specialist fronts shipped with the package, no baselines)",
                                     _str(optional=True))
    eval_random_baseline: bool = _key("eval", True, "also evaluate a uniformly random policy at the end",
                                      _bool)
    ref_point: tuple[float, ...] | None = _key("eval", None, "hypervolume reference point, one number per objective "
                                               "(null: the domain's; a foreign env without a documented one needs it)",
                                               _floats)
    domain_modules: tuple[str, ...] = _key("env", (), "Python modules imported before env_id is looked up (each "
                                           "registers domains, e.g. a module with SPECS; --domain-module)", _modules)

    # ------------------------------------------------------------------ checks
    def validate(self) -> "TrainConfig":
        """Check every value (type and range); raise ``ValueError`` naming the key, the value and what is valid."""
        for f in dataclasses.fields(self):
            check = f.metadata.get("check")
            value = getattr(self, f.name)
            problem = check(value) if check is not None else None
            if problem is not None:
                raise ValueError(f"config key {f.name!r} ({f.metadata['group']}) is {value!r}; valid: {problem}")
        if self.cudagraphs and not str(self.device).startswith("cuda"):
            raise ValueError(f"config key 'cudagraphs' (compile) is true but device is {self.device!r}; "
                             "valid: cudagraphs=true with a cuda device (compile=true works on any device)")
        return self

    # ------------------------------------------------------------------ views and files
    def group(self, name: str) -> dict[str, Any]:
        """The keys of one group and their values."""
        if name not in GROUPS:
            raise ValueError(f"unknown config group {name!r}; valid: {list(GROUPS)}")
        return {k: getattr(self, k) for k in GROUPS[name]}

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def to_toml(self) -> str:
        """The complete config as grouped TOML (``null`` values are written as comments)."""
        lines = []
        for g, keys in GROUPS.items():
            lines.append(f"[{g}]")
            for k in keys:
                value = getattr(self, k)
                help_ = _FIELDS[k].metadata["help"]
                if value is None:
                    lines.append(f"# {k} = null  # {help_}")
                else:
                    lines.append(f"{k} = {_toml_value(value)}  # {help_}")
            lines.append("")
        return "\n".join(lines)

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=2, sort_keys=True))

    @classmethod
    def load(cls, path: str | Path) -> "TrainConfig":
        path = Path(path)
        try:
            data = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError) as err:
            raise ValueError(f"cannot read the config {str(path)!r}: {err}") from None
        if not isinstance(data, dict):
            raise ValueError(f"the config {str(path)!r} holds a {type(data).__name__}, not an object of keys")
        return cls(**_coerce(data)).validate()


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, str):
        return json.dumps(v)
    return repr(v)


_FIELDS = {f.name: f for f in dataclasses.fields(TrainConfig)}
#: the float keys (an integer in a file or on the command line, e.g. ``lr = 1``, is read as a float)
_FLOAT_KEYS = frozenset(name for name, f in _FIELDS.items() if str(f.type).split(" |")[0] == "float")
#: group name -> its keys, in order
GROUPS: dict[str, tuple[str, ...]] = {}
for _f in dataclasses.fields(TrainConfig):
    GROUPS.setdefault(_f.metadata["group"], ())
    GROUPS[_f.metadata["group"]] += (_f.name,)


def _flatten(values: dict[str, Any], source: str) -> dict[str, Any]:
    """Flat keys from a mapping that may hold ``{group: {key: value}}`` tables."""
    flat: dict[str, Any] = {}
    for k, v in values.items():
        if k in GROUPS and isinstance(v, dict):
            wrong = sorted(set(v) - set(GROUPS[k]))
            if wrong:
                raise ValueError(f"{source}: key(s) {wrong} are not in group [{k}]; its keys: {list(GROUPS[k])}")
            flat.update(v)
        else:
            flat[k] = v
    return flat


def _coerce(values: dict[str, Any]) -> dict[str, Any]:
    unknown = sorted(set(values) - set(_FIELDS))
    if unknown:
        raise ValueError(f"unknown config key(s) {unknown}; valid keys: {sorted(_FIELDS)}")
    out = {}
    for k, v in values.items():
        if v == "null":  # TOML has no null: a file or a key=value flag writes the string
            v = None
        if k in ("hidden", "eval_contexts", "pcn_scaling_factor", "pcn_max_return", "gpi_dynamics_hidden", "ref_point",
                 "domain_modules") and isinstance(v, list):
            v = tuple(v)
        elif k in _FLOAT_KEYS and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        out[k] = v
    return out


# --------------------------------------------------------------------------- defaults
# The paper's settings (SPEC §4): the domain's protocol comes from its DomainSpec, then the
# algorithm's defaults, then (algorithm, domain) overrides.
# Where SPEC is silent the authors' code (MORL-Generalization, i.e. MORL-Baselines' defaults) decides:
# Envelope: lambda fixed (no homotopy decay), gradient norm clipped at 1, PER without importance
# weights and priorities from the first sampled preference, learning_starts=100, |N(0, I)|
# training preferences, num_sample_w=4 (SPEC: 8 on LunarLander and Mario); CAPQL: a new
# preference every step from the 22.5-degree cone, stored and reused by the loss, log-std
# clamped to [-20, 2]; MORL/D's MOSAC is evaluated with sampled actions (SPEC §2).
_ALGO = {
    "envelope": dict(batch_size=128, target_update_period=1000, prioritized=True, homotopy_lambda0=0.95,
                     homotopy_final=None, num_sampled_prefs=8, eps_start=1.0, eps_end=0.05, eps_frames=1_000_000,
                     init_random_frames=100, max_grad_norm=1.0, per_importance_weights=False,
                     envelope_priority="first", envelope_network="authors", preference_distribution="gaussian",
                     preference_resample="episode"),
    "capql": dict(batch_size=256, tau=0.005, alpha=0.2, init_random_frames=1_000, prioritized=False,
                  preference_distribution="cone", preference_resample="step", loss_fresh_preferences=False,
                  actor_scale="clamped_log_std"),
    "mosac": dict(batch_size=256, tau=0.005, alpha=0.2, learn_alpha=True, init_random_frames=10_000,
                  prioritized=False, eval_exploration="random"),
    "mosac_discrete": dict(batch_size=128, target_update_period=2000, learn_alpha=True,
                           target_entropy_scale=0.3, prioritized=False, eval_exploration="random"),
    # PCN: MORL-Baselines' lr 1e-3 and batch 256; the collector's random frames are replaced by
    # the authors' pcn_er_episodes random episodes
    "pcn": dict(lr=1e-3, batch_size=256, init_random_frames=0, prioritized=False),
    # PGMORL: P x 4 envs x 2048 steps per iteration, MO-PPO's lr 3e-4 and gradient norm 0.5, sampled
    # evaluation actions (MOPPO.eval samples)
    "pgmorl": dict(num_envs=24, frames_per_batch=24 * 2048, init_random_frames=0, prioritized=False,
                   max_grad_norm=0.5, eval_exploration="random"),
    # MORL/D (SPEC §4; MORL-Baselines' MOSAC / MOSACDiscrete defaults where SPEC is silent): shared buffer,
    # energy weights, temperature 0.2 tuned; the discrete domains' values are in _ALGO_DOMAIN
    "morld": dict(batch_size=256, tau=0.005, alpha=0.2, learn_alpha=True, init_random_frames=25_000, prioritized=False,
                  eval_exploration="random", pop_size=6, exchange_every=20_000, weight_adaptation="none",
                  num_envs=2, frames_per_batch=60, update_frequency=1),
    "morld_psa": dict(batch_size=256, tau=0.005, alpha=0.2, learn_alpha=True, init_random_frames=25_000,
                      prioritized=False, eval_exploration="random", pop_size=6, exchange_every=20_000,
                      weight_adaptation="psa", num_envs=2, frames_per_batch=60, update_frequency=1),
    # SAC on the domain's original scalar reward (SPEC §4), evaluated with sampled actions as the authors
    "sac": dict(batch_size=256, tau=0.005, alpha=0.2, learn_alpha=True, init_random_frames=25_000, prioritized=False,
                eval_exploration="random"),
    # GPI-LS / GPI-PD: the authors' GPIPD defaults (learning_starts 100, PER without importance
    # weights, hard copies counted in frames) with SPEC's epsilon schedule
    "gpi_ls": dict(batch_size=128, target_update_period=1000, prioritized=True, per_importance_weights=False,
                   init_random_frames=100, eps_start=1.0, eps_end=0.05, eps_frames=1_000_000),
    "gpi_pd": dict(batch_size=128, target_update_period=1000, prioritized=True, per_importance_weights=False,
                   init_random_frames=100, eps_start=1.0, eps_end=0.05, eps_frames=1_000_000),
}
_PCN_DOMAIN = {  # SPEC §4: scaling factor, max return, buffer (episodes), ER episodes (+ noise, batch)
    "MOLunarLanderDR-v0": dict(pcn_scaling_factor=(0.1,) * 5, pcn_buffer_episodes=100_000, pcn_er_episodes=1000),
    "MOHopperDR-v5": dict(pcn_scaling_factor=(0.1,) * 4, pcn_max_return=(2700.0, 3100.0, 1000.0),
                          pcn_buffer_episodes=100_000, pcn_er_episodes=1000),
    "MOHalfCheetahDR-v5": dict(pcn_scaling_factor=(0.1,) * 3, pcn_max_return=(12300.0, 0.0),
                               pcn_buffer_episodes=10_000, pcn_er_episodes=1000, pcn_noise=0.2),
    "MOHumanoidDR-v5": dict(pcn_scaling_factor=(0.1,) * 3, pcn_max_return=(5200.0, 1000.0),
                            pcn_buffer_episodes=100_000),
    "MOLavaGridDR-v0": dict(pcn_scaling_factor=(0.1,) * 3, pcn_max_return=(300.0, 300.0), pcn_buffer_episodes=4000,
                            pcn_er_episodes=2000),
    "MOSuperMarioBrosZeroShot-v2": dict(pcn_scaling_factor=(0.1,) * 4, pcn_max_return=(100.0, 100.0, 200.0),
                                        pcn_buffer_episodes=100_000, pcn_er_episodes=200, batch_size=64),
}
_MORLD_DISCRETE = dict(tau=None, batch_size=128, init_random_frames=20_000, update_frequency=4,
                       target_entropy_scale=0.89)
_ALGO_DOMAIN = {
    ("envelope", "MOLavaGridDR-v0"): dict(eps_frames=5_000_000, target_update_period=200, num_sampled_prefs=4),
    ("envelope", "MOSuperMarioBrosZeroShot-v2"): dict(batch_size=64, init_random_frames=25_000, buffer_size=100_000,
                                                      eps_start=0.2, eps_end=0.01, hidden=(512, 512)),
    ("capql", "MOHumanoidDR-v5"): dict(init_random_frames=25_000),
    ("mosac", "MOHopperDR-v5"): dict(init_random_frames=10_000),
    ("mosac", "MOHumanoidDR-v5"): dict(init_random_frames=5_000),
    ("mosac_discrete", "MOLavaGridDR-v0"): dict(target_update_period=200),
    # MORL/D: target periods in updates (the authors' are in frames, one update per 4 member frames)
    **{(a, "MOHalfCheetahDR-v5"): dict(exchange_every=10_000) for a in ("morld", "morld_psa")},
    **{(a, "MOHopperDR-v5"): dict(init_random_frames=10_000) for a in ("morld", "morld_psa")},
    **{(a, "MOHumanoidDR-v5"): dict(init_random_frames=5_000) for a in ("morld", "morld_psa")},
    **{(a, "MOLunarLanderDR-v0"): dict(_MORLD_DISCRETE, target_update_period=500, target_entropy_scale=0.3)
       for a in ("morld", "morld_psa")},
    **{(a, "MOLavaGridDR-v0"): dict(_MORLD_DISCRETE, pop_size=5, exchange_every=10_000, target_update_period=50)
       for a in ("morld", "morld_psa")},
    ("sac", "MOLunarLanderDR-v0"): dict(tau=None, batch_size=128, target_update_period=2000, target_entropy_scale=0.3,
                                        init_random_frames=20_000),
    ("sac", "MOLavaGridDR-v0"): dict(tau=None, batch_size=128, target_update_period=200, target_entropy_scale=0.89,
                                     init_random_frames=20_000),
    ("sac", "MOSuperMarioBrosZeroShot-v2"): dict(tau=None, batch_size=64, buffer_size=100_000,
                                                 target_update_period=1000, target_entropy_scale=0.5,
                                                 init_random_frames=20_000, hidden=(512, 512)),
    **{("pcn", d): v for d, v in _PCN_DOMAIN.items()},
    ("pgmorl", "MOHopperDR-v5"): dict(pgmorl_pop=6, pgmorl_warmup=200, pgmorl_evo_iterations=40,
                                      pgmorl_num_buffers=210, pgmorl_sparsity=-1e6, pgmorl_delta_weight=0.25),
    ("pgmorl", "MOHalfCheetahDR-v5"): dict(pgmorl_warmup=80, pgmorl_evo_iterations=20, pgmorl_num_buffers=100,
                                           pgmorl_sparsity=-1.0, pgmorl_delta_weight=0.2),
    ("pgmorl", "MOHumanoidDR-v5"): dict(pgmorl_pop=6, pgmorl_warmup=200, pgmorl_evo_iterations=40,
                                        pgmorl_num_buffers=100, pgmorl_sparsity=-1.0, pgmorl_delta_weight=0.2),
    ("gpi_ls", "MOLunarLanderDR-v0"): dict(gpi_front_episodes=3),
    ("gpi_ls", "MOLavaGridDR-v0"): dict(eps_frames=5_000_000, target_update_period=200),
    ("gpi_ls", "MOSuperMarioBrosZeroShot-v2"): dict(hidden=(512, 512), eps_start=0.2, eps_end=0.01, batch_size=64,
                                                    init_random_frames=25_000, buffer_size=100_000,
                                                    gpi_layer_norm=False, eval_weights=32),
    ("gpi_pd", "MOLunarLanderDR-v0"): dict(gpi_front_episodes=3, gpi_uncertainty_threshold=20.0,
                                           gpi_dynamics_train_freq=5_000, gpi_dynamics_rollout_freq=5_000),
    ("gpi_pd", "MOLavaGridDR-v0"): dict(eps_frames=5_000_000, target_update_period=200,
                                        gpi_uncertainty_threshold=1e4, gpi_dynamics_lr=3e-5,
                                        gpi_dynamics_hidden=(512, 512)),
}
# continuous GPI-LS / GPI-PD: the authors' GPIPDContinuousAction defaults with SPEC's script values
_GPI_CONTINUOUS = dict(tau=0.005, batch_size=256, init_random_frames=25_000, buffer_size=1_000_000,
                       gpi_gradient_updates=1, gpi_min_priority=0.1, gpi_dynamics_hidden=(200, 200, 200, 200),
                       gpi_dynamics_rollout_len=5, gpi_dynamics_rollout_starts=1_000, gpi_dynamics_rollout_batch=50_000,
                       gpi_dynamics_buffer=200_000, gpi_uncertainty_threshold=2.0, gpi_real_ratio=0.1,
                       gpi_dynamics_normalize=True)
for _algo in ("gpi_ls", "gpi_pd"):
    _ALGO_DOMAIN[(_algo, "MOHopperDR-v5")] = dict(_GPI_CONTINUOUS, gpi_iteration_frames=50_000)
    _ALGO_DOMAIN[(_algo, "MOHalfCheetahDR-v5")] = dict(_GPI_CONTINUOUS, gpi_iteration_frames=25_000)
    _ALGO_DOMAIN[(_algo, "MOHumanoidDR-v5")] = dict(_GPI_CONTINUOUS, gpi_iteration_frames=25_000)
_ALGO_DOMAIN[("gpi_pd", "MOHopperDR-v5")].update(gpi_dynamics_train_freq=2_000, gpi_dynamics_rollout_freq=2_000,
                                                 gpi_real_ratio=0.5)
_ALGO_DOMAIN[("gpi_pd", "MOHalfCheetahDR-v5")].update(gpi_dynamics_train_freq=4_000, gpi_dynamics_rollout_freq=4_000,
                                                      gpi_uncertainty_threshold=10.0)
_ALGO_DOMAIN[("gpi_pd", "MOHumanoidDR-v5")].update(gpi_dynamics_train_freq=5_000, gpi_dynamics_rollout_freq=5_000,
                                                   gpi_uncertainty_threshold=1e4, gpi_dynamics_lr=3e-5,
                                                   gpi_dynamics_hidden=(512, 512))
# --quick: a few CPU minutes on 2 cores, learning visibly on the default domains.
_QUICK = dict(
    frames=60_000, num_envs=16, frames_per_batch=64, updates_per_batch=16, init_random_frames=2_000,
    buffer_size=100_000, hidden=(128, 128), eps_frames=30_000, target_update_period=250, eval_interval=30_000,
    eval_weights=8, checkpoint_interval=20_000,
)
# --quick per algorithm, on top of _QUICK (MORL/D: num_envs sub-envs per member; PCN: fewer random
# warm-up episodes than the authors' 1000; PGMORL: shorter iterations; GPI-LS / GPI-PD: several
# weight-support iterations, cheaper model fits and rollouts)
_QUICK_ALGO = {
    "gpi_ls": dict(gpi_iteration_frames=10_000),
    "gpi_pd": dict(gpi_iteration_frames=10_000, gpi_dynamics_train_freq=5_000, gpi_dynamics_rollout_freq=1_000,
                   gpi_dynamics_rollout_batch=5_000),
    **{a: dict(num_envs=2, frames_per_batch=60, updates_per_batch=0, update_frequency=1) for a in ("morld", "morld_psa")},
    "pcn": dict(pcn_er_episodes=50, init_random_frames=0),
    "pgmorl": dict(num_envs=24, frames_per_batch=24 * 256, init_random_frames=0, pgmorl_warmup=4,
                   pgmorl_evo_iterations=2, pgmorl_minibatches=8,
                   # an iteration counts one member's 4 x 256 frames (the authors' count): 10 iterations
                   frames=10_240, eval_interval=5_120, checkpoint_interval=3_072),
}


def config_values(values: dict[str, Any], source: str) -> dict[str, Any]:
    """The typed config keys of a mapping that may hold ``{group: {key: value}}`` tables (what a
    config file or a grid's table gives); unknown keys raise, naming ``source`` and the valid keys."""
    return _coerce(_flatten(values, source))


def load_config_file(path: str | Path) -> dict[str, Any]:
    """Read overrides from a ``.toml`` or ``.json`` file (flat keys of :class:`TrainConfig`)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"config file {str(path)!r} does not exist")
    text = path.read_bytes()
    try:
        if path.suffix == ".toml":
            data = tomllib.loads(text.decode())
        elif path.suffix == ".json":
            data = json.loads(text)
        else:
            raise ValueError(f"config file {str(path)!r}: use a .toml or .json file")
    except (tomllib.TOMLDecodeError, json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ValueError(f"config file {str(path)!r} does not parse: {err}") from None
    if not isinstance(data, dict):
        raise ValueError(f"config file {str(path)!r} holds a {type(data).__name__}, not a table of keys")
    return config_values(data, f"config file {str(path)!r}")


def resolve_config(
    algo: str,
    env_id: str,
    *,
    quick: bool = False,
    config_file: str | Path | None = None,
    **overrides: Any,
) -> TrainConfig:
    """Build the :class:`TrainConfig` of a run (see the module docstring for the order).

    Example:
        >>> cfg = resolve_config("envelope", "MOLunarLanderDR-v0", seed=3)
        >>> cfg.history_len, cfg.batch_size, cfg.frames
        (2, 128, 3000000)
    """
    from_file = load_config_file(config_file) if config_file is not None else {}
    if "algo" in from_file and from_file["algo"] != algo:
        raise ValueError(f"config file {str(config_file)!r} is for algo {from_file['algo']!r}, not {algo!r}")
    env_id = from_file.get("env_id", env_id)  # a recipe file may name its domain
    if algo not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {algo!r}; valid: {list(ALGORITHMS)}")
    from morl_trl.envs import domain_of, load_domain_modules

    modules = overrides.get("domain_modules") or from_file.get("domain_modules") or ()
    load_domain_modules(modules)
    spec = domain_of(env_id)  # raises with close matches on an unknown id
    train_id = spec.train_id
    values: dict[str, Any] = {"algo": algo, "env_id": env_id}
    values.update(frames=spec.train_frames, history_len=spec.history_len, eval_interval=spec.eval_interval,
                  eval_weights=spec.eval_weights)
    values.update(_ALGO[algo])
    values.update(_ALGO_DOMAIN.get((algo, train_id), {}))
    if spec.foreign:  # no paper record: MORL-Baselines' constructor defaults (recipes/foreign_defaults.py)
        from morl_trl.recipes.foreign_defaults import FOREIGN_DEFAULTS, FOREIGN_DEFAULTS_CONTINUOUS

        values.update(FOREIGN_DEFAULTS.get(algo, {}))
        if algo in FOREIGN_DEFAULTS_CONTINUOUS and not _discrete_actions(spec):
            values.update(FOREIGN_DEFAULTS_CONTINUOUS[algo])
    if quick:
        values.update(_QUICK)
        values.update(_QUICK_ALGO.get(algo, {}))
    values.update(from_file)
    values.update(_coerce({k: v for k, v in overrides.items() if v is not None}))
    cfg = TrainConfig(**_coerce(values)).validate()
    check_env_fits(cfg, spec)
    return cfg


def _discrete_actions(spec) -> bool:
    """Whether the domain's env has discrete actions (one sub-env built to read its spec)."""
    from morl_trl.envs import make_env

    env = make_env(spec.train_id, num_envs=1, seed=0)
    try:
        return env.action_spec.domain == "discrete"
    finally:
        env.close()


def check_env_fits(cfg: TrainConfig, spec) -> None:
    """Refuse, with a clear error, a run whose env the algorithm or the evaluation cannot handle:
    a hypervolume without a reference point, SAC without an original scalar reward, PGMORL on
    discrete actions (the authors' PGMORL is continuous-only)."""
    k = spec.num_objectives
    ref = cfg.ref_point if cfg.ref_point is not None else spec.hv_ref_point
    if ref is None:
        raise ValueError(f"{spec.train_id} has no documented hypervolume reference point: pass one with "
                         f"ref_point=[...] (a config key), {k} numbers that every return of interest dominates "
                         f"(objectives {list(spec.objective_names)})")
    if len(ref) != k:
        raise ValueError(f"ref_point {list(ref)} has {len(ref)} numbers; {spec.train_id} has {k} objectives "
                         f"{list(spec.objective_names)}")
    if spec.foreign and cfg.algo == "sac":
        raise ValueError(f"sac trains on the env's original scalar reward; {spec.train_id} has a vector reward only "
                         f"(use a multi-objective method: {[a for a in ALGORITHMS if a != 'sac']})")
    if spec.foreign and cfg.algo == "pgmorl":  # (the other builders refuse the wrong action space themselves)
        if _discrete_actions(spec):
            raise ValueError(f"pgmorl needs continuous actions (the authors' PGMORL is continuous-only); "
                             f"{spec.train_id} has discrete ones: use envelope, gpi_ls, gpi_pd, pcn or morld")


def quick_preset(algo: str | None = None) -> dict[str, Any]:
    """The values ``--quick`` sets (for ``algo``: with its own quick overrides)."""
    return {**_QUICK, **(_QUICK_ALGO.get(algo, {}) if algo else {})}


#: the keys a resume may change (``morl-trl train ... --resume``): where and how fast it runs,
#: how long (``frames``: extend a run, or stop it earlier), what it logs to. Every other key
#: must equal the run's ``config.json``.
RESUME_MAY_CHANGE = ("frames", "device", "num_threads", "logger", "progress", "run_dir", "compile", "compile_mode",
                     "cudagraphs", "finite_check_interval")


def resume_config(saved: TrainConfig, given: dict[str, Any], source: str) -> TrainConfig:
    """The config a resumed run continues with: ``saved`` (the run's ``config.json``) with the
    keys of ``given`` that a resume may change (:data:`RESUME_MAY_CHANGE`, but ``run_dir``)
    applied. Any other key of ``given`` whose value differs from the run's raises a
    ``ValueError`` naming the key and both values (``source`` says where ``given`` came from)."""
    given = _coerce(dict(given))
    changes = {}
    for key, value in given.items():
        if key == "run_dir":
            continue
        if key in RESUME_MAY_CHANGE:
            changes[key] = value
            continue
        old = getattr(saved, key)
        if value != old:
            raise ValueError(
                f"cannot resume: {key} is {value!r} in {source} but {old!r} in the run's config.json; "
                f"a resume continues the run as it was (only {[k for k in RESUME_MAY_CHANGE if k != 'run_dir']} may change): "
                f"drop {key} or start a new run"
            )
    return dataclasses.replace(saved, **changes).validate()
