"""``TrainConfig``: a run's shared sections plus its algorithm's own dataclass, read as flat keys.

``cfg.batch_size`` reads the key from the section that holds it; a key the algorithm does not have
is an ``AttributeError`` naming the algorithm's keys. Code shared by several algorithms reads a key
some of them lack with ``getattr(cfg, key, default)``, which names at the read what an algorithm
without the key does. ``to_dict()`` (what ``config.json``
holds) and ``to_toml()`` (``morl-trl config ALGO ENV``) hold exactly the algorithm's keys.
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from pathlib import Path
from typing import Any

from morl_trl.recipes.config.keys import KEY_ALIASES, KEYS, NOT_SET, RENAMED_KEYS, coerce_values, unknown_keys_message
from morl_trl.recipes.config.registry import ALGORITHM_SPECS
from morl_trl.recipes.config.sections import SHARED, RunSection

__all__ = ["TrainConfig", "valid_keys", "upgrade_keys", "RENAMED"]


def valid_keys(algo: str) -> tuple[str, ...]:
    """Every key of ``algo``'s config: the shared sections', then its own."""
    shared = tuple(f.name for cls in SHARED.values() for f in dataclasses.fields(cls))
    return shared + ALGORITHM_SPECS[algo].keys


def _pcn_hidden(value: Any, algo: str) -> dict[str, Any]:
    # PCN's old network: an embedding of this width and one hidden layer of it
    return {"hidden": (value, value)} if algo == "pcn" else {}


#: renamed keys: old name -> (what it is now, its new key(s) for a value and the algorithm)
RENAMED = {  # (its names: keys.RENAMED_KEYS)
    "pcn_hidden": ("hidden (PCN: [embedding width, head widths...]; pcn_hidden = h is hidden = [h, h])", _pcn_hidden),
}
#: every key's value before configs were per algorithm, when every algorithm had every key (a file
#: written then, e.g. by ``--print-config``, holds keys its algorithm ignored, at these values)
_V1_DEFAULTS = {'algo': 'envelope', 'env_id': 'MOLavaGridDR-v0', 'seed': 0, 'device': 'cpu', 'num_threads': 1, 'run_dir': None, 'checkpoint_interval': 50000, 'keep_checkpoints': 2, 'logger': 'csv', 'progress': True, 'num_envs': 16, 'history_len': 0, 'gamma': None, 'preference_distribution': 'dirichlet', 'preference_resample': 'episode', 'frames': 1000000, 'frames_per_batch': 64, 'init_random_frames': 1000, 'buffer_size': 1000000, 'batch_size': 128, 'prioritized': True, 'per_alpha': 0.6, 'per_beta': 0.4, 'per_importance_weights': True, 'lr': 0.0003, 'updates_per_batch': 0, 'target_update_period': 1000, 'tau': None, 'max_grad_norm': None, 'fused_optimizer': True, 'compile': False, 'compile_mode': None, 'cudagraphs': False, 'finite_check_interval': 100, 'hidden': (256, 256, 256, 256), 'eps_start': 1.0, 'eps_end': 0.05, 'eps_frames': 1000000, 'num_sampled_prefs': 8, 'homotopy_lambda0': 0.95, 'homotopy_final': None, 'homotopy_frames': None, 'envelope_priority': 'first', 'envelope_network': 'authors', 'alpha': 0.2, 'learn_alpha': False, 'target_entropy_scale': 0.3, 'actor_scale': 'softplus', 'loss_fresh_preferences': False, 'pcn_scaling_factor': None, 'pcn_max_return': None, 'pcn_buffer_episodes': 100, 'pcn_er_episodes': 20, 'pcn_step_episodes': 10, 'pcn_model_updates': 50, 'pcn_noise': 0.1, 'pcn_hidden': 64, 'pgmorl_pop': 6, 'pgmorl_envs_per_member': 4, 'pgmorl_warmup': 80, 'pgmorl_evo_iterations': 20, 'pgmorl_num_buffers': 100, 'pgmorl_buffer_size': 2, 'pgmorl_delta_weight': 0.2, 'pgmorl_sparsity': -1.0, 'pgmorl_epochs': 10, 'pgmorl_minibatches': 32, 'pgmorl_clip': 0.2, 'pgmorl_gae_lambda': 0.95, 'pgmorl_eval_obs': 'raw', 'pop_size': 6, 'exchange_every': 20000, 'weight_adaptation': 'none', 'psa_delta': 0.1, 'update_frequency': 1, 'gpi_iteration_frames': 50000, 'gpi_front_episodes': 5, 'gpi_num_nets': 2, 'gpi_dropout': 0.01, 'gpi_layer_norm': True, 'gpi_gradient_updates': 20, 'gpi_min_priority': 0.01, 'gpi_dynamics_hidden': (256, 256, 256), 'gpi_dynamics_ensemble': 5, 'gpi_dynamics_elites': 2, 'gpi_dynamics_lr': 0.001, 'gpi_dynamics_train_freq': 250, 'gpi_dynamics_rollout_freq': 250, 'gpi_dynamics_rollout_starts': 5000, 'gpi_dynamics_rollout_batch': 25000, 'gpi_dynamics_buffer': 100000, 'gpi_uncertainty_threshold': 1.5, 'gpi_real_ratio': 0.5, 'gpi_dynamics_rollout_len': 1, 'gpi_dynamics_normalize': False, 'gpi_policy_noise': 0.2, 'gpi_noise_clip': 0.5, 'gpi_policy_delay': 2, 'eval_interval': 50000, 'eval_weights': 100, 'eval_episodes': 1, 'eval_exploration': 'deterministic', 'eval_contexts': None, 'reference_dir': None, 'eval_random_baseline': True}
#: keys a config.json written before they existed lacks: the value that reproduces that code
_ADDED_LATER = {"q_lr": None, "alpha_lr": None, "adam_eps": None, "update_frequency": 1, "policy_freq": 1, "alpha_loss_form": "log_alpha", "joint_update": True, "per_running_max": False, "gpi_dynamics_max_logvar": 0.5,
                "gpi_dynamics_max_grad_norm": None, "pgmorl_reset_each_iteration": False,
                "pgmorl_reseed_each_iteration": False,
                "morld_eval_episodes": 0, "morld_schedule": "concurrent", "morld_update_passes": 10,
                "morld_archive_initial": False, "capql_log_prob": "exact",
                "gpi_first_episode": "support", "gpi_update_weight": "iteration"}


def upgrade_keys(values: dict[str, Any], algo: str, source: str, *, saved: bool = False) -> dict[str, Any]:
    """Map renamed keys (with a ``DeprecationWarning``) and check every key is one of ``algo``'s.

    ``saved=True`` (a run's ``config.json``, written when every algorithm had every key): keys
    ``algo`` does not have are dropped (they did nothing) and keys added since get the value that
    reproduces the run's code. Otherwise a key ``algo`` does not have is a ``ValueError`` that
    names the valid keys, unless it holds the value every algorithm had before configs were per
    algorithm (a file written then): it is then dropped with a ``DeprecationWarning``.
    """
    out = dict(values)
    for old, (new, convert) in RENAMED.items():
        if old in out:
            value = out.pop(old)
            if not saved:
                warnings.warn(f"{source}: config key {old!r} is deprecated; use {new}", DeprecationWarning,
                              stacklevel=3)
            out.update(convert(value, algo))
    valid = valid_keys(algo)
    if saved:
        out = {k: v for k, v in out.items() if k in valid}
        for k, v in _ADDED_LATER.items():
            if k in valid and k not in out:
                out[k] = v
        return out
    unknown = sorted(set(out) - set(KEYS))
    if unknown:
        raise ValueError(unknown_keys_message(unknown, valid, source, algo))
    ignored = sorted(k for k in set(out) - set(valid) if k in _V1_DEFAULTS and out[k] == _V1_DEFAULTS[k])
    if ignored:  # what an old complete dump holds: those keys did nothing for this algorithm then either
        warnings.warn(f"{source}: config key(s) {ignored} are not settings of {algo} and are ignored (they hold the "
                      f"values every algorithm had before configs were per algorithm); drop them", DeprecationWarning,
                      stacklevel=3)
        out = {k: v for k, v in out.items() if k not in ignored}
    foreign = sorted(set(out) - set(valid))
    if foreign:
        raise ValueError(unknown_keys_message(foreign, valid, source, algo))
    return out


class TrainConfig:
    """A run's configuration: the shared sections (run, env, eval, logging, compute) and the
    algorithm's own dataclass (:mod:`morl_trl.algorithms.envelope.config`, ...), built from flat keys.

    Example:
        >>> cfg = TrainConfig(frames=1000)
        >>> cfg.algo, cfg.batch_size, cfg.sections["run"].frames
        ('envelope', 128, 1000)
        >>> cfg.group("replay_buffer")["batch_size"]
        128
        >>> TrainConfig(algo="pcn").eps_start
        Traceback (most recent call last):
        ...
        AttributeError: config key 'eps_start' is not a setting of pcn; valid keys of pcn: ['algo', ...] (morl-trl config pcn ENV_ID)
        >>> TrainConfig(algo="pcn").learning_rate
        Traceback (most recent call last):
        ...
        AttributeError: TrainConfig has no attribute 'learning_rate' (did you mean 'lr'?); valid keys of pcn: [...] (morl-trl config pcn ENV_ID)
        >>> TrainConfig(frames=-100).validate()
        Traceback (most recent call last):
        ...
        ValueError: config key 'frames' (collector) is -100; valid: an int in [1, inf]
    """

    def __init__(self, **values: Any) -> None:
        algo = values.get("algo", RunSection.algo)
        if algo not in ALGORITHM_SPECS:
            raise ValueError(f"config key 'algo' (run) is {algo!r}; valid: one of {list(ALGORITHM_SPECS)}")
        spec = ALGORITHM_SPECS[algo]
        unknown = sorted(set(values) - set(valid_keys(algo)))
        if unknown:
            raise ValueError(unknown_keys_message(unknown, valid_keys(algo), "", algo))
        sections = {}
        for name, cls in (*SHARED.items(), (algo, spec.config)):
            sections[name] = cls(**{f.name: values[f.name] for f in dataclasses.fields(cls) if f.name in values})
        owner = {f.name: name for name, s in sections.items() for f in dataclasses.fields(s)}
        object.__setattr__(self, "_sections", sections)
        object.__setattr__(self, "_owner", owner)

    # ------------------------------------------------------------------ flat access
    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        owner = self.__dict__["_owner"]
        if name in owner:
            return getattr(self.__dict__["_sections"][owner[name]], name)
        key = KEYS.get(name)
        algo = self.__dict__["_sections"]["run"].algo
        from morl_trl._suggest import did_you_mean

        hint = "" if key is not None else did_you_mean(name, owner, KEY_ALIASES)
        what = f"config key {name!r} is not a setting of {algo}" if key is not None else \
            f"{type(self).__name__} has no attribute {name!r}"
        raise AttributeError(f"{what}{hint}; valid keys of {algo}: {sorted(owner)} (morl-trl config {algo} ENV_ID)")

    def __setattr__(self, name: str, value: Any) -> None:
        owner = self.__dict__["_owner"]
        if name not in owner:
            raise AttributeError(f"config key {name!r} is not a setting of {self.algo}; valid keys: {sorted(owner)}")
        setattr(self._sections[owner[name]], name, value)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, TrainConfig) and self.to_dict() == other.to_dict()

    def __repr__(self) -> str:
        return f"TrainConfig({', '.join(f'{k}={v!r}' for k, v in self.to_dict().items())})"

    @property
    def sections(self) -> dict[str, Any]:
        """Section name -> its dataclass: ``run``, ``env``, ``eval``, ``logging``, ``compute`` and the algorithm's."""
        return dict(self._sections)

    def keys(self) -> tuple[str, ...]:
        return tuple(self._owner)

    def to_dict(self) -> dict[str, Any]:
        """The flat keys and values (what ``config.json`` holds)."""
        return {k: getattr(self._sections[s], k) for k, s in self._owner.items()}

    def replace(self, **changes: Any) -> "TrainConfig":
        """A copy with ``changes`` applied (flat keys)."""
        return TrainConfig(**{**self.to_dict(), **changes})

    # ------------------------------------------------------------------ checks
    def validate(self) -> "TrainConfig":
        """Check every value (type and range); raise ``ValueError`` naming the key, the value and what is valid."""
        for k, value in self.to_dict().items():
            problem = KEYS[k].problem(value)
            if problem is not None:
                raise ValueError(f"config key {k!r} ({KEYS[k].section}) is {value!r}; valid: {problem}")
        if self.cudagraphs and not str(self.device).startswith("cuda"):
            raise ValueError(f"config key 'cudagraphs' (compile) is true but device is {self.device!r}; "
                             "valid: cudagraphs=true with a cuda device (compile=true works on any device)")
        try:
            from morl_trl.envs import domain_of

            objectives = list(domain_of(self.env_id).objective_names)
        except (ValueError, KeyError):
            objectives = None  # (an unknown id is refused where the env is made, naming close matches)
        if objectives is not None and self.eval_weights < len(objectives):
            raise ValueError(f"config key 'eval_weights' (eval) is {self.eval_weights}; valid: an int >= "
                             f"{len(objectives)} (the evaluation weights include the {len(objectives)} corners of the "
                             f"simplex of the objectives {objectives})")
        if self.compile_mode is not None:  # (torch.compile checks it only at the first update: after a start)
            from torch._inductor import list_mode_options

            modes = sorted(list_mode_options())
            if self.compile_mode not in modes:
                raise ValueError(f"config key 'compile_mode' (compile) is {self.compile_mode!r}; valid: null or one of "
                                 f"{modes}")
        return self

    # ------------------------------------------------------------------ views and files
    def group(self, name: str) -> dict[str, Any]:
        """The keys of a section (``run``, ..., the algorithm's name) or of a key group (``optim``, ...)."""
        if name in self._sections:
            return dataclasses.asdict(self._sections[name])
        keys = {k: v for k, v in self.to_dict().items() if KEYS[k].section == name}
        if not keys:
            groups = sorted({*self._sections, *(KEYS[k].section for k in self._owner)})
            raise ValueError(f"unknown config group {name!r} for {self.algo}; valid: {groups}")
        return keys

    def to_toml(self) -> str:
        """The complete config as TOML: one table per section (``null`` values are written as comments)."""
        lines = []
        for name, section in self._sections.items():
            lines.append(f"[{name}]")
            group = None
            for f in dataclasses.fields(section):
                key = KEYS[f.name]
                if name == self.algo and key.section != group:
                    group = key.section
                    lines.append(f"# {group}")
                value = getattr(section, f.name)
                if value is None:
                    lines.append(f"# {f.name} = null  # {key.help}")
                else:
                    lines.append(f"{f.name} = {_toml_value(value)}  # {key.help}")
            lines.append("")
        return "\n".join(lines)

    def save(self, path: str | Path) -> None:
        """Write ``config.json`` atomically (a kill leaves the old file or the new one, never half)."""
        from morl_trl.runs.atomic import atomic_write_text

        atomic_write_text(path, json.dumps(self.to_dict(), indent=2, sort_keys=True))

    @classmethod
    def load(cls, path: str | Path) -> "TrainConfig":
        """A run's ``config.json`` (also one written by an earlier version: see :func:`upgrade_keys`)."""
        path = Path(path)
        try:
            data = json.loads(path.read_bytes().decode())
        except UnicodeDecodeError as err:
            raise ValueError(f"cannot read the config {str(path)!r}: it is not UTF-8 text (byte "
                             f"{err.object[err.start]:#04x} at position {err.start}): it was damaged or is not a "
                             f"config; restore it from a copy of the run") from None
        except (OSError, json.JSONDecodeError) as err:
            raise ValueError(f"cannot read the config {str(path)!r}: {err}") from None
        if not isinstance(data, dict):
            raise ValueError(f"the config {str(path)!r} holds a {type(data).__name__}, not an object of keys")
        algo = data.get("algo", RunSection.algo)
        if algo not in ALGORITHM_SPECS:
            raise ValueError(f"the config {str(path)!r}: algo is {algo!r}; valid: one of {list(ALGORITHM_SPECS)}")
        return cls(**coerce_values(upgrade_keys(data, algo, str(path), saved=True))).validate()


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, str):
        return json.dumps(v)
    return repr(v)


assert set(RENAMED) == RENAMED_KEYS
