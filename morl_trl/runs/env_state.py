"""The running state of a training env, for checkpoints that resume exactly.

:func:`env_state` captures what a batched env stack carries between two collector batches
(besides the TensorDict the collector holds): the simulator state of the base env when it
can snapshot it (:meth:`~morl_trl.envs.base.ContextualMOEnv.simulator_state`, opt-in per
domain: MO-LavaGrid and the MuJoCo domains can, Box2D's MO-LunarLander and Mario cannot), and every transform's
running state: its random generator, seed bookkeeping, and the attributes some transforms
keep outside the TensorDict (``StateActionHistory``'s history, ``PreferenceConditioning``'s
current preferences, cursor and a next preference not yet given) plus any registered buffers; and the stream of the base env's
context sampler (domain randomization draws inside the env).
"""

from __future__ import annotations

from typing import Any

import torch
from torchrl.envs import TransformedEnv

__all__ = ["env_state", "load_env_state", "load_context_sampler_state", "can_snapshot", "base_env_of", "transforms_of"]

# attributes (outside buffers) in which morl_trl's transforms keep running state
_ATTRS = ("_history", "_current", "_cursor", "_seed", "_env_seed_seen", "_checked_parent", "_first", "_first_left")


def base_env_of(env):
    while isinstance(env, TransformedEnv):
        env = env.base_env
    return env


def transforms_of(env) -> list:
    """The transforms of a (nested) ``TransformedEnv``, outermost env's last."""
    out = []
    while isinstance(env, TransformedEnv):
        t = env.transform
        out = (list(t) if hasattr(t, "__iter__") else [t]) + out
        env = env.base_env
    return out


def can_snapshot(env) -> bool:
    """Whether the base env of ``env`` can capture and restore its simulator state."""
    base = base_env_of(env)
    check = getattr(base, "can_snapshot", None)
    return bool(check()) if callable(check) else False


def _copy(v):
    return v.detach().clone() if isinstance(v, torch.Tensor) else v


def _transform_state(t) -> dict[str, Any]:
    state: dict[str, Any] = {"buffers": {k: _copy(v) for k, v in t.state_dict().items()}}
    for name in _ATTRS:
        if name in t.__dict__:
            v = t.__dict__[name]
            if v is None or isinstance(v, (bool, int, float, torch.Tensor)):  # (not sentinels)
                state[name] = _copy(v)
    gen = t.__dict__.get("generator")
    if isinstance(gen, torch.Generator):
        state["generator"] = gen.get_state()
    return state


def _load_transform_state(t, state: dict[str, Any]) -> None:
    if state["buffers"]:
        t.load_state_dict(state["buffers"])
    for name in _ATTRS:
        if name in state:
            t.__dict__[name] = _copy(state[name])  # (plain attributes, as the transforms set them)
    if "generator" in state:
        t.__dict__["generator"].set_state(state["generator"])


def env_state(env, *, simulator: bool = True) -> dict[str, Any]:
    """The running state of ``env`` (a ``TransformedEnv`` stack or a base env)."""
    base = base_env_of(env)
    sim = base.simulator_state() if simulator and can_snapshot(env) else None
    sampler = getattr(base, "context_sampler", None)
    return {"simulator": sim, "transforms": [_transform_state(t) for t in transforms_of(env)],
            "context_sampler": None if sampler is None else sampler.get_state()}


def load_context_sampler_state(env, state: dict[str, Any]) -> None:
    """Restore the base env's context sampler (domain randomization) stream from :func:`env_state`."""
    sampler = getattr(base_env_of(env), "context_sampler", None)
    saved = state.get("context_sampler")
    if (sampler is None) != (saved is None):
        raise ValueError("the checkpoint and the env disagree on domain randomization: "
                         f"the env {'has no' if sampler is None else 'has a'} context sampler, the checkpoint "
                         f"{'holds none' if saved is None else 'holds one'}")
    if sampler is not None:
        sampler.set_state(saved)


def load_env_state(env, state: dict[str, Any], *, simulator: bool = True) -> None:
    """Restore what :func:`env_state` captured (the simulator too when ``simulator`` and captured)."""
    transforms = transforms_of(env)
    if len(transforms) != len(state["transforms"]):
        raise ValueError(f"the checkpoint holds {len(state['transforms'])} transforms' state; the env has "
                         f"{len(transforms)}")
    for t, s in zip(transforms, state["transforms"]):
        _load_transform_state(t, s)
    if simulator and state.get("simulator") is not None:
        base_env_of(env).load_simulator_state(state["simulator"])
    load_context_sampler_state(env, state)
