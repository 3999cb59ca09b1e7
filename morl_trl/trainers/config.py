"""Training configuration: one flat dataclass, the paper's defaults per (algorithm, domain), presets.

Resolution order (later wins): the algorithm's defaults -> the paper's values for the domain
(SPEC §4) -> the ``quick`` preset (if asked) -> a TOML/JSON config file -> command-line flags.
Unknown keys anywhere raise a ``ValueError`` that lists the valid ones.
"""

from __future__ import annotations

import dataclasses
import json
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["TrainConfig", "ALGORITHMS", "resolve_config", "load_config_file"]

ALGORITHMS = ("envelope", "capql", "mosac", "mosac_discrete")


@dataclass
class TrainConfig:
    """Every knob of a training run (see :func:`resolve_config` for where values come from)."""

    algo: str = "envelope"
    env_id: str = "MOLavaGridDR-v0"
    seed: int = 0
    device: str = "cpu"
    num_threads: int = 1                # torch CPU threads; 1 avoids OpenMP oversubscription with small nets (0: torch's default)
    frames: int = 1_000_000
    num_envs: int = 16
    frames_per_batch: int = 64          # environment frames per collector batch (all sub-envs)
    init_random_frames: int = 1_000     # uniformly random actions before learning starts
    buffer_size: int = 1_000_000
    batch_size: int = 128
    updates_per_batch: int = 0          # 0: one gradient update per collected frame (frames_per_batch)
    lr: float = 3e-4
    gamma: float | None = None          # None: the domain's evaluation discount
    hidden: tuple[int, ...] = (256, 256, 256, 256)
    history_len: int = 0                # StateActionHistory length (2 for LunarLander and MuJoCo in the paper)
    # targets: hard copy every `target_update_period` updates, or Polyak with tau
    target_update_period: int = 1000
    tau: float | None = None
    # DQN-style exploration
    eps_start: float = 1.0
    eps_end: float = 0.05
    eps_frames: int = 1_000_000
    # Envelope
    num_sampled_prefs: int = 8
    homotopy_lambda0: float = 0.95
    homotopy_frames: int | None = None  # None: over the whole run
    prioritized: bool = True
    per_alpha: float = 0.6
    per_beta: float = 0.4
    # actor-critic (CAPQL, MOSAC)
    alpha: float = 0.2
    learn_alpha: bool = False
    target_entropy_scale: float = 0.3   # discrete MOSAC: fraction of max entropy
    # evaluation
    eval_interval: int = 50_000
    eval_weights: int = 100
    eval_episodes: int = 1
    eval_contexts: tuple[str, ...] | None = None  # None: the domain's evaluation suite
    reference_dir: str | None = None    # the published data, for NHGR/EUGR against the paper's specialists
    eval_random_baseline: bool = True   # also evaluate a uniformly random policy at the end, for the report
    # bookkeeping
    run_dir: str | None = None
    checkpoint_interval: int = 50_000
    logger: str = "csv"                 # csv | tensorboard | wandb
    progress: bool = True

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=2, sort_keys=True))

    @classmethod
    def load(cls, path: str | Path) -> "TrainConfig":
        return cls(**_coerce(json.loads(Path(path).read_text())))


_FIELDS = {f.name: f for f in dataclasses.fields(TrainConfig)}


def _coerce(values: dict[str, Any]) -> dict[str, Any]:
    unknown = sorted(set(values) - set(_FIELDS))
    if unknown:
        raise ValueError(f"unknown config key(s) {unknown}; valid keys: {sorted(_FIELDS)}")
    out = {}
    for k, v in values.items():
        if k in ("hidden", "eval_contexts") and v is not None:
            v = tuple(v)
        out[k] = v
    return out


# --------------------------------------------------------------------------- defaults
# The paper's settings (SPEC §4): the domain's protocol comes from its DomainSpec, then the
# algorithm's defaults, then (algorithm, domain) overrides.
_ALGO = {
    "envelope": dict(batch_size=128, target_update_period=1000, prioritized=True, homotopy_lambda0=0.95,
                     num_sampled_prefs=8, eps_start=1.0, eps_end=0.05, eps_frames=1_000_000),
    "capql": dict(batch_size=256, tau=0.005, alpha=0.2, init_random_frames=1_000, prioritized=False),
    "mosac": dict(batch_size=256, tau=0.005, alpha=0.2, learn_alpha=True, init_random_frames=10_000,
                  prioritized=False),
    "mosac_discrete": dict(batch_size=128, target_update_period=2000, learn_alpha=True,
                           target_entropy_scale=0.3, prioritized=False),
}
_ALGO_DOMAIN = {
    ("envelope", "MOLavaGridDR-v0"): dict(eps_frames=5_000_000, target_update_period=200),
    ("envelope", "MOSuperMarioBrosZeroShot-v2"): dict(batch_size=64, init_random_frames=25_000, buffer_size=100_000,
                                                      eps_start=0.2, eps_end=0.01, hidden=(512, 512)),
    ("capql", "MOHumanoidDR-v5"): dict(init_random_frames=25_000),
    ("mosac", "MOHopperDR-v5"): dict(init_random_frames=10_000),
    ("mosac", "MOHumanoidDR-v5"): dict(init_random_frames=5_000),
    ("mosac_discrete", "MOLavaGridDR-v0"): dict(target_update_period=200),
}
# --quick: a few CPU minutes on 2 cores, learning visibly on the default domains.
_QUICK = dict(
    frames=60_000, num_envs=16, frames_per_batch=64, updates_per_batch=16, init_random_frames=2_000,
    buffer_size=100_000, hidden=(128, 128), eps_frames=30_000, target_update_period=250, eval_interval=30_000,
    eval_weights=8, checkpoint_interval=20_000,
)


def load_config_file(path: str | Path) -> dict[str, Any]:
    """Read overrides from a ``.toml`` or ``.json`` file (flat keys of :class:`TrainConfig`)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"config file {str(path)!r} does not exist")
    text = path.read_bytes()
    if path.suffix == ".toml":
        data = tomllib.loads(text.decode())
    elif path.suffix == ".json":
        data = json.loads(text)
    else:
        raise ValueError(f"config file {str(path)!r}: use a .toml or .json file")
    return _coerce(data)


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
    from morl_trl.envs import domain_of

    spec = domain_of(env_id)  # raises with close matches on an unknown id
    train_id = spec.train_id
    values: dict[str, Any] = {"algo": algo, "env_id": env_id}
    values.update(frames=spec.train_frames, history_len=spec.history_len, eval_interval=spec.eval_interval,
                  eval_weights=spec.eval_weights)
    values.update(_ALGO[algo])
    values.update(_ALGO_DOMAIN.get((algo, train_id), {}))
    if quick:
        values.update(_QUICK)
    values.update(from_file)
    values.update(_coerce({k: v for k, v in overrides.items() if v is not None}))
    return TrainConfig(**_coerce(values))
