"""TorchRL's ``TransformedEnv`` with a short ``step_and_maybe_reset`` over our own envs and transforms.

:class:`LeanTransformedEnv` is what :func:`~morl_trl.transforms.compose_policy_env` and
:func:`~morl_trl.transforms.compose_training_env` wrap an env in. Over a
:class:`~morl_trl.envs.ContextualMOEnv` whose transforms are all among
:data:`LEAN_TRANSFORMS` (ours: they have no inverse, no step-MDP hook and write only into the
``"next"`` and reset TensorDicts), its ``step_and_maybe_reset`` -- what collectors and rollouts
call once per step -- calls the same hooks in the same order as TorchRL's (the env's ``_step``,
each transform's ``_step``; where a sub-env is done, ``_reset`` with ``"_reset"`` only, which runs
the env's ``_reset`` and each transform's ``_reset``), hence the same random draws and the same
values, and builds the next step's TensorDict directly (:mod:`morl_trl.envs.step_mdp`) instead of
through ``step``'s checks, ``step_mdp``, ``maybe_reset`` and ``reset``'s bookkeeping: in a one-env
run that plumbing cost several times the env step itself. Any other case (another transform, a
foreign base env, partial steps, a preset ``"next"``, type checks, nested entries) is TorchRL's
method; everything else is TorchRL's ``TransformedEnv``.

Example:
    >>> import torch
    >>> from morl_trl.envs import make_env
    >>> from morl_trl.transforms import compose_training_env
    >>> env = compose_training_env(make_env("MOLavaGridDR-v0", num_envs=2, seed=0), gamma=0.99, preference_seed=1)
    >>> type(env).__name__, env.lean_step_applies(env.reset())
    ('LeanTransformedEnv', True)
    >>> td, nxt = env.step_and_maybe_reset(env.reset().set("action", torch.tensor([0, 1])))
    >>> sorted(nxt.keys()) == sorted(env.step_mdp_keys(td))
    True
"""

from __future__ import annotations

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Composite
from torchrl.envs import Compose, TransformedEnv

from morl_trl._torchrl_compat import (complete_done, env_reset, env_step, new_tensordict_unsafe, step_mdp_of,
                                      tensordict_entries, transform_reset, transform_reset_preprocess, transform_step)
from morl_trl.envs import ContextualMOEnv
from morl_trl.envs.step_mdp import merge_reset, spec_cached, step_mdp_entries
from morl_trl.transforms.command import DesiredReturnConditioning
from morl_trl.transforms.history import StateActionHistory
from morl_trl.transforms.preference import PreferenceConditioning
from morl_trl.transforms.returns import DiscountedVectorReturn

__all__ = ["LeanTransformedEnv", "LEAN_TRANSFORMS"]

#: the transforms the short path runs (exact types: a subclass may add an inverse or a hook)
LEAN_TRANSFORMS = (PreferenceConditioning, DiscountedVectorReturn, StateActionHistory, DesiredReturnConditioning)


def _done_shapes(env) -> list | None:
    """``[(key, shape)]`` of the env's done entries (``None`` for nested ones): a reset output holding
    each with its shape is what ``_complete_done`` leaves as it is."""
    spec = env.full_done_spec
    lead = tuple(env.batch_size)[: len(env.batch_size) - spec.ndim] if spec.ndim else tuple(env.batch_size)
    out = []
    for key, item in spec.items():
        if not isinstance(key, str) or isinstance(item, Composite):
            return None
        out.append((key, torch.Size((*lead, *item.shape))))
    return out


class LeanTransformedEnv(TransformedEnv):
    """:class:`~torchrl.envs.TransformedEnv` whose ``step_and_maybe_reset`` takes a short path when it
    computes exactly what TorchRL's would (see the module docstring); every argument is TorchRL's.

    Example:
        >>> from morl_trl.envs.toy import ToyContextEnv
        >>> from morl_trl.transforms import DiscountedVectorReturn
        >>> env = LeanTransformedEnv(ToyContextEnv(num_envs=1), DiscountedVectorReturn(0.5))
        >>> env.lean_step_applies(env.reset()), env.rollout(3)["next", "episode_return"].shape
        (True, torch.Size([1, 3, 2]))
    """

    def _lean_stack(self) -> bool:
        """Our env under our transforms only, without TorchRL's type checks: the short paths' common condition."""
        return (isinstance(self.base_env, ContextualMOEnv) and not self.run_type_checks
                and spec_cached(self, "lean_transforms",
                                lambda: all(type(t) in LEAN_TRANSFORMS for t in self._transform_list())))

    def lean_step_applies(self, tensordict: TensorDictBase) -> bool:
        """Whether ``step_and_maybe_reset(tensordict)`` takes the short path."""
        return self._lean_stack() and self.base_env._lean_step_applies(tensordict)

    def step_mdp_keys(self, tensordict: TensorDictBase) -> list:
        """The keys of the TensorDict ``step_mdp`` makes of ``tensordict`` (a stepped one, with ``"next"``)."""
        return list(step_mdp_of(self)(tensordict).keys())

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs):
        """TorchRL's ``TransformedEnv._reset``; over our env and transforms, the same calls (the input's
        reset and state entries selected, each transform's ``_reset_env_preprocess`` last to first, the
        env's ``_reset``, TorchRL's completion of missing done entries, each transform's ``_reset``) with
        the spec walks done once (the state keys; the done entries' shapes, against which a reset that
        holds them all needs no completion) -- a one-env run resets every few frames."""
        if tensordict is None or kwargs or not self._lean_stack():
            return super()._reset(tensordict, **kwargs)
        base = self.base_env
        state_keys = spec_cached(self, "state_keys", lambda: list(self.state_spec.keys(True, True)))
        tensordict = tensordict.select(*self.reset_keys, *state_keys, strict=False)
        transforms = self._transform_list()
        for t in reversed(transforms):
            tensordict = transform_reset_preprocess(t, tensordict)
        reset = env_reset(base, tensordict)
        done_shapes = spec_cached(self, "done_shapes", lambda: _done_shapes(base))
        entries = tensordict_entries(reset) if type(reset) is TensorDict else {}
        if done_shapes is None or not all(
                isinstance(entries.get(key), torch.Tensor) and entries[key].shape == shape for key, shape in done_shapes):
            complete_done(base, reset)
        for t in transforms:
            reset = transform_reset(t, tensordict, reset)
        return reset

    def _transform_list(self) -> list:
        transform = self.transform
        return list(transform.transforms) if isinstance(transform, Compose) else [transform]

    def _step_and_maybe_reset(self, tensordict: TensorDictBase) -> tuple[TensorDictBase, TensorDictBase]:
        if not self.lean_step_applies(tensordict):
            return super()._step_and_maybe_reset(tensordict)
        # TransformedEnv._step: the env's step, then the transforms' (none has an inverse: tensordict is the input)
        next_td = transform_step(self.transform, tensordict, env_step(self.base_env, tensordict))
        tensordict.set("next", next_td)
        entries = step_mdp_entries(self, tensordict, next_td)
        if entries is None:  # nested or non-tensor entries: TorchRL's step_mdp and maybe_reset
            return tensordict, self.maybe_reset(step_mdp_of(self)(tensordict))
        done = next_td.get("done")
        if done.any():
            # maybe_reset: reset(select_reset_only=True) hands _reset a TensorDict holding "_reset" only
            reset = self._reset(new_tensordict_unsafe({"_reset": done.clone()}, batch_size=self.batch_size,
                                                      device=self.device))
            mask = done.view(-1)
            if mask.all():  # (TorchRL's update: the entries the reset does not produce are kept)
                entries.update(reset.items())
            else:
                merge_reset(entries, reset, mask)
        return tensordict, new_tensordict_unsafe(entries, batch_size=self.batch_size, device=self.device)
