"""Every use of a TorchRL (and tensordict) private attribute in morl_trl, in one place.

TorchRL gives no public way to save and restore a collector's carried TensorDict and
trajectory pool (what an exact resume needs), to run one transform's ``_reset`` / ``_step`` on
data outside an env (the evaluator's and PGMORL's batched bookkeeping), to build a
TensorDict without its checks (the envs' hot path), or to reach a replay buffer's sample unit,
a storage's rows and a sampler's generator (the captured update's sampling,
:mod:`morl_trl.training.capture`); the losses reuse TorchRL's value cache and vmap helper. Each name below is checked by ``tests/test_torchrl_compat.py``, which fails loudly
(naming the attribute) when a TorchRL or tensordict release changes it.

Example:
    >>> new_tensordict_unsafe({"a": torch.zeros(2)}, batch_size=torch.Size([2])).batch_size
    torch.Size([2])
"""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictSequential
from torchrl.collectors import Collector
from torchrl.data import ReplayBuffer
from torchrl.data.replay_buffers.samplers import PrioritizedSampler
from torchrl.data.replay_buffers.storages.utils import _collate_id
from torchrl.envs import EnvBase, Transform
from torchrl.envs.transforms.vecnorm import VecNormV2
from torchrl.objectives import LossModule
from torchrl.objectives.utils import TargetNetUpdater, _cache_values, _vmap_func

__all__ = ["collector_state", "load_collector_state", "reset_collector", "VecNormNonNegativeVar", "transform_reset", "transform_step", "cache_values",
           "vmap_func", "new_tensordict_unsafe", "PRIORITIZED_SAMPLER_INTERNALS", "PRIORITIZED_SAMPLER_STATE",
           "ENV_BASE_INTERNALS", "replay_sample_unit", "storage_data", "sampler_generator",
           "module_kwargs", "SUBCLASS_INTERNALS", "collate_id", "priority_weight", "reduce_loss", "clear_weakrefs", "default_device",
           "target_updater_params", "sac_alpha", "sac_vmap_qvalue", "sac_detached_qvalue_params", "hook_first_steps",
           "drop_step_hook", "env_step", "step_mdp_of", "tensordict_entries", "tensordict_params_data",
           "env_reset", "transform_reset_preprocess", "complete_done", "plain_round_robin", "writer_cursor",
           "record_round_robin_write"]

#: ``torchrl.objectives.utils._cache_values``: caches a loss's property (e.g. detached params) per call
cache_values = _cache_values
#: ``torchrl.objectives.utils._vmap_func``: ``torch.vmap`` over a functional module, with TorchRL's randomness
vmap_func = _vmap_func
#: ``torchrl.data.replay_buffers.storages.utils._collate_id``: the collate function a tensor storage's buffer
#: gets by default (the identity; :class:`morl_trl.data.lean.LeanTensorDictReplayBuffer` checks for it)
collate_id = _collate_id
#: ``TensorDict._new_unsafe``: a TensorDict without the checks (the envs build one per step)
new_tensordict_unsafe = TensorDict._new_unsafe

#: the methods of TorchRL's ``PrioritizedSampler`` that :mod:`morl_trl.data.prioritized` overrides or
#: calls, and the attributes its ``__init__`` sets in their place (TorchRL's methods read them)
PRIORITIZED_SAMPLER_INTERNALS = ("_init", "_tree_device_from_storage", "_maybe_init_from_storage",
                                 "_retransform_priority_trees")
PRIORITIZED_SAMPLER_STATE = ("_max_capacity", "_alpha", "_beta", "_eps", "_max_priority_within_buffer", "_sum_tree",
                             "_min_tree", "_max_priority", "_device")
#: the methods of TorchRL's ``EnvBase`` that :class:`morl_trl.envs.ContextualMOEnv` overrides and calls
#: (besides the documented ``_reset`` / ``_step`` / ``_set_seed``)
ENV_BASE_INTERNALS = ("_step_and_maybe_reset", "_step_mdp", "_post_step_mdp_hooks")

#: per TorchRL class, the private names morl_trl's subclasses of it override, set or call through
#: ``self`` (TorchRL's subclassing protocol: e.g. an env implements ``_reset`` / ``_step`` /
#: ``_set_seed`` and says ``_has_frame_skip`` when it skips frames itself, a transform ``_call`` /
#: ``_reset`` / ``_step``, a loss declares ``_AcceptedKeys`` and ``_schedulable_buffers``, sets
#: ``_value_estimator`` in ``make_value_estimator`` and keeps its ``in_keys`` in ``_in_keys``). Every name is one the class
#: defines or sets (``tests/test_torchrl_compat.py``); any other one a subclass reaches through
#: ``self`` fails ``tests/test_layers.py``.
SUBCLASS_INTERNALS: dict[type, tuple[str, ...]] = {
    EnvBase: ("_reset", "_step", "_set_seed", "_has_frame_skip") + ENV_BASE_INTERNALS,
    Transform: ("_call", "_reset", "_step", "_reset_env_preprocess"),
    LossModule: ("_AcceptedKeys", "_schedulable_buffers", "_forward_value_estimator_keys", "_value_estimator",
                 "_in_keys"),
    PrioritizedSampler: PRIORITIZED_SAMPLER_INTERNALS + PRIORITIZED_SAMPLER_STATE + ("_tree_argmax",
                                                                                     "_STATE_SCHEMA_VERSION"),
    VecNormV2: ("_norm",),
    TargetNetUpdater: ("_step",),  # (the per-parameter update its step() calls: a hard copy in PeriodicHardUpdate)
    # what morl_trl.data.lean's short sample / priority paths read (the parts TorchRL's methods use) and
    # check (TorchRL's features that send a call back to TorchRL's method)
    ReplayBuffer: ("_delayed_init", "_init", "_transform", "_storage", "_sampler", "_writer", "_prefetch",
                   "_sample_unit", "_pin_memory", "_sample_dependency", "_service_shutdown", "_collate_fn",
                   "_batch_size", "_replay_lock", "_write_lock"),
    # what morl_trl.training.parts.RecipeCollector's one-step rollout reads and calls (the parts of TorchRL's
    # rollout it keeps) and checks (the features that send a batch back to TorchRL's rollout)
    Collector: ("_postproc", "_exclude_private_keys", "_use_buffers", "_compact_next_keys", "_truncated_keys",
                "_cast_to_policy_device", "_cast_to_env_device", "_carrier", "_should_use_random_frames",
                "_wrapped_policy", "_policy_output_keys", "_sync_storage", "_final_rollout", "_carrier_has_no_device",
                "_maybe_set_truncated"),
    # morl_trl.objectives.sequential.LeanSequential's short call: what TensorDictSequential's forward checks and walks
    TensorDictSequential: ("_select_before_return", "_module_iter"),
}


def collector_state(collector) -> dict[str, Any]:
    """What a ``torchrl.collectors.Collector`` carries between batches: the TensorDict of the
    next step (``_carrier``) and the trajectory-id pool (``_traj_pool``)."""
    return {"carrier": collector._carrier.clone(), "traj_pool": collector._traj_pool.state_dict()}


def load_collector_state(collector, state: dict[str, Any], device: torch.device | str) -> None:
    """Restore :func:`collector_state` into a fresh collector (before its first batch)."""
    collector._carrier = state["carrier"].to(device)
    collector._traj_pool.load_state_dict(state["traj_pool"])


class VecNormNonNegativeVar(VecNormV2):
    """TorchRL's ``VecNorm(new_api=True)`` (``VecNormV2``) whose variance ``E[x^2] - E[x]^2`` is
    clamped at 0 before its square root (its ``_norm``): for a feature equal in every sample so far
    (e.g. sub-envs started from the same seeded state, PGMORL's re-seed) the rounding can make it
    slightly negative, and TorchRL's ``sqrt().clamp_min(eps)`` then gives NaN instead of ``eps``."""

    def _norm(self, data, loc, var, count):
        var = var.apply(lambda v, m: torch.maximum(v, m.pow(2)), loc)
        return super()._norm(data, loc, var, count)


def reset_collector(collector) -> None:
    """``collector.reset()`` (every sub-env restarts, new trajectory ids) on a copy of its carried
    TensorDict (``_carrier``): TorchRL's reset zeroes the carrier in place, and our envs' outputs
    share live state with it (e.g. the DR context tensor, :class:`morl_trl.envs.ContextualMOEnv`),
    which the zeroing would overwrite before the reset reads it."""
    collector._carrier = collector._carrier.clone()
    collector.reset()


def transform_reset(transform, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
    """``transform._reset(tensordict, tensordict_reset)``: a transform's reset on data outside its env."""
    return transform._reset(tensordict, tensordict_reset)


def transform_step(transform, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
    """``transform._step(tensordict, next_tensordict)``: a transform's step on data outside its env."""
    return transform._step(tensordict, next_tensordict)


def env_step(env: EnvBase, tensordict: TensorDictBase) -> TensorDictBase:
    """``env._step(tensordict)``: an env's own step (the ``"next"`` TensorDict), without ``step``'s checks."""
    return env._step(tensordict)


def step_mdp_of(env: EnvBase):
    """``env._step_mdp``: TorchRL's ``_StepMDP`` of ``env`` (its ``exclude_from_root`` / ``keys_from_next``)."""
    return env._step_mdp


def replay_sample_unit(buffer):
    """``buffer._sample_unit``: how a replay buffer expands sampled indices (``None``: one row per index)."""
    return buffer._sample_unit


def storage_data(storage) -> TensorDictBase:
    """``storage._storage``: the TensorDict of a ``LazyTensorStorage``'s rows (full capacity), indexed without its checks."""
    return storage._storage


def tensordict_entries(td: TensorDict) -> dict:
    """``td._tensordict``: a plain ``TensorDict``'s own name -> tensor / sub-tensordict dict (the one-env
    paths read and index it directly; a caller checks ``type(td) is TensorDict`` first)."""
    return td._tensordict


def tensordict_params_data(params) -> TensorDict | None:
    """``params._param_td``: the ``TensorDict`` behind a ``TensorDictParams`` whose ``get`` returns its entries as
    they are (no get hook), else ``None``."""
    return None if params._get_post_hook else params._param_td


def env_reset(env: EnvBase, tensordict: TensorDictBase) -> TensorDictBase:
    """``env._reset(tensordict)``: an env's own reset (under a transformed env), without ``reset``'s bookkeeping."""
    return env._reset(tensordict)


def transform_reset_preprocess(transform, tensordict: TensorDictBase) -> TensorDictBase:
    """``transform._reset_env_preprocess(tensordict)``: a transform's look at the reset input before the env's reset."""
    return transform._reset_env_preprocess(tensordict)


def complete_done(env: EnvBase, tensordict: TensorDictBase) -> TensorDictBase:
    """``env._complete_done(env.full_done_spec, tensordict)``: the done entries a reset or step output lacks, filled in."""
    return env._complete_done(env.full_done_spec, tensordict)


def plain_round_robin(writer, storage) -> bool:
    """Whether a round-robin ``writer`` and its ``storage`` write nothing but the rows: no generation stamps
    (``writer._track_generations`` / ``_generation``) and no key filter of a locked storage (``storage._storage_keys``)."""
    return not writer._track_generations and writer._generation is None and storage._storage_keys is None


def writer_cursor(writer) -> int:
    """``writer._cursor``: where a round-robin writer writes next."""
    return writer._cursor


def record_round_robin_write(writer, storage, index: Tensor, n: int) -> None:
    """What ``RoundRobinWriter.extend`` and ``TensorStorage.set`` do around writing ``n`` rows at ``index``
    (written by the caller): the cursor and write count advanced, the storage's last cursor, length and
    mutation revision, the attached samplers told (``mark_update``)."""
    writer._cursor = (writer._cursor + n) % storage.max_size
    writer._write_count += n
    storage._set_last_cursor(index)
    storage._len = min(storage._len + n, storage.max_size)
    storage._bump_mutation_revision()
    writer._mark_update_entities(index)


def sampler_generator(sampler) -> torch.Generator | None:
    """``sampler._rng``: the generator a TorchRL sampler draws from (``None``: torch's global one)."""
    return sampler._rng


def module_kwargs(module) -> list | None:
    """``module._kwargs``: the in_keys a tensordict ``TensorDictModule`` passes by keyword (``None``
    or empty: all positional, so its wrapped module can be called on the input tensors directly)."""
    return getattr(module, "_kwargs", None)


# ---------------------------------------------------------------------- LossModule helpers (every loss)
def priority_weight(loss_module, tensordict: TensorDictBase) -> Tensor | None:
    """``loss_module._maybe_get_priority_weight(tensordict)``: the importance weights of a prioritised
    sample (``None`` when the loss does not use them or the sample has none)."""
    return loss_module._maybe_get_priority_weight(tensordict)


def reduce_loss(loss_module, loss: Tensor, tensordict: TensorDictBase, weights: Tensor | None) -> Tensor:
    """``loss_module._reduce_loss(loss, tensordict=..., weights=...)``: TorchRL's reduction by the
    module's ``reduction`` (``"mean"`` with weights: ``sum(w loss) / sum(w)``), with its loss mask."""
    return loss_module._reduce_loss(loss, tensordict=tensordict, weights=weights)


def clear_weakrefs(loss_module, *tds) -> None:
    """``loss_module._clear_weakrefs(*tds)``: what TorchRL's losses do at the end of ``forward`` under
    ``torch.compile`` (``tds``: TensorDicts or names of the module's parameter TensorDicts)."""
    loss_module._clear_weakrefs(*tds)


def default_device(loss_module) -> torch.device | None:
    """``loss_module._default_device``: the device of all its parameters (``None`` when spread)."""
    return loss_module._default_device


def target_updater_params(updater) -> tuple[list[str], Any, Any]:
    """``(updater._target_names, updater._sources, updater._targets)`` of a TorchRL
    ``TargetNetUpdater``: the loss's target attribute names, and the online and target parameter
    TensorDicts (sources keyed ``name``, targets ``target_name``)."""
    return updater._target_names, updater._sources, updater._targets


# ---------------------------------------------------------------------- SACLoss (the SAC baseline)
def sac_alpha(loss) -> Tensor:
    """``loss._alpha`` of a TorchRL ``SACLoss`` / ``DiscreteSACLoss``: ``exp(log_alpha)``, detached,
    after clamping ``log_alpha`` in place to ``[min_alpha, max_alpha]`` (as its ``forward`` does)."""
    return loss._alpha


def sac_vmap_qvalue(loss):
    """``loss._vmap_qnetworkN0``: the critic ``vmap``-ed over the stacked critic parameters
    (``(td, params) -> td`` with a leading critic dimension)."""
    return loss._vmap_qnetworkN0


def sac_detached_qvalue_params(loss) -> TensorDictBase:
    """``loss._cached_detached_qvalue_params``: the critics' parameters, detached (cached per call)."""
    return loss._cached_detached_qvalue_params


def hook_first_steps(env: EnvBase, check, steps: int) -> EnvBase:
    """Run ``check(out, step)`` on what unbatched ``env`` returns from its first ``steps`` steps:
    ``env._step`` (what ``EnvBase.step`` and TorchRL's ``SerialEnv`` call for each sub-env) is
    replaced on the instance for those steps, then the class's own is used again (no per-step
    cost after them)."""
    inner = env._step
    count = [0]

    def _step(tensordict):
        out = inner(tensordict)
        count[0] += 1
        check(out, count[0])
        if count[0] >= steps:
            del env._step
        return out

    env._step = _step
    return env


def drop_step_hook(env: EnvBase) -> EnvBase:
    """``env`` (a deep copy of a hooked env) without the hook of :func:`hook_first_steps`."""
    env.__dict__.pop("_step", None)
    return env
