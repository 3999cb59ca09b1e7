"""The key blocks several algorithms share, written once: the DQN family's (Envelope, GPI-LS/PD) and
the actor-critic family's (CAPQL, SAC, MOSAC, MORL/D), and :func:`algorithm_config`, which builds
an algorithm's dataclass from such blocks.

A block is an ordered ``{key: default}`` (MORL-Baselines' values, which the algorithms' tables
then set per domain); a key's type and meaning are in :data:`~morl_trl.recipes.config.keys.KEYS`.
An algorithm takes the keys it has, in the block's order (the order ``morl-trl config`` prints),
and changes the defaults that differ for it.

Example:
    >>> Cfg = algorithm_config("Cfg", "doc", pick(DQN_OPTIM, max_grad_norm=1.0), {"num_sampled_prefs": 8})
    >>> [f.name for f in dataclasses.fields(Cfg)][-2:], Cfg().max_grad_norm
    (['max_grad_norm', 'num_sampled_prefs'], 1.0)
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Iterable, Mapping
from typing import Any

from morl_trl.recipes.config.domains import frozen
from morl_trl.recipes.config.keys import KEYS

__all__ = ["DQN_REPLAY", "DQN_OPTIM", "DQN_EXPLORATION", "ACTOR_CRITIC", "pick", "algorithm_config"]

#: the DQN family's replay: PER without importance weights (MORL-Baselines' Envelope and GPI-PD)
DQN_REPLAY = frozen(dict(frames_per_batch=64, init_random_frames=100, buffer_size=1_000_000, batch_size=128,
                         prioritized=True, per_alpha=0.6, per_beta=0.4, per_importance_weights=False))
#: the DQN family's optimisation: one update per frame, a hard target copy every 1000 frames
DQN_OPTIM = frozen(dict(lr=3e-4, updates_per_batch=0, target_update_period=1000, tau=None, max_grad_norm=None))
#: the DQN family's epsilon-greedy: 1 -> 0.05 over 1M frames after learning_starts
DQN_EXPLORATION = frozen(dict(eps_start=1.0, eps_end=0.05, eps_frames=1_000_000))

#: the actor-critic family's keys in the order every member prints them (each takes the ones it has):
#: MORL-Baselines' SAC values, Polyak 0.005, no PER, four hidden layers of 256 (CAPQL: see its module)
ACTOR_CRITIC = frozen(dict(
    frames_per_batch=64, init_random_frames=1_000, buffer_size=1_000_000, batch_size=256, prioritized=False,
    per_alpha=0.6, per_beta=0.4, per_importance_weights=True,
    lr=3e-4, q_lr=None, alpha_lr=None, adam_eps=None, updates_per_batch=0, update_frequency=1, tau=0.005,
    target_update_period=1000, max_grad_norm=None,
    hidden=(256, 256, 256, 256), alpha=0.2, learn_alpha=True, target_entropy_scale=0.3,
    # the authors' SAC/MOSAC actor: log_std = -5 + 3.5 (tanh(x) + 1), 2 actor steps after every 2nd critic step
    actor_scale="tanh_log_std", policy_freq=2,
    # the temperature's loss: -alpha (log pi + target), the authors' CleanRL-style SAC (sac_continuous_action.py:
    # alpha_loss = (-log_alpha.exp() * (log_pi + target_entropy)).mean()); MOSAC's members take -log alpha (below)
    alpha_loss_form="alpha", joint_update=False,
))


def pick(block: Mapping[str, Any], keys: Iterable[str] | None = None, **changes: Any) -> dict[str, Any]:
    """``keys`` of ``block`` (default: all) in the block's order, with ``changes`` to their defaults."""
    keys = list(block) if keys is None else list(keys)
    unknown = [k for k in [*keys, *changes] if k not in block]
    if unknown:
        raise KeyError(f"{unknown} are not in the block {list(block)}")
    return {k: changes.get(k, block[k]) for k in block if k in keys}


def algorithm_config(name: str, doc: str, *blocks: Mapping[str, Any]) -> type:
    """A dataclass ``name`` whose fields are the blocks' keys in order (types from ``KEYS``),
    defined in the calling module."""
    fields, seen = [], set()
    for block in blocks:
        for key, default in block.items():
            if key in seen:
                raise ValueError(f"{name}: key {key!r} given twice")
            seen.add(key)
            fields.append((key, KEYS[key].type, dataclasses.field(default=default)))
    cls = dataclasses.make_dataclass(name, fields)
    cls.__doc__ = doc
    cls.__module__ = sys._getframe(1).f_globals["__name__"]
    return cls
