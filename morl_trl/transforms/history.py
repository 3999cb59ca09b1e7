"""State–action history: the observation augmented with the last states and actions."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from tensordict import TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, MultiOneHot, OneHot, TensorSpec, Unbounded
from torchrl.envs.transforms import Transform

from morl_trl.transforms._utils import reset_mask

__all__ = ["StateActionHistory"]

_DISCRETE_MODES = ("index", "one_hot")


class StateActionHistory(Transform):
    """Writes ``(s_{t-L}, a_{t-L}, ..., s_{t-1}, a_{t-1}, s_t)`` in that interleaved order.

    This is the history of the paper's appendix B (``length=2``:
    ``(s_{t-2}, a_{t-2}, s_{t-1}, a_{t-1}, s_t)``), used for MO-LunarLander and the MuJoCo
    domains. At a reset the past states are padded with ``s_0`` and the past actions with
    zeros, so the reset observation is ``[s0, 0, s0, 0, s0]`` and step 1 gives
    ``[s0, 0, s0, a0, s1]``. The vector has ``(L + 1) * obs_dim + L * action_dim`` entries
    (MO-Hopper: 39, MO-LunarLander discrete: 26). ``length=0`` gives the plain observation.

    The action of step ``t`` is read from the input TensorDict of that step (TorchRL keeps it
    at the root, ``td["action"]``), in the action space of the env underneath. Discrete
    actions enter as their index (a float, the authors' choice; ``discrete_action="index"``)
    or one-hot (``discrete_action="one_hot"``); ``OneHot`` action specs are converted the
    same way. Continuous actions enter as they are.

    Keys: by default the history *replaces* ``"observation"`` (``out_key=None``), so a policy
    or loss reading ``"observation"`` needs no change and its input size is the paper's. Pass
    ``out_key="history"`` to keep the raw observation next to it.

    State: the last history of every sub-env is kept in the transform (as TorchRL's
    ``CatFrames`` keeps its frames), so partial resets only refill the sub-envs being reset.
    Use one transform per env; inside ``SerialEnv``/``ParallelEnv`` each worker has its own.

    Args:
        length: number of past state–action pairs ``L >= 0``.
        in_key: the observation to stack (a flat ``[*B, obs_dim]`` vector).
        out_key: where the history goes (default: ``in_key``).
        action_key: the action entry (default: the env's action key).
        discrete_action: ``"index"`` or ``"one_hot"``.

    Example:
        >>> import torch
        >>> from torchrl.envs import TransformedEnv
        >>> from morl_trl.envs.toy import ToyContextEnv
        >>> env = TransformedEnv(ToyContextEnv(num_envs=1), StateActionHistory(2))
        >>> td = env.reset()
        >>> td["observation"]                       # [s0, 0, s0, 0, s0], s0 = [position, time]
        tensor([[0., 0., 0., 0., 0., 0., 0., 0.]])
        >>> td = env.step(td.set("action", torch.tensor([1])))
        >>> td["next", "observation"]               # [s0, 0, s0, a0=1, s1]
        tensor([[0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 1.0000, 1.0000, 0.1000]])
    """

    def __init__(
        self,
        length: int = 2,
        *,
        in_key: str = "observation",
        out_key: str | None = None,
        action_key: str | None = None,
        discrete_action: str = "index",
    ) -> None:
        if isinstance(length, bool) or not isinstance(length, int) or length < 0:
            raise ValueError(f"history length must be an integer >= 0, got {length!r}")
        if discrete_action not in _DISCRETE_MODES:
            raise ValueError(f"discrete_action must be one of {_DISCRETE_MODES}, got {discrete_action!r}")
        super().__init__(in_keys=[in_key], out_keys=[in_key if out_key is None else out_key])
        self.length = length
        self.discrete_action = discrete_action
        self._action_key = action_key
        self._history: torch.Tensor | None = None
        self._layout: tuple[int, int] | None = None  # (obs_dim, action_dim)
        self._encoding: tuple[str, int] | None = None

    # ------------------------------------------------------------------ keys and sizes
    @property
    def in_key(self):
        return self.in_keys[0]

    @property
    def out_key(self):
        return self.out_keys[0]

    @property
    def action_key(self):
        if self._action_key is None:
            parent = self.parent
            return "action" if parent is None else parent.action_key
        return self._action_key

    def _action_spec(self) -> TensorSpec:
        parent = self.parent
        if parent is None:
            raise RuntimeError("StateActionHistory needs a parent env to read the action spec")
        # the action reaching _step has been through every inverse transform: the base env's space
        return parent.base_env.full_action_spec[self.action_key]

    def _action_kind(self, spec: TensorSpec) -> str:
        if isinstance(spec, MultiOneHot) or type(spec).__name__ in ("MultiCategorical", "Binary"):
            if self.discrete_action == "one_hot" or isinstance(spec, MultiOneHot):
                raise ValueError(
                    f"StateActionHistory(discrete_action={self.discrete_action!r}) does not support "
                    f"{type(spec).__name__} actions"
                )
            return "flat"
        if isinstance(spec, OneHot):
            return "onehot_spec"
        if isinstance(spec, Categorical):
            return "categorical"
        return "flat"

    def _action_width(self, spec: TensorSpec, nb: int) -> int:
        count = int(torch.Size(spec.shape[nb:]).numel())
        kind = self._action_kind(spec)
        if kind == "onehot_spec":
            return 1 if self.discrete_action == "index" else spec.space.n
        if kind == "categorical" and self.discrete_action == "one_hot":
            return count * spec.space.n
        return count

    def _action_encoding(self) -> tuple[str, int]:
        """(kind, n) of the env's action, cached: read once from the spec."""
        if self._encoding is None:
            spec = self._action_spec()
            kind = self._action_kind(spec)
            self._encoding = (kind, spec.space.n if kind in ("onehot_spec", "categorical") else 0)
        return self._encoding

    def _encode_action(self, action: torch.Tensor, batch: torch.Size, dtype) -> torch.Tensor:
        kind, n = self._action_encoding()
        action = action.reshape(*batch, -1)
        if kind == "onehot_spec" and self.discrete_action == "index":
            return action.to(torch.uint8).argmax(-1, keepdim=True).to(dtype)
        if kind == "categorical" and self.discrete_action == "one_hot":
            return F.one_hot(action.long(), n).reshape(*batch, -1).to(dtype)
        return action.to(dtype)

    def _sizes(self, obs_spec: TensorSpec, nb: int) -> tuple[int, int]:
        event = obs_spec.shape[nb:]
        if len(event) != 1:
            raise ValueError(
                f"StateActionHistory stacks flat observations [*B, obs_dim]; {self.in_key!r} has event "
                f"shape {tuple(event)} (flatten it first, e.g. with torchrl's FlattenObservation)"
            )
        return int(event[0]), self._action_width(self._action_spec(), nb)

    # ------------------------------------------------------------------ specs
    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        parent = self.parent
        nb = len(parent.batch_size) if parent is not None else len(observation_spec.shape)
        obs_spec = observation_spec[self.in_key]
        d, a = self._sizes(obs_spec, nb)
        self._layout, self._encoding = (d, a), None
        L = self.length
        batch = obs_spec.shape[:nb]
        width = (L + 1) * d + L * a
        dtype = obs_spec.dtype if obs_spec.dtype.is_floating_point else torch.float32
        bounds = self._bounds(obs_spec, self._action_spec(), batch, dtype)
        if bounds is None:
            spec = Unbounded(shape=(*batch, width), dtype=dtype, device=obs_spec.device)
        else:
            (olo, ohi), (alo, ahi) = bounds
            low = torch.cat([olo, alo] * L + [olo], -1)
            high = torch.cat([ohi, ahi] * L + [ohi], -1)
            spec = Bounded(low=low, high=high, shape=(*batch, width), dtype=dtype, device=obs_spec.device)
        observation_spec[self.out_key] = spec
        return observation_spec

    def _bounds(self, obs_spec, act_spec, batch, dtype):
        if not isinstance(obs_spec, Bounded):
            return None
        olo = obs_spec.space.low.to(dtype).expand(obs_spec.shape)
        ohi = obs_spec.space.high.to(dtype).expand(obs_spec.shape)
        a = self._action_width(act_spec, len(batch))
        kind = self._action_kind(act_spec)
        if isinstance(act_spec, Bounded):
            alo = act_spec.space.low.to(dtype).expand(act_spec.shape).reshape(*batch, a).clamp(max=0)
            ahi = act_spec.space.high.to(dtype).expand(act_spec.shape).reshape(*batch, a).clamp(min=0)
        elif kind in ("categorical", "onehot_spec"):
            top = 1.0 if self.discrete_action == "one_hot" else float(act_spec.space.n - 1)
            alo = torch.zeros(*batch, a, dtype=dtype)
            ahi = torch.full((*batch, a), top, dtype=dtype)
        else:
            return None
        return (olo, ohi), (alo.to(olo.device), ahi.to(olo.device))

    # ------------------------------------------------------------------ reset / step
    def _padded(self, obs: torch.Tensor) -> torch.Tensor:
        """The reset history ``[s0, 0, ..., s0, 0, s0]``."""
        if self.length == 0:
            return obs
        _, a = self._layout
        pad = torch.zeros(*obs.shape[:-1], a, dtype=obs.dtype, device=obs.device)
        block = torch.cat([obs, pad], -1)
        return torch.cat([block] * self.length + [obs], -1)

    def _observation(self, tensordict: TensorDictBase) -> torch.Tensor:
        obs = tensordict.get(self.in_key)
        return obs if obs.is_floating_point() else obs.to(torch.float32)

    def _ensure_layout(self) -> None:
        if self._layout is None:
            parent = self.parent
            self._layout = self._sizes(parent.full_observation_spec[self.in_key], len(parent.batch_size))

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        self._ensure_layout()
        obs = self._observation(tensordict_reset)
        fresh = self._padded(obs)
        mask = reset_mask(tensordict, obs.shape[:-1], obs.device)
        old = self._history
        if old is None or old.shape != fresh.shape or old.device != fresh.device or mask.all():
            history = fresh
        else:
            history = torch.where(mask.unsqueeze(-1), fresh, old)
        self._history = history
        tensordict_reset.set(self.out_key, history)
        return tensordict_reset

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        obs = self._observation(next_tensordict)
        if self.length == 0:
            next_tensordict.set(self.out_key, obs)
            return next_tensordict
        if self._history is None:
            raise RuntimeError("StateActionHistory: the env was stepped before it was reset")
        d, a = self._layout
        action = tensordict.get(self.action_key)
        enc = self._encode_action(action, obs.shape[:-1], obs.dtype)
        history = torch.cat([self._history[..., d + a :], enc, obs], -1)
        self._history = history
        next_tensordict.set(self.out_key, history)
        return next_tensordict

    def _call(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        # TorchRL only calls _call outside _step/_reset when the transform is used as a module
        raise NotImplementedError(
            "StateActionHistory needs the action of each step and the episode boundaries: "
            "use it inside a TransformedEnv, or call forward() on a [*B, T] trajectory"
        )

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Rebuild histories offline on trajectories ``[*B, T]`` (the last batch dim is time).

        Reads ``in_key``, the action and, when present, ``("next", in_key)``; an episode starts
        at ``t = 0``, wherever ``"is_init"`` is true, and after a step whose ``("next", "done")``
        is true. Writes ``out_key`` and ``("next", out_key)``, equal to what the transform
        produces online.
        """
        if tensordict.ndim < 1:
            raise ValueError("StateActionHistory.forward expects a trajectory TensorDict [*B, T]")
        obs = self._observation(tensordict)
        T = obs.shape[-2]
        start = self._episode_starts(tensordict)  # [*B, T] index of each step's episode start
        t = torch.arange(T, device=obs.device).expand_as(start)
        L = self.length
        action = tensordict.get(self.action_key, None) if L else None
        enc = None
        if L:
            if action is None:
                raise KeyError(f"StateActionHistory.forward: no {self.action_key!r} in the TensorDict")
            enc = self._encode_offline(action, obs)

        def build(cur_obs: torch.Tensor, now: torch.Tensor) -> torch.Tensor:
            # now: [*B, T] time index of the current state within the trajectory
            parts = []
            for lag in range(L, 0, -1):
                idx = now - lag
                valid = idx >= start
                sidx = torch.where(valid, idx, start)
                parts.append(obs.gather(-2, sidx.unsqueeze(-1).expand(*sidx.shape, obs.shape[-1])))
                aidx = idx.clamp(min=0)
                act = enc.gather(-2, aidx.unsqueeze(-1).expand(*aidx.shape, enc.shape[-1]))
                parts.append(torch.where(valid.unsqueeze(-1), act, torch.zeros_like(act)))
            parts.append(cur_obs)
            return torch.cat(parts, -1)

        next_obs = tensordict.get(("next", self.in_key), None)
        out = build(obs, t)
        if next_obs is not None:
            next_obs = next_obs if next_obs.is_floating_point() else next_obs.to(torch.float32)
            tensordict.set(("next", self.out_key), build(next_obs, t + 1))
        tensordict.set(self.out_key, out)
        return tensordict

    def _encode_offline(self, action: torch.Tensor, obs: torch.Tensor) -> torch.Tensor:
        batch = obs.shape[:-1]
        if self.parent is not None:
            return self._encode_action(action, batch, obs.dtype)
        if self.discrete_action == "one_hot":
            raise ValueError("offline one-hot encoding needs the env (its action spec); use it inside a TransformedEnv")
        return action.reshape(*batch, -1).to(obs.dtype)

    @staticmethod
    def _episode_starts(tensordict: TensorDictBase) -> torch.Tensor:
        shape = tensordict.batch_size
        T = shape[-1]
        new = torch.zeros(shape, dtype=torch.bool, device=tensordict.device)
        new[..., 0] = True
        is_init = tensordict.get("is_init", None)
        if is_init is not None:
            new |= is_init.reshape(shape).to(torch.bool)
        done = tensordict.get(("next", "done"), None)
        if done is not None and T > 1:
            new[..., 1:] |= done.reshape(shape)[..., :-1].to(torch.bool)
        t = torch.arange(T, device=new.device).expand(shape)
        return torch.where(new, t, torch.zeros_like(t)).cummax(-1).values

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(length={self.length}, in_key={self.in_key!r}, out_key={self.out_key!r}, "
            f"discrete_action={self.discrete_action!r})"
        )
