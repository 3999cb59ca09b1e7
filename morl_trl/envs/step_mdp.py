"""What TorchRL's ``step_mdp`` + ``maybe_reset`` make of a step, as plain dicts of tensors.

The lean ``step_and_maybe_reset`` of :class:`~morl_trl.envs.ContextualMOEnv` and of
:class:`~morl_trl.transforms.LeanTransformedEnv` build the TensorDict of the next step from
these: :func:`step_mdp_entries` (the entries ``step_mdp`` keeps, read from TorchRL's own key
lists) and :func:`merge_reset` (the rows of the sub-envs being reset replaced as
``maybe_reset`` replaces them).

Example:
    >>> import torch
    >>> entries = {"observation": torch.tensor([[1.0], [2.0]]), "action": torch.tensor([3, 4])}
    >>> merge_reset(entries, {"observation": torch.tensor([[0.0], [0.0]])}, torch.tensor([False, True]))
    >>> entries["observation"].tolist(), entries["action"].tolist()
    ([[1.0], [0.0]], [3, 0])
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import torch
from tensordict import TensorDictBase
from torchrl.envs import EnvBase

from morl_trl._torchrl_compat import step_mdp_of

__all__ = ["spec_cached", "step_mdp_entries", "merge_reset"]


def spec_cached(env: EnvBase, name: str, compute: Callable):
    """``compute()``, remembered in ``env``'s TorchRL spec cache while its specs are locked (TorchRL
    clears that cache whenever a spec or a transform changes)."""
    if not env.is_spec_locked:
        return compute()
    cache = env.__dict__.setdefault("_cache", {})
    value = cache.get(name)
    if value is None:
        value = cache[name] = compute()
    return value


def _plan(env: EnvBase):
    step_mdp = step_mdp_of(env)  # TorchRL's own key lists (observations, states, done flags)
    flat = all(v is None for v in step_mdp.exclude_from_root.values()) and all(
        v is None for v in step_mdp.keys_from_next.values()
    )
    return (frozenset(step_mdp.exclude_from_root), frozenset(step_mdp.keys_from_next)) if flat else False


def step_mdp_entries(env: EnvBase, tensordict: TensorDictBase, next_td: TensorDictBase) -> dict | None:
    """The entries ``env``'s ``step_mdp(tensordict)`` would hold, as a dict; ``None`` if any is
    not a plain tensor or a key is nested (then TorchRL's ``step_mdp`` handles it)."""
    plan = spec_cached(env, "step_mdp_plan", lambda: _plan(env))
    if not plan:
        return None
    exclude, from_next = plan
    entries = {}
    for key, value in tensordict.items():
        if key not in exclude:
            if type(value) is not torch.Tensor:
                return None
            entries[key] = value
    for key, value in next_td.items():
        if key in from_next:
            if type(value) is not torch.Tensor:
                return None
            entries[key] = value
    return entries


def merge_reset(entries: dict, reset: Mapping, mask: torch.Tensor) -> None:
    """Replace, in place, the rows ``mask`` (``[N]`` bool, some but not all True) of ``entries``
    with ``reset``'s, as ``maybe_reset`` does after a partial reset: an entry the reset does not
    produce gets zeros in those rows, one only the reset produces zeros in the others."""
    conds = {}
    for key, old in entries.items():
        new = reset.get(key, None)
        if new is old:  # e.g. contexts that the reset kept
            continue
        cond = conds.get(old.ndim)
        if cond is None:
            cond = conds[old.ndim] = mask.view(-1, *(1,) * (old.ndim - 1))
        entries[key] = old.masked_fill(cond, 0) if new is None else torch.where(cond, new, old)
    for key, new in reset.items():
        if key not in entries:
            entries[key] = new.masked_fill(~mask.view(-1, *(1,) * (new.ndim - 1)), 0)
