"""The shared base of every batched contextual multi-objective domain.

:class:`ContextualMOEnv` owns what all domains have in common, so that a domain only writes
its physics:

* ``batch_size=[num_envs]``: one ``step`` advances every sub-environment;
* the per-sub-env ``context`` (``[*B, c]``), in the observation *and* state specs so that a
  reset TensorDict can set it (``env.reset(TensorDict(context=...))``); partial resets through
  ``"_reset"`` only touch the selected sub-envs;
* an optional :class:`~morl_trl.envs.ContextSampler` (domain randomization) drawing the
  contexts of the sub-envs being reset (see :class:`ContextualMOEnv` for the rule);
* the vector reward ``[*B, k]`` with ``objective_names``, and the domain's original scalar
  reward (the paper's single-objective reward) under ``"original_reward"`` ``[*B, 1]``;
* truncation after ``max_episode_steps``; action checking; seeding;
* a lean ``step_and_maybe_reset`` (what collectors and rollouts call): the TensorDicts of
  TorchRL's ``step`` + ``step_mdp`` + ``maybe_reset``, without their generic per-call
  bookkeeping, which on a CPU costs as much as several sub-env steps of a physics domain.

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

and may override ``_seed_subenvs(seed)`` to seed its own random generators, and
``_render_subenv(i, **kwargs)`` (an RGB ``uint8 [H, W, 3]`` image of sub-env ``i``) to support
:meth:`ContextualMOEnv.render`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from morl_trl._torchrl_compat import new_tensordict_unsafe
from morl_trl.envs.context import ContextSpace
from morl_trl.envs.sampler import ContextSampler, check_seed
from morl_trl.envs.step_mdp import merge_reset, spec_cached, step_mdp_entries

__all__ = ["ContextualMOEnv", "NonFiniteStepError", "check_num_envs"]


class NonFiniteStepError(FloatingPointError, ValueError):
    """A step produced a NaN or infinite reward or observation (the physics diverged, usually
    under a context far outside the domain's bounds). The message names the first sub-env
    concerned, the entry and its context. A ``FloatingPointError`` and a ``ValueError``."""


def check_num_envs(num_envs) -> int:
    """``num_envs`` if it is a positive int (bools rejected), else a ``ValueError``."""
    if isinstance(num_envs, bool) or not hasattr(num_envs, "__index__") or num_envs.__index__() < 1:
        raise ValueError(f"num_envs must be a positive int, got {num_envs!r} ({type(num_envs).__name__})")
    return num_envs.__index__()

# entries that every reset sets to zero (False): the domain's original reward and the done flags
_ZERO_AFTER_RESET = ("original_reward", "terminated", "truncated", "done")


class ContextualMOEnv(EnvBase):
    """Base class of the batched contextual MO domains (see the module docstring).

    The context of a sub-env being reset (``reset``, a partial reset through ``"_reset"``, or
    an auto-reset in ``step_and_maybe_reset``) is, in this order:

    1. the ``context`` entry of the TensorDict given to ``env.reset(td)``, validated (a bad
       one raises a ``ValueError`` naming the parameter and leaves the env unchanged), on
       every env, domain-randomized or not;
    2. else a draw of ``context_sampler`` (one row per sub-env being reset, with the current
       contexts as ``previous``);
    3. else the sub-env's current context.

    Only an explicit ``env.reset(td)`` passes a ``context``: auto-resets never do. TorchRL's
    ``maybe_reset`` resets with ``select_reset_only=True`` (the reset TensorDict holds only
    ``"_reset"``, not the ``context`` carried from the last step), and the lean
    ``step_and_maybe_reset`` below draws directly; so a domain-randomized env draws at every
    auto-reset. To redraw in a manual partial reset, pass only ``"_reset"`` (e.g.
    ``env.reset(td.select("_reset"))``); a TensorDict with the current ``context`` keeps it.

    Args:
        context_space: the domain's :class:`~morl_trl.envs.ContextSpace`.
        num_envs: number of sub-environments stepped by one ``step``.
        context: initial context, ``[c]`` (shared) or ``[num_envs, c]``; default context if
            ``None`` (the contexts until the first reset).
        device: where the TensorDicts live.
        seed: seed of the sub-envs' random generators (sub-env ``i`` is seeded with
            ``seed + i``, Gymnasium's vector-env convention) and of an unseeded
            ``context_sampler``; ``set_seed(s)`` re-seeds both.
        max_episode_steps: truncation horizon.
        context_sampler: a :class:`~morl_trl.envs.ContextSampler` drawing the contexts of
            the sub-envs being reset (domain randomization); ``None``: contexts are kept.
        allow_extrapolation: accept contexts (initial, or given to ``reset``) outside the
            context space's declared bounds, for extrapolation studies; they must still be
            finite (and positive where the physics needs it). By default such a context
            raises a ``ValueError`` naming the parameter, the value and the bounds.

    Checks (one rule for every domain, each failure a ``ValueError`` naming what is valid):
    ``num_envs`` is a positive int (not a bool); a seed is an int in ``[0, 2**63 - 1]``
    (sub-env ``i`` uses ``seed + i``); a TensorDict given to ``step``/``reset`` has the
    env's batch size; a discrete action is an integer tensor (a float tensor holding
    integral values is accepted; bools, NaN, inf and fractions are not) in ``[0, n)``; a
    continuous action is finite and inside its bounds (never clipped). A step whose reward
    or observation is NaN or infinite raises :class:`NonFiniteStepError` (see
    ``check_finite``).

    Example:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from morl_trl.envs import ContextSampler
        >>> from morl_trl.envs.toy import ToyContextEnv, TOY_CONTEXT
        >>> env = ToyContextEnv(num_envs=2, seed=0, context_sampler=ContextSampler(TOY_CONTEXT))
        >>> TOY_CONTEXT.contains(env.reset()["context"])   # drawn
        True
        >>> env.reset(TensorDict(context=torch.tensor([[1.5, 0.0]] * 2), batch_size=[2]))["context"]
        tensor([[1.5000, 0.0000],
                [1.5000, 0.0000]])
    """

    objective_names: tuple[str, ...] = ()
    has_original_reward: bool = True
    #: validate every action against the spec (one reduction per step); set False on an
    #: accelerator once a policy is trusted, to drop the host sync it costs.
    check_actions: bool = True
    #: raise :class:`NonFiniteStepError` when a step's reward or a checked observation entry is
    #: NaN or infinite (a sum and a scalar read per entry: ~2.5 us each on a CPU per step).
    check_finite: bool = True
    #: the observation entries ``check_finite`` covers besides the reward (``None``: every
    #: floating-point entry; a domain whose observations cannot diverge may set ``()``).
    finite_check_keys: tuple[str, ...] | None = None
    batch_locked = True
    #: what :meth:`render` returns (Gymnasium's name): an RGB ``uint8`` array
    render_mode: str = "rgb_array"

    def __init__(
        self,
        *,
        context_space: ContextSpace,
        num_envs: int = 1,
        context: torch.Tensor | None = None,
        device: torch.device | str = "cpu",
        seed: int | None = None,
        max_episode_steps: int = 1000,
        context_sampler: ContextSampler | None = None,
        allow_extrapolation: bool = False,
    ) -> None:
        num_envs = check_num_envs(num_envs)
        if isinstance(max_episode_steps, bool) or not hasattr(max_episode_steps, "__index__") or max_episode_steps < 1:
            raise ValueError(f"max_episode_steps must be a positive int, got {max_episode_steps!r}")
        if seed is not None:
            seed = check_seed(seed)
        super().__init__(device=device, batch_size=torch.Size([num_envs]))
        self.context_space = context_space
        self.num_envs = num_envs
        self.max_episode_steps = int(max_episode_steps)
        self.allow_extrapolation = bool(allow_extrapolation)
        if context is None:
            context = context_space.default_tensor()
        context = context_space.validate(context, allow_extrapolation=self.allow_extrapolation).to(torch.float32)
        self._context = context.expand(num_envs, context_space.dim).clone().to(self.device)
        self._step_count = torch.zeros(num_envs, dtype=torch.long, device=self.device)
        self._make_specs()
        self._seed = None
        self._active: torch.Tensor | None = None
        self._action_bounds: tuple[torch.Tensor, torch.Tensor] | None = None
        if context_sampler is not None:
            if not isinstance(context_sampler, ContextSampler):
                raise ValueError(f"context_sampler must be a ContextSampler, got {type(context_sampler).__name__}")
            if context_sampler.context_space.dim != context_space.dim:
                raise ValueError(
                    f"the context sampler draws {context_sampler.context_space.dim} parameters; the env's "
                    f"context has {context_space.dim} ({list(context_space.names)})"
                )
        self._context_sampler = None
        self._set_seed(seed)
        if context_sampler is not None and context_sampler.seed is None:  # a seeded sampler keeps its seed
            context_sampler.set_seed(self._seed)
        self._context_sampler = context_sampler

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

    @property
    def context_sampler(self) -> ContextSampler | None:
        """The :class:`~morl_trl.envs.ContextSampler` drawing reset contexts (``None``: kept)."""
        return self._context_sampler

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
        if new_context is not None:  # an explicit context (see the class docstring)
            new_context = torch.as_tensor(new_context, device=self.device)
            extrapolate = self.allow_extrapolation
            if new_context.shape != self._context.shape:
                new_context = self.context_space.validate(new_context, allow_extrapolation=extrapolate)
                try:  # a shared [c] context, or one of the wrong width (named above)
                    new_context = new_context.expand_as(self._context)
                except RuntimeError:
                    raise ValueError(
                        f"the reset context has shape {tuple(new_context.shape)}; expected "
                        f"{tuple(self._context.shape)} or [{self.context_space.dim}]"
                    ) from None
            # validated before any state changes: a bad context leaves the env untouched
            chosen = self.context_space.validate(new_context[idx], allow_extrapolation=extrapolate).to(torch.float32)
        elif self._context_sampler is not None and idx.numel():
            chosen = self._draw_contexts(idx)  # drawn (and checked) before any state changes
        else:
            chosen = None
        if idx.numel():
            self._reset_subenvs(idx, self._context[idx] if chosen is None else chosen)
            if chosen is not None:
                # out of place: step outputs share a copy of self._context made once per change (_context_output)
                context = self._context.clone()
                context[idx] = chosen
                self.__dict__["_context"] = context
            self._step_count[idx] = 0
        no = torch.zeros(2, self.num_envs, dtype=torch.bool, device=self.device)  # (two rows: no shared views)
        return self._make_output(self._observe(), reward=None, original=None, terminated=no[0], truncated=no[1])

    def _draw_contexts(self, idx: torch.Tensor) -> torch.Tensor:
        """The sampler's contexts ``[n, c]`` for the sub-envs ``idx``, on the env's device."""
        sampler = self._context_sampler
        previous = self._context[idx] if sampler.takes_previous else None
        return sampler.draw(idx.numel(), previous).to(self.device)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = self._check_action(tensordict.get("action", None))
        # TorchRL's partial steps: "_step" [N] marks the sub-envs to advance. Domains whose
        # per-sub-env cost dominates (Box2D, MuJoCo) skip the others (see `_active`); the
        # outputs of skipped sub-envs are to be ignored by the caller.
        partial = tensordict.get("_step", None)
        active = None if partial is None else partial.reshape(self.num_envs).to(self.device, torch.bool)
        self.__dict__["_active"] = active  # (nn.Module.__setattr__ costs microseconds per step)
        obs, reward, original, terminated = self._step_subenvs(action)
        if self.check_finite:
            self._check_finite(obs, reward, active)
        if active is None:  # (in place, without an attribute assignment: EnvBase's __setattr__ is slow)
            self._step_count.add_(1)
        else:
            self._step_count.add_(active)
        truncated = (self._step_count >= self.max_episode_steps) > terminated  # (bools: a > b is a & ~b)
        return self._make_output(obs, reward, original, terminated, truncated)

    def _check_finite(self, obs: dict, reward: torch.Tensor, active: torch.Tensor | None) -> None:
        """Raise :class:`NonFiniteStepError` if the reward or a checked observation entry
        (``finite_check_keys``) of an (active) sub-env is NaN or infinite. The usual path is
        one sum per entry and one scalar read (a NaN or inf entry makes the sum non-finite);
        the diagnosis runs only when the sum is not finite."""
        keys = self.finite_check_keys
        values = [obs[key] for key in (obs if keys is None else keys) if obs[key].is_floating_point()]
        if reward.device.type == "cpu":  # Python floats: cheaper than adding tensors on a CPU
            s = reward.sum().item() + sum(v.sum().item() for v in values)
        else:  # one host read per step on an accelerator, not one per entry
            s = torch.stack([reward.sum().float(), *(v.sum().float() for v in values)]).sum().item()
        if s - s == 0.0:  # finite (inf - inf and nan - x are nan)
            return
        entries = {"reward": reward, **{k: v for k, v in obs.items() if v.is_floating_point()}}
        for key, value in entries.items():
            bad = ~torch.isfinite(value.reshape(self.num_envs, -1)).all(-1)
            if active is not None:
                bad &= active
            if bad.any():
                i = int(bad.nonzero()[0])
                row = value.reshape(self.num_envs, -1)[i]
                shown = [round(v, 4) for v in row[:8].tolist()]
                ctx = {k: round(v, 6) for k, v in self.context_dict(i).items()}
                raise NonFiniteStepError(
                    f"{type(self).__name__}: sub-env {i} produced a non-finite {key!r} {shown}"
                    f"{' ...' if row.numel() > 8 else ''} (sub-envs {bad.nonzero().squeeze(-1).tolist()}) "
                    f"at step {int(self._step_count[i]) + 1} of its episode; its context: {ctx}"
                )
        # finite entries whose sum overflowed: nothing is wrong

    # ------------------------------------------------------------------ batch size
    def _check_batch_size(self, tensordict, what: str) -> None:
        if tensordict is not None and tensordict.batch_size != self.batch_size:
            raise ValueError(
                f"{type(self).__name__}.{what}: the TensorDict has batch size {list(tensordict.batch_size)}; "
                f"this env has batch size {list(self.batch_size)} (num_envs={self.num_envs})"
            )

    def step(self, tensordict: TensorDictBase) -> TensorDictBase:
        self._check_batch_size(tensordict, "step")
        return super().step(tensordict)

    def reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        self._check_batch_size(tensordict, "reset")
        return super().reset(tensordict, **kwargs)

    def step_and_maybe_reset(self, tensordict: TensorDictBase) -> tuple[TensorDictBase, TensorDictBase]:
        self._check_batch_size(tensordict, "step_and_maybe_reset")
        return super().step_and_maybe_reset(tensordict)

    # ------------------------------------------------------------------ auto-reset
    def _step_and_maybe_reset(self, tensordict: TensorDictBase) -> tuple[TensorDictBase, TensorDictBase]:
        """TorchRL's ``step`` + ``step_mdp`` + ``maybe_reset``, without their per-call bookkeeping.

        Collectors and rollouts call this once per batch of sub-env steps. On the CPU, the
        generic path's checks and copies cost about as much as ten Box2D sub-env steps per
        call, and a partial reset as much again; this class already guarantees what they
        check (one flat done group, outputs of the right shape, done False after a reset).
        The results are the same TensorDicts: ``tensordict`` gains ``"next"`` in place; the
        returned one holds what ``step_mdp`` keeps, with the rows of finished sub-envs
        replaced as ``maybe_reset`` does (their reset values, and zeros for the entries the
        reset does not produce, such as ``"action"``). Anything unusual (partial steps, a
        preset ``"next"``, type checks, step-MDP hooks, nested entries, a lazy stack, another
        device or batch size) takes TorchRL's path.
        """
        if not self._lean_step_applies(tensordict):
            return super()._step_and_maybe_reset(tensordict)
        next_td = self._step(tensordict)
        tensordict.set("next", next_td)
        entries = self._step_mdp_entries(tensordict, next_td)
        done = next_td.get("done")
        if entries is None:  # nested or non-tensor entries: TorchRL's step_mdp and maybe_reset
            return tensordict, self.maybe_reset(self._step_mdp(tensordict))
        if done.any():
            mask = done.view(self.num_envs)
            reset = self._auto_reset(mask)
            if mask.all():  # as maybe_reset: a full reset updates, keeping the entries it does not produce
                entries.update(reset)
                for key in _ZERO_AFTER_RESET:
                    if key in entries and key not in reset:
                        entries[key] = torch.zeros_like(entries[key])
                return tensordict, new_tensordict_unsafe(entries, batch_size=self.batch_size, device=self.device)
            merge_reset(entries, reset, mask)
        return tensordict, new_tensordict_unsafe(entries, batch_size=self.batch_size, device=self.device)

    def _auto_reset(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        """Reset the sub-envs ``mask`` (``[N]`` bool) as ``_reset`` does for a reset TensorDict
        without ``context`` (contexts drawn by the sampler, else kept); return the entries
        ``_reset`` would (rows outside ``mask`` are to be ignored), but for those that a reset
        zeroes (``_ZERO_AFTER_RESET``), which may be left out."""
        if type(self)._reset is not ContextualMOEnv._reset:  # a domain with its own reset
            return dict(self._reset(self._reset_request(mask.view(-1, 1))).items())
        idx = mask.nonzero().squeeze(-1)
        if self._context_sampler is None:
            self._reset_subenvs(idx, self._context[idx])
        else:
            chosen = self._draw_contexts(idx)  # drawn and checked before any state changes
            self._reset_subenvs(idx, chosen)
            new_context = self._context.clone()  # out of place (see _context_output)
            new_context[idx] = chosen
            self.__dict__["_context"] = new_context
        self._step_count.masked_fill_(mask, 0)
        out = self._observe()
        out["context"] = self._context_output()
        return out

    def _lean_step_applies(self, tensordict: TensorDictBase) -> bool:
        return (
            isinstance(tensordict, TensorDict)  # (not a lazy stack or a view)
            and tensordict.batch_size == self.batch_size
            and tensordict.device == self.device
            and "_step" not in tensordict.keys()
            and "next" not in tensordict.keys()
            and not self.run_type_checks
            and self._post_step_mdp_hooks is None
            and not self.__dict__.get("_torchrl_native_autoreset", False)
        )

    def _reset_request(self, done: torch.Tensor) -> TensorDictBase:
        return new_tensordict_unsafe({"_reset": done}, batch_size=self.batch_size, device=self.device)

    def _cached(self, name: str, compute):
        """``compute()``, remembered in TorchRL's spec cache while the specs are locked."""
        return spec_cached(self, name, compute)

    def _step_mdp_entries(self, tensordict: TensorDictBase, next_td: TensorDictBase) -> dict | None:
        """The entries ``step_mdp(tensordict)`` would hold, as a dict; ``None`` if any is
        not a plain tensor (then TorchRL's ``step_mdp`` handles it)."""
        return step_mdp_entries(self, tensordict, next_td)

    def _context_output(self) -> torch.Tensor:
        """The contexts ``[N, c]`` the outputs carry: a copy of ``_context`` made once per change of it (every
        change replaces ``_context`` out of place), shared by the outputs until the next. The dynamics read
        ``_context`` itself, so a consumer writing into an output in place (TorchRL's ``Collector.reset``
        zeroes its carrier) cannot change the env: it once zeroed MO-LavaGrid's goals and reward weights."""
        context = self._context
        cached = self.__dict__.get("_context_out")
        if cached is None or cached[0] is not context:
            cached = self.__dict__["_context_out"] = (context, context.clone())
        return cached[1]

    def _make_output(self, obs, reward, original, terminated, truncated) -> TensorDictBase:
        out = dict(obs)
        out["context"] = self._context_output()
        n = self.num_envs
        if self.has_original_reward:
            out["original_reward"] = (
                original.reshape(n, 1).to(self.device, torch.float32)
                if original is not None
                else torch.zeros(n, 1, device=self.device)
            )
        if reward is not None:
            out["reward"] = reward.to(self.device, torch.float32)
        out["terminated"] = terminated.view(n, 1)
        out["truncated"] = truncated.view(n, 1)
        out["done"] = (terminated | truncated).view(n, 1)
        # every entry is built here with the right batch shape and device: skip the checks
        return new_tensordict_unsafe(out, batch_size=self.batch_size, device=self.device)

    def _check_action(self, action: torch.Tensor) -> torch.Tensor:
        spec = self._cached("action_spec", lambda: self.action_spec)  # the property walks the input spec
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
            if action.dtype is torch.bool or action.is_complex():
                raise ValueError(f"discrete actions must be integers in [0, {n}); got a {action.dtype} tensor")
            if action.is_floating_point():  # accepted when every value is an integer
                integral = torch.isfinite(action) & (action == action.round())
                if not bool(integral.all()):
                    bad = action[~integral][0].item()
                    raise ValueError(f"discrete actions must be integers in [0, {n}); got {bad}")
                action = action.long()
            if self.check_actions:
                lo, hi = torch.aminmax(action)  # one reduction
                if int(lo) < 0 or int(hi) >= n:
                    bad = action[(action < 0) | (action >= n)][0].item()
                    raise ValueError(f"action {bad} is out of the action space [0, {n})")
            return action
        if action.dtype is torch.bool or action.is_complex():
            raise ValueError(f"continuous actions must be real numbers; got a {action.dtype} tensor")
        if not action.is_floating_point():  # integers: exact in the spec's float type
            action = action.to(spec.dtype)
        if action.shape != spec.shape:
            raise ValueError(f"action has shape {tuple(action.shape)}; expected {tuple(spec.shape)}")
        if self.check_actions:
            if self._action_bounds is None:  # computed once: with the 1e-6 float tolerance
                low, high = (spec.space.low, spec.space.high) if isinstance(spec, Bounded) else (-torch.inf, torch.inf)
                low, high = torch.as_tensor(low - 1e-6), torch.as_tensor(high + 1e-6)
                if bool((low == low.min()).all() and (high == high.max()).all()):  # one range for all: floats
                    low, high = float(low.min()), float(high.max())
                self._action_bounds = (low, high)
            low, high = self._action_bounds
            # one reduction: NaN fails every comparison
            if isinstance(low, float):
                lo, hi = torch.aminmax(action)
                inside = float(lo) >= low and float(hi) <= high
            else:
                inside = bool(((action >= low) & (action <= high)).all())
            if not inside:
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
        self._seed = check_seed(seed)
        self._seed_subenvs(self._seed)
        sampler = self.__dict__.get("_context_sampler")
        if sampler is not None:  # the context stream follows the env's seed
            sampler.set_seed(self._seed)

    def _seed_subenvs(self, seed: int) -> None:
        """Seed the domain's own random generators (override in subclasses)."""

    def reseed_subenvs(self, seeds) -> None:
        """Re-seed each sub-env's own generator, sub-env ``i`` with ``seeds[i]`` (as Gymnasium's
        ``reset(seed=s)`` of a vector env seeds its copy ``i`` with ``s + i``); takes effect at
        their next reset. The context sampler's stream is not touched. ``NotImplementedError`` for
        a domain without per-sub-env generators (the MuJoCo domains have them)."""
        raise NotImplementedError(f"{type(self).__name__} has no per-sub-env random generators to re-seed")

    # ------------------------------------------------------------------ domain hooks
    def _reset_subenvs(self, idx: torch.Tensor, context: torch.Tensor) -> None:
        raise NotImplementedError

    def _step_subenvs(self, action: torch.Tensor):
        raise NotImplementedError

    def _observe(self) -> dict[str, torch.Tensor]:
        raise NotImplementedError

    # ------------------------------------------------------------------ snapshots (opt-in)
    def can_snapshot(self) -> bool:
        """Whether this domain can capture and restore its simulator state
        (:meth:`simulator_state`): it implements ``_snapshot_subenvs``."""
        return type(self)._snapshot_subenvs is not ContextualMOEnv._snapshot_subenvs

    def simulator_state(self) -> dict[str, Any]:
        """A copy of the state of every sub-env (contexts, step counts, seed and the domain's
        own state), for :meth:`load_simulator_state`; checkpoints use it to resume episodes
        exactly. ``NotImplementedError`` for domains that cannot snapshot (:meth:`can_snapshot`)."""
        if not self.can_snapshot():
            raise NotImplementedError(f"{type(self).__name__} cannot snapshot its simulator state")
        return {"context": self._context.clone(), "step_count": self._step_count.clone(), "seed": self._seed,
                "domain": self._snapshot_subenvs()}

    def load_simulator_state(self, state: dict[str, Any]) -> None:
        """Restore a :meth:`simulator_state` of an env of the same class and ``num_envs``."""
        if not self.can_snapshot():
            raise NotImplementedError(f"{type(self).__name__} cannot snapshot its simulator state")
        if tuple(state["context"].shape) != tuple(self._context.shape):
            raise ValueError(f"the snapshot has contexts of shape {tuple(state['context'].shape)}; "
                             f"this env has {tuple(self._context.shape)}")
        self.__dict__["_context"] = state["context"].to(self.device).clone()
        self._step_count.copy_(state["step_count"])
        self._seed = state["seed"]
        self._load_snapshot_subenvs(state["domain"])

    def _snapshot_subenvs(self) -> dict[str, Any]:
        """Hook (opt-in): a copy of the domain's own state of every sub-env."""
        raise NotImplementedError

    def _load_snapshot_subenvs(self, state: dict[str, Any]) -> None:
        """Hook (opt-in): restore what ``_snapshot_subenvs`` returned."""
        raise NotImplementedError

    # ------------------------------------------------------------------ rendering
    def render(self, index: int | None = 0, *, mode: str | None = None, **kwargs) -> np.ndarray:
        """An RGB ``uint8`` image ``[H, W, 3]`` of sub-env ``index`` (no window); all sub-envs
        ``[num_envs, H, W, 3]`` with ``index=None``. ``kwargs`` go to the domain's drawing (e.g.
        ``tile_size`` for MO-LavaGrid, ``width``/``height`` for MuJoCo).

        TorchRL's ``PixelRenderTransform(index=None)`` records every sub-env as a ``"pixels"``
        entry ``[*B, H, W, 3]``, which ``VideoRecorder`` turns into a clip.

        Example:
            >>> from morl_trl.envs import make_env
            >>> env = make_env("MOLavaGridRoom-v0", num_envs=2, seed=0)
            >>> _ = env.reset()
            >>> env.render().shape, env.render(index=None).shape, env.render().dtype
            ((208, 208, 3), (2, 208, 208, 3), dtype('uint8'))
        """
        mode = self.render_mode if mode is None else mode
        if mode != "rgb_array":
            raise ValueError(f"render mode {mode!r} is not supported; only 'rgb_array'")
        if index is None:
            return np.stack([self._render_subenv(i, **kwargs) for i in range(self.num_envs)])
        if isinstance(index, bool) or not isinstance(index, int) or not -self.num_envs <= index < self.num_envs:
            raise ValueError(f"index {index!r} is out of range for {self.num_envs} sub-envs")
        return self._render_subenv(index % self.num_envs, **kwargs)

    def _render_subenv(self, index: int, **kwargs) -> np.ndarray:
        """Hook: the RGB ``uint8 [H, W, 3]`` image of sub-env ``index``."""
        raise NotImplementedError(f"{type(self).__name__} does not render")

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(num_envs={self.num_envs}, objectives={list(self.objective_names)}, "
            f"context={list(self.context_space.names)}, device={self.device})"
        )
