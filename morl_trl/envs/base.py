"""The shared base of every batched contextual multi-objective domain.

:class:`ContextualMOEnv` owns what all domains have in common, so that a domain only writes
its physics:

* ``batch_size=[num_envs]``: one ``step`` advances every sub-environment;
* the per-sub-env ``context`` (``[*B, c]``), in the observation *and* state specs so that a
  reset TensorDict can set it (``env.reset(TensorDict(context=...))``); partial resets through
  ``"_reset"`` only touch the selected sub-envs;
* the vector reward ``[*B, k]`` with ``objective_names``, and the domain's original scalar
  reward (the paper's single-objective reward) under ``"original_reward"`` ``[*B, 1]``;
* truncation after ``max_episode_steps``; action checking; seeding.

A domain subclass implements four hooks:

``_domain_observation_spec()``
    a dict ``key -> spec`` (unbatched shapes) of its observation entries.
``_domain_action_spec()``
    its unbatched action spec.
``_reset_subenvs(idx, context)``
    re-initialise the sub-envs ``idx`` (a ``LongTensor``) with contexts ``[len(idx), c]``.
``_step_subenvs(action)``
    advance all sub-envs; return ``(observations: dict, reward [N, k],
    original_reward [N, 1] | None, terminated [N] bool)``. During a partial step
    (TorchRL's ``"_step"`` mask) ``self._active`` is the ``[N]`` bool mask of the sub-envs to
    advance (``None``: all); a domain may skip the others, whose outputs are ignored.
``_observe()``
    the current observation dict of all sub-envs (used after a reset).

and may override ``_seed_subenvs(seed)`` to seed its own random generators.
"""

from __future__ import annotations

from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from morl_trl.envs.context import ContextSpace

__all__ = ["ContextualMOEnv"]


class ContextualMOEnv(EnvBase):
    """Base class of the batched contextual MO domains (see the module docstring).

    Args:
        context_space: the domain's :class:`~morl_trl.envs.ContextSpace`.
        num_envs: number of sub-environments stepped by one ``step``.
        context: initial context, ``[c]`` (shared) or ``[num_envs, c]``; default context if
            ``None``.
        device: where the TensorDicts live.
        seed: seed of the sub-envs' random generators (sub-env ``i`` is seeded with
            ``seed + i``, Gymnasium's vector-env convention).
        max_episode_steps: truncation horizon.
    """

    objective_names: tuple[str, ...] = ()
    has_original_reward: bool = True
    #: validate every action against the spec (one reduction per step); set False on an
    #: accelerator once a policy is trusted, to drop the host sync it costs.
    check_actions: bool = True
    batch_locked = True

    def __init__(
        self,
        *,
        context_space: ContextSpace,
        num_envs: int = 1,
        context: torch.Tensor | None = None,
        device: torch.device | str = "cpu",
        seed: int | None = None,
        max_episode_steps: int = 1000,
    ) -> None:
        if not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive int, got {num_envs!r}")
        if max_episode_steps < 1:
            raise ValueError(f"max_episode_steps must be >= 1, got {max_episode_steps}")
        super().__init__(device=device, batch_size=torch.Size([num_envs]))
        self.context_space = context_space
        self.num_envs = num_envs
        self.max_episode_steps = int(max_episode_steps)
        if context is None:
            context = context_space.default_tensor()
        context = context_space.validate(context).to(torch.float32)
        self._context = context.expand(num_envs, context_space.dim).clone().to(self.device)
        self._step_count = torch.zeros(num_envs, dtype=torch.long, device=self.device)
        self._make_specs()
        self._seed = None
        self._active: torch.Tensor | None = None
        self._action_bounds: tuple[torch.Tensor, torch.Tensor] | None = None
        self._set_seed(seed)

    # ------------------------------------------------------------------ specs
    @property
    def num_objectives(self) -> int:
        return len(self.objective_names)

    def _make_specs(self) -> None:
        n = self.num_envs
        bs = self.batch_size
        obs = {
            key: spec.expand(n, *spec.shape).to(self.device)
            for key, spec in self._domain_observation_spec().items()
        }
        ctx_spec = Unbounded(shape=(n, self.context_space.dim), dtype=torch.float32, device=self.device)
        obs["context"] = ctx_spec
        if self.has_original_reward:
            obs["original_reward"] = Unbounded(shape=(n, 1), dtype=torch.float32, device=self.device)
        self.observation_spec = Composite(obs, shape=bs, device=self.device)
        self.state_spec = Composite(context=ctx_spec.clone(), shape=bs, device=self.device)
        act = self._domain_action_spec()
        self.action_spec = act.expand(n, *act.shape).to(self.device)
        self.reward_spec = Unbounded(shape=(n, self.num_objectives), dtype=torch.float32, device=self.device)
        flag = Categorical(2, shape=(n, 1), dtype=torch.bool, device=self.device)
        self.full_done_spec = Composite(
            done=flag.clone(), terminated=flag.clone(), truncated=flag.clone(), shape=bs, device=self.device
        )

    def _domain_observation_spec(self) -> dict[str, Any]:
        raise NotImplementedError

    def _domain_action_spec(self):
        raise NotImplementedError

    # ------------------------------------------------------------------ context
    @property
    def context(self) -> torch.Tensor:
        """The current context of every sub-env, ``[num_envs, c]`` (a copy)."""
        return self._context.clone()

    def context_dict(self, i: int = 0) -> dict[str, float]:
        """The named context of sub-env ``i``."""
        return self.context_space.as_dict(self._context[i])

    # ------------------------------------------------------------------ reset / step
    def _reset_mask(self, tensordict: TensorDictBase | None) -> torch.Tensor:
        if tensordict is not None:
            reset = tensordict.get("_reset", None)
            if reset is not None:
                return reset.reshape(self.num_envs).to(self.device, torch.bool)
        return torch.ones(self.num_envs, dtype=torch.bool, device=self.device)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        mask = self._reset_mask(tensordict)
        idx = mask.nonzero().squeeze(-1)
        new_context = None if tensordict is None else tensordict.get("context", None)
        if new_context is not None:
            new_context = torch.as_tensor(new_context, device=self.device)
            if new_context.shape != self._context.shape:
                new_context = self.context_space.validate(new_context)  # names the expected width
                new_context = new_context.expand_as(self._context)
            # validated before any state changes: a bad context leaves the env untouched
            chosen = self.context_space.validate(new_context[idx]).to(torch.float32)
        else:
            chosen = self._context[idx]
        if idx.numel():
            self._reset_subenvs(idx, chosen)
            # out of place: step outputs share self._context without copying it every step
            context = self._context.clone()
            context[idx] = chosen
            self._context = context
            self._step_count[idx] = 0
        return self._make_output(self._observe(), reward=None, original=None,
                                 terminated=torch.zeros(self.num_envs, dtype=torch.bool, device=self.device),
                                 truncated=torch.zeros(self.num_envs, dtype=torch.bool, device=self.device))

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get("action")
        action = self._check_action(action)
        # TorchRL's partial steps: "_step" [N] marks the sub-envs to advance. Domains whose
        # per-sub-env cost dominates (Box2D, MuJoCo) skip the others (see `_active`); the
        # outputs of skipped sub-envs are to be ignored by the caller.
        partial = tensordict.get("_step", None)
        self._active = None if partial is None else partial.reshape(self.num_envs).to(self.device, torch.bool)
        obs, reward, original, terminated = self._step_subenvs(action)
        self._step_count += 1 if self._active is None else self._active.long()
        truncated = (self._step_count >= self.max_episode_steps) & ~terminated
        return self._make_output(obs, reward, original, terminated, truncated)

    def _make_output(self, obs, reward, original, terminated, truncated) -> TensorDictBase:
        out = dict(obs)
        out["context"] = self._context
        if self.has_original_reward:
            out["original_reward"] = (
                original.reshape(self.num_envs, 1).to(self.device, torch.float32)
                if original is not None
                else torch.zeros(self.num_envs, 1, device=self.device)
            )
        if reward is not None:
            out["reward"] = reward.to(self.device, torch.float32)
        done = terminated | truncated
        out["terminated"] = terminated.reshape(self.num_envs, 1)
        out["truncated"] = truncated.reshape(self.num_envs, 1)
        out["done"] = done.reshape(self.num_envs, 1)
        # every entry is built here with the right batch shape and device: skip the checks
        return TensorDict._new_unsafe(out, batch_size=self.batch_size, device=self.device)

    def _check_action(self, action: torch.Tensor) -> torch.Tensor:
        spec = self.action_spec
        if action is None:
            raise ValueError("the step TensorDict has no 'action'")
        if not isinstance(action, torch.Tensor):
            action = torch.as_tensor(action, device=self.device)
        elif action.device != self.device:
            action = action.to(self.device)
        if isinstance(spec, Categorical):
            n = spec.space.n
            if action.shape == (self.num_envs, 1):
                action = action.squeeze(-1)
            if action.shape != spec.shape:
                raise ValueError(
                    f"action has shape {tuple(action.shape)}; expected {tuple(spec.shape)} "
                    f"(one index in [0, {n}) per sub-env)"
                )
            if action.is_floating_point():
                if not torch.equal(action, action.round()):
                    raise ValueError(f"discrete actions must be integers, got {action}")
                action = action.long()
            if self.check_actions and bool(((action < 0) | (action >= n)).any()):
                bad = action[(action < 0) | (action >= n)][0].item()
                raise ValueError(f"action {bad} is out of the action space [0, {n})")
            return action
        if action.shape != spec.shape:
            raise ValueError(f"action has shape {tuple(action.shape)}; expected {tuple(spec.shape)}")
        if self.check_actions:
            if self._action_bounds is None:  # computed once: with the 1e-6 float tolerance
                low, high = (spec.space.low, spec.space.high) if isinstance(spec, Bounded) else (-torch.inf, torch.inf)
                self._action_bounds = (torch.as_tensor(low - 1e-6), torch.as_tensor(high + 1e-6))
            low, high = self._action_bounds
            # one reduction (one host sync on an accelerator): NaN fails both comparisons
            if not bool(((action >= low) & (action <= high)).all()):
                if not torch.isfinite(action).all():
                    raise ValueError("action contains NaN or inf")
                raise ValueError(
                    f"action out of its bounds [{torch.as_tensor(low).min().item()}, "
                    f"{torch.as_tensor(high).max().item()}]: min {action.min().item()}, max {action.max().item()}"
                )
        return action

    # ------------------------------------------------------------------ seeding
    def _set_seed(self, seed: int | None) -> None:
        if seed is None:
            seed = int(torch.randint(0, 2**31 - 1, (1,)).item())
        self._seed = int(seed)
        self._seed_subenvs(self._seed)

    def _seed_subenvs(self, seed: int) -> None:
        """Seed the domain's own random generators (override in subclasses)."""

    # ------------------------------------------------------------------ domain hooks
    def _reset_subenvs(self, idx: torch.Tensor, context: torch.Tensor) -> None:
        raise NotImplementedError

    def _step_subenvs(self, action: torch.Tensor):
        raise NotImplementedError

    def _observe(self) -> dict[str, torch.Tensor]:
        raise NotImplementedError

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(num_envs={self.num_envs}, objectives={list(self.objective_names)}, "
            f"context={list(self.context_space.names)}, device={self.device})"
        )
