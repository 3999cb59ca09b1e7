"""Where a run's values come from: four layers, later wins.

1. the algorithm's defaults (:func:`algorithm_defaults`): the shared sections' defaults, the values
   its module changes there (``SHARED_DEFAULTS``) and its dataclass's;
2. the domain's table (:func:`domain_values`): the domain's protocol (its
   :class:`~morl_trl.envs.DomainSpec`: frames, history, evaluation period and weights) with the
   algorithm's row on top: the authors' record (the module's ``DEFAULTS``) on a paper domain,
   MORL-Baselines' constructor defaults (:mod:`morl_trl.recipes.foreign_defaults`) on a foreign env;
3. config files: ``--quick``'s preset file (``quick.toml``, the algorithm's table), then ``--config``;
4. the command line's ``KEY=VALUE`` overrides and flags.

Every key of layers 2-4 is one of the algorithm's (any other is an error naming the valid keys).

Example:
    >>> cfg = resolve_config("envelope", "MOLunarLanderDR-v0", seed=3)
    >>> cfg.history_len, cfg.batch_size, cfg.frames
    (2, 128, 3000000)
"""

from __future__ import annotations

import dataclasses
import json
import tomllib
from pathlib import Path
from typing import Any

from morl_trl.recipes.config.keys import ALGORITHMS, KEYS, SHARED_SECTIONS, coerce_values, unknown_keys_message
from morl_trl.recipes.config.registry import ALGORITHM_SPECS
from morl_trl.recipes.config.sections import SHARED
from morl_trl.recipes.config.train_config import TrainConfig, upgrade_keys, valid_keys

__all__ = ["resolve_config", "load_config_file", "quick_preset", "coerce_values", "flatten_tables",
           "RESUME_MAY_CHANGE", "resume_config", "check_env_fits", "algorithm_defaults", "domain_values", "defaults",
           "config_values", "QUICK_PATH", "PROTOCOL_KEYS"]

#: table names a config file may group keys under: the sections, the algorithms, and the groups of
#: earlier versions (``[replay_buffer]``, ``[optim]``, ...)
_TABLES = frozenset({*SHARED_SECTIONS, *ALGORITHM_SPECS, *(k.section for k in KEYS.values()), "collector", "compile",
                     "actor_critic"})
#: ``--quick``'s preset file: one table per algorithm
QUICK_PATH = Path(__file__).parent / "quick.toml"
#: the keys a domain's protocol sets (its :class:`~morl_trl.envs.DomainSpec`)
PROTOCOL_KEYS = ("frames", "history_len", "eval_interval", "eval_weights")


def flatten_tables(values: dict[str, Any], source: str) -> dict[str, Any]:
    """Flat keys from a mapping that may hold ``{section: {key: value}}`` tables."""
    flat: dict[str, Any] = {}
    for k, v in values.items():
        if k in _TABLES and isinstance(v, dict) and k not in KEYS:
            flat.update(v)
        else:
            flat[k] = v
    return flat


def load_config_file(path: str | Path) -> dict[str, Any]:
    """Read overrides from a ``.toml`` or ``.json`` file (flat keys, or keys in section tables)."""
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


def quick_preset(algo: str) -> dict[str, Any]:
    """The values ``--quick`` sets for ``algo``: its table of the preset file :data:`QUICK_PATH`."""
    with QUICK_PATH.open("rb") as f:
        tables = tomllib.load(f)
    return upgrade_keys(config_values(tables[algo], f"{QUICK_PATH.name} [{algo}]"), algo, f"{QUICK_PATH.name} [{algo}]")


def algorithm_defaults(algo: str) -> dict[str, Any]:
    """Layer 1: every key of ``algo`` at its default (the shared sections', the shared values its
    module changes, its dataclass's)."""
    spec = ALGORITHM_SPECS[algo]
    values = {f.name: f.default for cls in SHARED.values() for f in dataclasses.fields(cls)}
    values.update(spec.shared)
    values.update({f.name: f.default for f in dataclasses.fields(spec.config)})
    values["algo"] = algo
    return values


def domain_values(algo: str, env_id: str) -> dict[str, Any]:
    """Layer 2: ``algo``'s table for the domain of ``env_id``: the domain's protocol, with the
    authors' values for the pair on top (a foreign env, which has no record: MORL-Baselines'
    constructor defaults, :mod:`morl_trl.recipes.foreign_defaults`)."""
    from morl_trl.envs import domain_of

    spec = domain_of(env_id)  # raises with close matches on an unknown id
    values: dict[str, Any] = {"env_id": env_id, "frames": spec.train_frames, "history_len": spec.history_len,
                              "eval_interval": spec.eval_interval, "eval_weights": spec.eval_weights}
    values.update(ALGORITHM_SPECS[algo].domains.get(spec.train_id, {}))
    if spec.foreign:
        from morl_trl.recipes.foreign_defaults import FOREIGN_DEFAULTS, FOREIGN_DEFAULTS_CONTINUOUS

        values.update(FOREIGN_DEFAULTS.get(algo, {}))
        if algo in FOREIGN_DEFAULTS_CONTINUOUS and not _discrete_actions(spec):
            values.update(FOREIGN_DEFAULTS_CONTINUOUS[algo])
    return values


def defaults(algo: str, env_id: str) -> dict[str, Any]:
    """``algo``'s values on ``env_id`` before any file or flag: layers 1 and 2."""
    return {**algorithm_defaults(algo), **domain_values(algo, env_id)}


def _check_tables() -> None:
    """Every key of every algorithm's tables is one of its keys (nothing is dropped as inert), and no
    algorithm changes a key of the domain's protocol (layer 2 starts with it)."""
    from morl_trl.recipes.foreign_defaults import FOREIGN_DEFAULTS, FOREIGN_DEFAULTS_CONTINUOUS

    for algo, spec in ALGORITHM_SPECS.items():
        valid = valid_keys(algo)
        tables = {"SHARED_DEFAULTS": spec.shared, **{f"DEFAULTS[{d!r}]": t for d, t in spec.domains.items()},
                  "FOREIGN_DEFAULTS": FOREIGN_DEFAULTS.get(algo, {}),
                  "FOREIGN_DEFAULTS_CONTINUOUS": FOREIGN_DEFAULTS_CONTINUOUS.get(algo, {})}
        for name, table in tables.items():
            unknown = set(table) - set(valid)
            if unknown:
                raise AssertionError(unknown_keys_message(unknown, valid, f"{algo} {name}", algo))
        protocol = set(spec.shared) & set(PROTOCOL_KEYS)
        assert not protocol, (algo, protocol)


def resolve_config(
    algo: str,
    env_id: str,
    *,
    quick: bool = False,
    config_file: str | Path | None = None,
    **overrides: Any,
) -> TrainConfig:
    """Build the :class:`TrainConfig` of a run (the module docstring's four layers).

    A key ``algo`` does not have (in the file or the overrides) is an error naming its valid keys;
    a renamed key is mapped, with a ``DeprecationWarning``.

    Example:
        >>> resolve_config("pcn", "MOLavaGridDR-v0", eps_start=0.5)
        Traceback (most recent call last):
        ...
        ValueError: overrides: config key 'eps_start' is not a setting of pcn; morl-trl config pcn ENV_ID prints every key of pcn
    """
    if algo not in ALGORITHM_SPECS:
        raise ValueError(f"unknown algorithm {algo!r}; valid: {list(ALGORITHM_SPECS)}")
    from_file = load_config_file(config_file) if config_file is not None else {}
    if "algo" in from_file and from_file["algo"] != algo:
        raise ValueError(f"config file {str(config_file)!r} is for algo {from_file['algo']!r}, not {algo!r}")
    if from_file:
        from_file = upgrade_keys(from_file, algo, f"config file {str(config_file)!r}")
    env_id = from_file.get("env_id", env_id)  # a recipe file may name its domain
    from morl_trl.envs import domain_of, load_domain_modules

    load_domain_modules(overrides.get("domain_modules") or from_file.get("domain_modules") or ())
    values = algorithm_defaults(algo)  # 1
    values.update(domain_values(algo, env_id))  # 2
    if quick:  # 3
        values.update(quick_preset(algo))
    values.update(from_file)
    given = coerce_values({k: v for k, v in overrides.items() if v is not None})  # 4
    values.update(upgrade_keys(given, algo, "overrides"))
    cfg = TrainConfig(**coerce_values(values)).validate()
    check_env_fits(cfg, domain_of(env_id))
    return cfg


def _discrete_actions(spec) -> bool:
    """Whether the domain's env has discrete actions (one sub-env built to read its spec)."""
    from morl_trl.envs import make_env

    env = make_env(spec.train_id, num_envs=1, seed=0)
    try:
        return env.action_spec.domain == "discrete"
    finally:
        env.close()


def config_values(values: dict[str, Any], source: str) -> dict[str, Any]:
    """The typed config keys of a mapping that may hold ``{section: {key: value}}`` tables (what a
    config file or a grid's table gives); unknown keys raise, naming ``source`` and the valid keys."""
    return coerce_values(flatten_tables(values, source))


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
    given = coerce_values(dict(given))
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
    return saved.replace(**changes).validate()


_check_tables()
