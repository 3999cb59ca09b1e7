"""Agent states saved by older code, converted to the current parameter names and layouts on load.

Every agent's ``load_state_dict`` (:class:`~morl_trl.training.agent.Agent`) passes its state through
:func:`upgrade_agent_state`, so a checkpoint written before a change of the networks' layout still
loads, resumes and evaluates (``tests/runs/test_population_states.py`` loads states of the code of
2026-11-26 from ``tests/fixtures/population_states``).

Layout changes so far (2026-11-26, the one batched linear of :mod:`morl_trl.objectives.batched`):

* PGMORL's population MLP: ``weights.i`` / ``biases.i`` became ``mlp.{2i}.weight`` / ``mlp.{2i}.bias``
  (same shapes; the optimizer's parameter order changed with the names);
* MORL/D's population layers: weight ``[P, out, in]`` became ``[P, in, out]``, bias ``[P, out]``
  became ``[P, 1, out]`` (and the loss's critic copies ``[n, P, ...]`` alike).
"""

from __future__ import annotations

import re

import torch

__all__ = ["upgrade_agent_state", "upgrade_loss_state"]


#: PGMORL's population MLP before the one batched MLP (2026-11-26): ``weights.i`` / ``biases.i`` ParameterLists
_PGMORL_PARAM = re.compile(r"^(.*?)(weights|biases)\.(\d+)$")


def _renamed(key: str) -> str:
    """The current name of a parameter saved under an older name (PGMORL's ``weights.i`` -> ``mlp.{2i}.weight``)."""
    m = _PGMORL_PARAM.match(key)
    if m is None:
        return key
    prefix, kind, i = m.groups()
    return f"{prefix}mlp.{2 * int(i)}.{'weight' if kind == 'weights' else 'bias'}"


def _old_layout_fns(saved: dict, live: dict) -> dict:
    """``{key: transform}`` for the layers saved in MORL/D's older population layout (``nn.Linear``'s:
    weight ``[..., out, in]``, bias ``[..., out]``), recognised by a bias with one dim fewer than the
    current ``[..., 1, out]``; the transform gives the current layout (weight ``[..., in, out]``)."""
    fns = {}
    for key, value in saved.items():
        cur = live.get(key)
        if not key.endswith("bias") or not torch.is_tensor(value) or not torch.is_tensor(cur):
            continue
        if value.ndim + 1 == cur.ndim and cur.shape[-2] == 1 and value.shape[-1] == cur.shape[-1]:
            fns[key] = lambda t: t.unsqueeze(-2)
            weight = key[: -len("bias")] + "weight"
            if weight in saved:
                fns[weight] = lambda t: t.transpose(-1, -2).contiguous()
    return fns


def upgrade_loss_state(loss: torch.nn.Module, saved: dict) -> tuple[dict, dict[str, str], dict]:
    """A loss ``state_dict`` saved by older code, in ``loss``'s current names and layouts.

    Returns ``(state_dict, renamed, transforms)``: the converted state dict, the renamed keys
    (``old -> new``) and the per-key layout transforms applied (``new key -> fn``). A state dict in
    the current layout comes back unchanged.

    Example:
        >>> from morl_trl.objectives.pgmorl import make_population_value_network
        >>> net = make_population_value_network(2, obs_dim=3, num_objectives=2, num_cells=(4,))
        >>> old = {"module.weights.0": torch.zeros(2, 3, 4), "module.biases.0": torch.zeros(2, 1, 4),
        ...        "module.weights.1": torch.zeros(2, 4, 2), "module.biases.1": torch.zeros(2, 1, 2)}
        >>> new, renamed, _ = upgrade_loss_state(net, old)
        >>> sorted(new) == sorted(net.state_dict()), renamed["module.weights.1"]
        (True, 'module.mlp.2.weight')
    """
    live = loss.state_dict(keep_vars=True)
    renamed = {k: _renamed(k) for k in saved if k not in live and _renamed(k) in live}
    state = {renamed.get(k, k): v for k, v in saved.items()}
    fns = _old_layout_fns(state, live)
    for key, fn in fns.items():
        state[key] = fn(state[key])
    return state, renamed, fns


def _upgrade_optimizer(optimizer: torch.optim.Optimizer, saved: dict, live_names: dict[int, str],
                       old_position: dict[str, int], fns: dict) -> dict:
    """An optimizer ``state_dict`` saved before the parameters were renamed or re-laid out: each
    parameter's moments follow it (the saved order was the loss's older parameter order)."""
    groups, state, start = [], {}, 0
    for live_group, saved_group in zip(optimizer.param_groups, saved["param_groups"]):
        names = [live_names.get(id(p)) for p in live_group["params"]]
        if None in names or any(n not in old_position for n in names) or len(names) != len(saved_group["params"]):
            return saved  # not a loss parameter we know: left as saved
        old_order = sorted(range(len(names)), key=lambda i: old_position[names[i]])
        for j, i in enumerate(old_order):
            moments = saved["state"].get(saved_group["params"][j])
            if moments is not None:
                fn = fns.get(names[i])
                state[start + i] = {k: fn(v) if fn is not None and torch.is_tensor(v) and v.ndim > 1 else v
                                    for k, v in moments.items()}
        groups.append({**saved_group, "params": list(range(start, start + len(names)))})
        start += len(names)
    return {"state": state, "param_groups": groups}


def _upgrade_member_state(state: dict, live: dict) -> dict:
    """A member's parameters (PGMORL's ``member_state``, MORL/D's archived actor) in the current names and layout."""
    state = {_renamed(k) if k not in live else k: v for k, v in state.items()}
    for key, fn in _old_layout_fns(state, live).items():
        state[key] = fn(state[key])
    return state


def upgrade_agent_state(agent, state: dict) -> dict:
    """Converts, in place, an agent ``state_dict`` (the ``"agent"`` entry of a checkpoint) saved by
    older code to ``agent``'s parameter names and layouts, and returns it: the loss's parameters,
    targets and optimizer moments, PGMORL's population and archive snapshots and MORL/D's archived
    actors. The batched layers were unified on 2026-11-26 (:mod:`morl_trl.objectives.batched`):
    PGMORL's ``weights.i``/``biases.i`` became ``mlp.{2i}.weight``/``.bias``, MORL/D's population
    weights ``[P, out, in]`` became ``[P, in, out]`` (and biases ``[P, out]`` ``[P, 1, out]``).
    A state in the current layout is returned as it is."""
    saved = state.get("loss")
    if not isinstance(saved, dict):
        return state
    loss_state, renamed, fns = upgrade_loss_state(agent.loss, saved)
    if not renamed and not fns:
        return state
    state["loss"] = loss_state
    live_names = {id(v): k for k, v in agent.loss.state_dict(keep_vars=True).items() if torch.is_tensor(v)}
    old_keys = {new: old for old, new in renamed.items()}
    old_position = {old_keys.get(k, k): i for i, k in enumerate(saved)}
    old_position = {k: old_position[old_keys.get(k, k)] for k in loss_state if old_keys.get(k, k) in old_position}
    for name, optimizer in agent.optimizers.items():
        if name in state.get("optimizers", {}):
            state["optimizers"][name] = _upgrade_optimizer(optimizer, state["optimizers"][name], live_names,
                                                           old_position, fns)
    head = getattr(agent, "head", None)
    if head is not None and hasattr(head, "member_state"):  # PGMORL: member states of the population and archive
        live_actor, live_critic = head.member_state(0), agent.critic.module.member_state(0)
        for people in state.get("population", {}).get("bins", []):
            for person in people:
                person["actor"] = _upgrade_member_state(person["actor"], live_actor)
                person["critic"] = _upgrade_member_state(person["critic"], live_critic)
        for member in state.get("archive_members", []):
            member["actor"] = _upgrade_member_state(member["actor"], live_actor)
    archive = state.get("morld", {}).get("archive")
    if archive is not None:  # MORL/D: the archived actors ([...] per member)
        live = {".".join(k): v[0] for k, v in agent.loss.actor_network_params.items(True, True)}
        for person in archive.get("individuals", []):
            actor = person["actor"]
            flat = _upgrade_member_state({".".join(k): v for k, v in actor.items(True, True)}, live)
            person["actor"] = actor.empty(recurse=True).update({tuple(k.split(".")): v for k, v in flat.items()})
    return state
