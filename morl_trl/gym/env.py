"""One sub-env of a batched :class:`~morl_trl.envs.ContextualMOEnv` as an MO-Gymnasium-style
``gymnasium.Env``: NumPy in and out, the vector reward, contexts through ``reset(options=...)``."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces
from tensordict import TensorDict
from torchrl.data import Binary, Bounded, Categorical, MultiCategorical, MultiOneHot, OneHot

from morl_trl.envs import domain_of, make_env

__all__ = ["MOGymnasiumEnv", "spec_to_space"]


def _np_dtype(dtype: torch.dtype) -> np.dtype:
    return torch.empty((), dtype=dtype).numpy().dtype


def spec_to_space(spec) -> spaces.Space:
    """The Gymnasium space of an *unbatched* TorchRL leaf spec (``Categorical`` -> ``Discrete``,
    ``Bounded``/``Unbounded`` -> ``Box``, ``MultiCategorical`` -> ``MultiDiscrete``, ...)."""
    if isinstance(spec, OneHot):
        return spaces.Discrete(spec.space.n)
    if isinstance(spec, Categorical):
        if spec.shape != ():
            return spaces.MultiDiscrete(np.full(tuple(spec.shape), spec.space.n))
        return spaces.Discrete(spec.space.n)
    if isinstance(spec, Binary):
        return spaces.MultiBinary(tuple(spec.shape))
    if isinstance(spec, (MultiCategorical, MultiOneHot)):
        return spaces.MultiDiscrete(np.asarray(spec.nvec).reshape(-1))
    dtype = _np_dtype(spec.dtype)
    shape = tuple(spec.shape)
    if isinstance(spec, Bounded):
        low = spec.space.low.detach().cpu().numpy().astype(dtype)
        high = spec.space.high.detach().cpu().numpy().astype(dtype)
        return spaces.Box(low, high, shape=shape, dtype=dtype)
    if np.issubdtype(dtype, np.integer):
        info = np.iinfo(dtype)
        return spaces.Box(info.min, info.max, shape=shape, dtype=dtype)
    return spaces.Box(-np.inf, np.inf, shape=shape, dtype=dtype)


class MOGymnasiumEnv(gymnasium.Env):
    """A morl_trl id as a single MO-Gymnasium-style environment.

    ``gymnasium.make("morl_trl/<id>")`` builds it (after ``import morl_trl.gym``, or with
    ``gymnasium.make("morl_trl.gym:morl_trl/<id>")``); ``MOGymnasiumEnv("<id>")`` too. It steps
    the domain's batched env with ``num_envs=1``:

    * ``step(action)`` returns ``(observation, reward, terminated, truncated, info)`` with the
      **vector** reward (``np.float32 [k]``, one entry per objective, ``objective_names``),
      as MO-Gymnasium's environments do; ``reward_space`` is its ``Box``.
    * ``reset(seed=s)`` re-seeds the simulator and the context stream (same seed, same
      episode); ``reset(options={"context": c})`` plays the next episode in context ``c``: a
      ``{name: value}`` mapping (the other parameters at the domain's defaults) or a full
      vector ``[c]``. Without one, a ``*DR-*`` id draws a context (domain randomization) and
      any other id keeps its fixed context.
    * ``info["context"]`` (``np.float32 [c]``, names in ``context_names``) and
      ``info["original_reward"]`` (the domain's scalar reward) after every reset and step.
    * Episodes end inside the env (its ``max_episode_steps``); no ``TimeLimit`` is added.

    Args:
        env_id: a morl_trl id (``morl_trl.envs.list_envs()``).
        render_mode: ``None`` or ``"rgb_array"`` (domains that render: LavaGrid, LunarLander).
        device: the torch device of the batched env underneath.
        **overrides: context parameters fixed by name, or env options (as ``make_env``).
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 50}

    def __init__(self, env_id: str, render_mode: str | None = None, device: str = "cpu", **overrides: Any) -> None:
        super().__init__()
        self.env_id = env_id
        self.domain = domain_of(env_id)
        self.env = make_env(env_id, num_envs=1, device=device, **overrides)
        can_render = callable(getattr(self.env, "render", None))
        self.metadata = {**type(self).metadata, "render_modes": ["rgb_array"] if can_render else []}
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"{env_id}: render_mode {render_mode!r} is not supported; "
                             f"valid: {[None, *self.metadata['render_modes']]}")
        self.render_mode = render_mode
        self.context_space = self.env.context_space
        self.context_names: tuple[str, ...] = tuple(self.context_space.names)
        self.objective_names: tuple[str, ...] = tuple(self.env.objective_names)
        self.observation_space = spec_to_space(self.env.observation_spec["observation"][0])
        self.action_space = spec_to_space(self.env.full_action_spec[self.env.action_key][0])
        k = len(self.objective_names)
        self.reward_space = spaces.Box(-np.inf, np.inf, shape=(k,), dtype=np.float32)
        self.reward_dim = k  # (MO-Gymnasium's name)
        self._discrete = isinstance(self.action_space, spaces.Discrete)

    # ------------------------------------------------------------------ helpers
    def _context_tensor(self, context) -> torch.Tensor:
        if isinstance(context, Mapping):
            unknown = sorted(set(context) - set(self.context_names))
            if unknown:
                raise ValueError(f"{self.env_id}: unknown context parameter(s) {unknown}; "
                                 f"valid: {list(self.context_names)}")
            return self.context_space.make(dict(context))
        return self.context_space.validate(torch.as_tensor(np.asarray(context, dtype=np.float32)))

    def _info(self, td) -> dict[str, Any]:
        info = {"context": td["context"][0].detach().cpu().numpy().copy()}
        if "original_reward" in td.keys():
            info["original_reward"] = float(td["original_reward"][0, 0])
        return info

    def _observation(self, td) -> np.ndarray:
        return td["observation"][0].detach().cpu().numpy().copy()

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        unknown = sorted(set(options or {}) - {"context"})
        if unknown:
            raise ValueError(f"{self.env_id}: unknown reset option(s) {unknown}; valid: ['context']")
        td = None
        context = (options or {}).get("context")
        if context is not None:
            ctx = self._context_tensor(context)
            td = TensorDict(context=ctx.reshape(1, -1).to(self.env.device), batch_size=[1], device=self.env.device)
        if seed is not None:
            self.env.set_seed(int(seed))
        out = self.env.reset(td)
        return self._observation(out), self._info(out)

    def _action_tensor(self, action) -> torch.Tensor:
        """``action`` as the batched env's ``[1, ...]`` action, unconverted: the env checks it as it
        checks any action (``step(1.5)``, ``step(True)``, ``step(nan)`` of a discrete env, NaN or
        out-of-bounds continuous actions are ``ValueError``s naming the value and the valid range)."""
        try:
            arr = np.asarray(action)
        except (TypeError, ValueError) as err:
            raise ValueError(f"{self.env_id}: action {action!r} is not a number or array ({err})") from None
        if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number) or arr.dtype == np.bool_):
            raise ValueError(f"{self.env_id}: action {action!r} is not numeric; valid: {self.action_space}")
        shape = () if self._discrete else self.action_space.shape
        if arr.size != int(np.prod(shape)):
            raise ValueError(f"{self.env_id}: action has shape {arr.shape}; valid: {self.action_space} "
                             f"(shape {shape})")
        if not self._discrete and np.issubdtype(arr.dtype, np.floating):
            arr = arr.astype(self.action_space.dtype)  # (NaN stays NaN: the env refuses it)
        return torch.as_tensor(arr.reshape(1, *shape).copy())

    def step(self, action):
        act = self._action_tensor(action)
        td = TensorDict(action=act.to(self.env.device), batch_size=[1], device=self.env.device)
        nxt = self.env.step(td)["next"]
        reward = nxt["reward"][0].detach().cpu().numpy().astype(np.float32, copy=True)
        return (self._observation(nxt), reward, bool(nxt["terminated"][0, 0]), bool(nxt["truncated"][0, 0]),
                self._info(nxt))

    def render(self):
        if self.render_mode is None:
            gymnasium.logger.warn(f"{self.env_id}: render() without a render_mode; make the env with "
                                  f"render_mode='rgb_array'")
            return None
        return self.env.render(0)

    def close(self) -> None:
        env = self.__dict__.get("env")
        if env is not None and not env.is_closed:
            env.close()

    def __repr__(self) -> str:
        return f"MOGymnasiumEnv({self.env_id!r})"
