"""Any multi-objective environment as a morl_trl domain: MO-Gymnasium ids and TorchRL envs.

``make_env``, ``morl-trl train`` and the grid take, besides our own ids,

* any Gymnasium / MO-Gymnasium id whose env has a vector reward (``"deep-sea-treasure-v0"``,
  ``"minecart-v0"``, ``"mo-hopper-v5"``, ...): each sub-env is TorchRL's ``MOGymEnv``, and
  ``num_envs`` of them are batched by TorchRL's ``SerialEnv``;
* a callable returning a TorchRL ``EnvBase`` with a vector reward ``[*, k]`` (unbatched: it is
  called once per sub-env and the envs are batched by ``SerialEnv``);
* an ``EnvBase`` instance (unbatched; copied with ``copy.deepcopy`` for every further sub-env).

:func:`foreign_domain` describes such an env as a :class:`~morl_trl.envs.DomainSpec` with no
context parameters (one "context": the env itself), so that everything built for our domains
-- the training loop, the evaluator, reports -- runs on it unchanged. The env class is
:class:`ForeignMOEnv`, a :class:`~morl_trl.envs.ContextualMOEnv` over the batched TorchRL env.

What the specs say is read from them: discrete (``Categorical``/``OneHot``) or continuous
(``Bounded``) actions, flat or image (``[H, W, C]``, given to the policy as ``[C, H, W]``;
a side above :data:`MAX_IMAGE_SIDE` pixels area-averaged to :data:`IMAGE_SIZE`) observations,
and the number of objectives ``k``. Such envs have no original scalar reward
(no ``"original_reward"`` entry: there is no f_SORL for them).

The hypervolume reference point of a MO-Gymnasium env is the one the user gives
(``ref_point=``, ``--ref-point``), else the one :mod:`morl_trl.envs.ref_point`'s rule gives
(MORL-Baselines' point, else the reward bounds times the horizon, else a random rollout; the
spec says which in ``hv_ref_point_source``); where MO-Gymnasium knows the true Pareto front
(``env.unwrapped.pareto_front(gamma)``), the spec carries it for IGD and the hypervolume ratio.
"""

from __future__ import annotations

import copy
import functools
import itertools
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict
from torchrl.data import Bounded, Categorical, OneHot, Unbounded
from torchrl.envs import EnvBase, SerialEnv

from morl_trl._quiet import quiet_gym
from morl_trl._torchrl_compat import drop_step_hook, hook_first_steps
from morl_trl.envs.base import ContextualMOEnv
from morl_trl.envs.gym_make import make_gym_env
from morl_trl.envs.context import ContextSpace
from morl_trl.envs.ref_point import MO_GYMNASIUM_REF_POINTS, reference_point
from morl_trl.envs.spec import DomainSpec

__all__ = [
    "ForeignMOEnv",
    "RewardShapeError",
    "check_reward_shape",
    "MO_GYMNASIUM_REF_POINTS",
    "MO_GYMNASIUM_OBJECTIVES",
    "foreign_domain",
    "is_gym_id",
    "NO_CONTEXT",
]

#: the context space of an env without context parameters
NO_CONTEXT = ContextSpace((), (), (), ())

#: MO-Gymnasium id -> objective names, from MO-Gymnasium's environment pages
MO_GYMNASIUM_OBJECTIVES: dict[str, tuple[str, ...]] = {
    "deep-sea-treasure-v0": ("treasure", "time_penalty"),
    "deep-sea-treasure-concave-v0": ("treasure", "time_penalty"),
    "minecart-v0": ("ore1", "ore2", "fuel"),
    "minecart-deterministic-v0": ("ore1", "ore2", "fuel"),
    "fruit-tree-v0": ("protein", "carbs", "fats", "vitamins", "minerals", "water"),
    "mo-mountaincarcontinuous-v0": ("time_penalty", "fuel_consumption_penalty"),
    "mo-hopper-v4": ("velocity", "height", "energy"),
    "mo-hopper-v5": ("velocity", "height", "energy"),
    "resource-gathering-v0": ("enemy", "gold", "gem"),
}

# the truncation horizon of an env that declares none (a safety cap: its episodes end themselves)
_NO_LIMIT = 100_000

#: images with a side above MAX_IMAGE_SIDE pixels are area-averaged to IMAGE_SIZE x IMAGE_SIZE
#: (DQN's Atari size): minecart-rgb-v0's [480, 480] frames would give the Nature CNN a
#: 100-million-weight head, about 1 frame/s on a CPU
MAX_IMAGE_SIDE = 128
IMAGE_SIZE = 84


def is_gym_id(env_id: str) -> bool:
    """Whether ``env_id`` is registered with Gymnasium (MO-Gymnasium's ids included)."""
    try:
        import gymnasium
    except ImportError:  # (without the gym extra: only our ids)
        return False
    try:
        import mo_gymnasium  # noqa: F401  (registers its ids)
    except ImportError:
        pass
    return isinstance(env_id, str) and env_id in gymnasium.registry


def _gym_factory(env_id: str, **kwargs) -> EnvBase:
    from torchrl.envs import MOGymWrapper

    with quiet_gym():
        return MOGymWrapper(make_gym_env(env_id, kwargs), categorical_action_encoding=True)


#: the first steps of every sub-env whose reward is checked against its spec (after them, no check: no per-step cost)
REWARD_CHECK_STEPS = 8


class RewardShapeError(ValueError):
    """A foreign env returned a reward of another shape than its reward spec declares
    (raised by :func:`check_reward_shape` on the env's first steps).

    Example:
        >>> print(str(_reward_error("my-env", (), (2,), 1)).split(": ")[0])
        the env 'my-env' returned a reward of shape () at step 1, but its reward spec declares shape (2,) (one value per objective)
    """


def _reward_error(name: str, got, want: tuple, step: int) -> RewardShapeError:
    return RewardShapeError(
        f"the env {name!r} returned a reward of shape {got} at step {step}, but its reward spec declares shape "
        f"{want} (one value per objective): return a reward of shape {want} (a scalar or a vector of another width "
        f"is never broadcast to the objectives)")


def check_reward_shape(env: EnvBase, name: str, steps: int = REWARD_CHECK_STEPS) -> EnvBase:
    """``env`` (an unbatched TorchRL env), its rewards checked against ``env.full_reward_spec``
    on its first ``steps`` steps (:class:`RewardShapeError` naming ``name``, the declared and the
    returned shape), then never again: the check replaces ``env._step`` (what TorchRL's
    ``SerialEnv`` calls) for those steps only and then removes itself."""
    key = env.reward_key
    want = tuple(env.full_reward_spec[key].shape)

    def check(out, step: int) -> None:
        reward = out.get(key, None)
        got = None if reward is None else tuple(torch.as_tensor(reward).shape)
        if got != want:
            raise _reward_error(name, got, want, step)

    return hook_first_steps(env, check, steps)


class _TorchRLBatch:
    """``num_envs`` unbatched TorchRL envs stepped as one (TorchRL's ``SerialEnv``), each sub-env's
    reward checked against its spec on its first steps (:func:`check_reward_shape`)."""

    def __init__(self, make_env: Callable[[], EnvBase], num_envs: int, name: str = "env") -> None:
        def make_one() -> EnvBase:
            env = make_env()
            return check_reward_shape(env, name) if isinstance(env, EnvBase) else env

        probe = make_one()
        if not isinstance(probe, EnvBase):
            raise ValueError(f"the env factory returned {type(probe).__name__}; it must return a TorchRL EnvBase")
        if tuple(probe.batch_size) != ():
            raise ValueError(f"the env factory built an env of batch size {tuple(probe.batch_size)}; give an "
                             f"unbatched env (batch size ()), which is batched here into {num_envs} sub-envs")
        made = iter([probe])
        self.spec_env = probe
        self.env = SerialEnv(num_envs, lambda: next(made, None) or make_one())
        self.num_envs = num_envs

    def reset(self, idx: torch.Tensor):
        env = self.env
        if idx.numel() == self.num_envs:
            return env.reset()
        mask = torch.zeros(self.num_envs, 1, dtype=torch.bool)
        mask[idx.cpu()] = True
        return env.reset(TensorDict({"_reset": mask}, batch_size=env.batch_size))

    def step(self, action: torch.Tensor, key):
        env = self.env
        td = TensorDict({key: action.to(env.device or "cpu")}, batch_size=env.batch_size)
        return env.step(td).get("next")

    def seed(self, seed: int) -> None:
        self.env.set_seed(seed)

    def close(self) -> None:
        if not self.env.is_closed:
            self.env.close()


class _GymBatch:
    """``num_envs`` MO-Gymnasium envs stepped in one loop (what Gymnasium's ``SyncVectorEnv``
    does, with per-sub-env resets instead of its autoreset): the specs are TorchRL's
    ``MOGymEnv``'s, the stepping skips its per-call TensorDict work (~1 ms a call on a CPU,
    20x a Deep Sea Treasure step)."""

    def __init__(self, env_id: str, num_envs: int, env_kwargs: dict) -> None:
        self.env_id = env_id
        self.steps = 0
        self.spec_env = _gym_factory(env_id, **env_kwargs)  # TorchRL's spec conversion of the spaces
        self.reward_shape = tuple(self.spec_env.full_reward_spec[self.spec_env.reward_key].shape)
        self.envs = [make_gym_env(env_id, env_kwargs) for _ in range(num_envs)]
        self.num_envs = num_envs
        self.obs_key = "observation"
        self.seeds: list[int | None] = [None] * num_envs
        self.obs: np.ndarray | None = None

    def _stack(self, items) -> torch.Tensor:
        return torch.as_tensor(np.stack([np.asarray(o) for o in items]))

    def reset(self, idx: torch.Tensor):
        idx = idx.tolist()
        firsts = []
        for i in idx:
            seed, self.seeds[i] = self.seeds[i], None
            firsts.append(self.envs[i].reset(seed=seed)[0])
        new = self._stack(firsts)
        if self.obs is None or len(idx) == self.num_envs:
            self.obs = new.clone() if len(idx) == self.num_envs else torch.zeros(self.num_envs, *new.shape[1:],
                                                                                 dtype=new.dtype)
        self.obs[idx] = new
        return {self.obs_key: self.obs}

    def step(self, action: torch.Tensor, key):
        acts = action.cpu().numpy()
        obs, rew, term, trunc = [], [], [], []
        for env, a in zip(self.envs, acts):
            o, r, te, tr, _ = env.step(a)
            obs.append(o)
            rew.append(r)
            term.append(te)
            trunc.append(tr)
        if self.steps < REWARD_CHECK_STEPS:  # (the first steps only: no per-step cost after them)
            self.steps += 1
            for r in rew:
                if np.shape(r) != self.reward_shape:
                    raise _reward_error(self.env_id, tuple(np.shape(r)), self.reward_shape, self.steps)
        self.obs = self._stack(obs)
        return {self.obs_key: self.obs, "reward": torch.as_tensor(np.stack(rew), dtype=torch.float32),
                "terminated": torch.as_tensor(term), "truncated": torch.as_tensor(trunc)}

    def seed(self, seed: int) -> None:
        self.seeds = [seed + i for i in range(self.num_envs)]
        for i, env in enumerate(self.envs):
            env.action_space.seed(seed + i)

    def close(self) -> None:
        for env in self.envs:
            env.close()
        self.spec_env.close()


def _image_layout(shape: Sequence[int]) -> bool:
    """``[H, W, C]`` (channels last, as Gymnasium's images) rather than ``[C, H, W]``."""
    return len(shape) == 3 and shape[-1] in (1, 3, 4) and shape[0] not in (1, 3, 4)


class ForeignMOEnv(ContextualMOEnv):
    """A batched TorchRL env with a vector reward as a morl_trl domain (no context parameters).

    Args:
        source: a Gymnasium / MO-Gymnasium id, a callable returning an unbatched TorchRL
            ``EnvBase`` (called once per sub-env), or an unbatched ``EnvBase`` (deep-copied
            for every further sub-env).
        num_envs, device, seed: as every domain (sub-env ``i`` is seeded with ``seed + i``).
        max_episode_steps: our truncation horizon (default: the Gymnasium spec's limit, else
            a safety cap of 100,000 steps); the env's own truncations count as well.
        objective_names: names of the reward entries (default ``objective_0``, ...).
        env_kwargs: keyword arguments of ``mo_gymnasium.make`` for an id.
        name: the env's id, named by an error (e.g. a reward of another shape than its spec's,
            checked on the first :data:`REWARD_CHECK_STEPS` steps of every sub-env).

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = make_env("deep-sea-treasure-v0", num_envs=2, seed=0)
        >>> td = env.rollout(3, break_when_any_done=False)
        >>> td["next", "reward"].shape, env.objective_names, "original_reward" in td["next"].keys()
        (torch.Size([2, 3, 2]), ('treasure', 'time_penalty'), False)
    """

    has_original_reward = False

    def __init__(self, num_envs: int = 1, context=None, device="cpu", seed=None, context_sampler=None, *,
                 source, max_episode_steps: int | None = None, objective_names: Sequence[str] | None = None,
                 env_kwargs: dict | None = None, allow_extrapolation: bool = False, name: str | None = None):
        from morl_trl.envs.base import check_num_envs

        num_envs = check_num_envs(num_envs)
        if isinstance(source, str):
            if not is_gym_id(source):
                raise ValueError(f"{source!r} is not a Gymnasium / MO-Gymnasium id")
            batch = _GymBatch(source, num_envs, dict(env_kwargs or {}))
        else:
            batch = _TorchRLBatch(_one_env_factory(source), num_envs,
                                  name or getattr(source, "__name__", None) or type(source).__name__)
        self.__dict__["_batch"] = batch  # (before EnvBase's init builds the specs from it)
        self._read_specs(batch.spec_env, objective_names)
        batch.obs_key = self._obs_key
        super().__init__(context_space=NO_CONTEXT, num_envs=num_envs, context=context, device=device, seed=seed,
                         max_episode_steps=max_episode_steps or _NO_LIMIT, context_sampler=context_sampler,
                         allow_extrapolation=allow_extrapolation)
        self._obs: dict[str, torch.Tensor] | None = None
        self._inner_truncated = torch.zeros(num_envs, dtype=torch.bool, device=self.device)

    # ------------------------------------------------------------------ specs
    def _read_specs(self, env: EnvBase, objective_names) -> None:
        """The specs of the unbatched TorchRL env ``env`` (one sub-env) as a domain's."""
        d = self.__dict__
        obs_specs = {k: v for k, v in env.observation_spec.items() if not k.startswith("_")}
        if "observation" in obs_specs:
            key = "observation"
        elif len(obs_specs) == 1:
            key = next(iter(obs_specs))
        else:
            raise ValueError(f"the env has the observation entries {sorted(obs_specs)}; morl_trl's policies read one "
                             f"entry, 'observation': rename or concatenate them (TorchRL's RenameTransform / "
                             f"CatTensors) in the env you give")
        spec = obs_specs[key]
        shape = tuple(spec.shape)
        d["_obs_key"] = key
        d["_to_chw"] = _image_layout(shape)
        if d["_to_chw"]:
            h, w, c = shape
            d["_obs_spec"] = Bounded(0, 255, shape=(c, h, w), dtype=torch.uint8) if spec.dtype == torch.uint8 \
                else Unbounded(shape=(c, h, w), dtype=torch.float32)
            d["_obs_dtype"] = spec.dtype if spec.dtype == torch.uint8 else torch.float32
        elif len(shape) == 3 and spec.dtype == torch.uint8:  # channels first already
            d["_obs_spec"], d["_obs_dtype"] = Bounded(0, 255, shape=shape, dtype=torch.uint8), torch.uint8
        elif len(shape) in (1, 3):
            d["_obs_spec"] = Unbounded(shape=shape, dtype=torch.float32)  # (integer grid positions become floats)
            d["_obs_dtype"] = torch.float32
        else:
            raise ValueError(f"the env's {key!r} has shape {shape}; morl_trl's networks take flat [n] or image "
                             f"[H, W, C] / [C, H, W] observations (flatten it, e.g. with TorchRL's FlattenObservation)")
        d["_resize"] = None
        img = tuple(d["_obs_spec"].shape)
        if len(img) == 3 and max(img[1:]) > MAX_IMAGE_SIDE:  # (a [480, 480] frame: a 100M-weight CNN head)
            d["_resize"] = (IMAGE_SIZE, IMAGE_SIZE)
            small = (img[0], IMAGE_SIZE, IMAGE_SIZE)
            d["_obs_spec"] = Bounded(0, 255, shape=small, dtype=torch.uint8) if d["_obs_dtype"] == torch.uint8 \
                else Unbounded(shape=small, dtype=torch.float32)
        d["_action_key"] = env.action_key
        act = env.full_action_spec[env.action_key]
        d["_one_hot"] = isinstance(act, OneHot)
        if isinstance(act, (OneHot, Categorical)) and act.ndim != int(d["_one_hot"]):
            raise ValueError(f"the env's action spec {type(act).__name__} of shape {tuple(act.shape)} is not one "
                             f"discrete choice: morl_trl's methods take one Categorical action or a Bounded vector")
        if isinstance(act, (OneHot, Categorical)):
            d["_act_spec"] = Categorical(int(act.space.n), shape=(), dtype=torch.long)
        elif isinstance(act, Bounded) and act.dtype.is_floating_point:
            low, high = act.space.low.float(), act.space.high.float()
            if not (torch.isfinite(low).all() and torch.isfinite(high).all()):
                raise ValueError(f"the env's continuous actions have infinite bounds (low {low.tolist()}, high "
                                 f"{high.tolist()}); morl_trl's continuous methods squash actions into finite bounds: "
                                 f"wrap the env so that its action Box has finite bounds (a gymnasium.ActionWrapper "
                                 f"mapping [-1, 1] to the range you mean) and register it with "
                                 f"morl_trl.envs.register_env")
            d["_act_spec"] = Bounded(act.space.low.float(), act.space.high.float(), shape=act.shape, dtype=torch.float32)
        else:
            raise ValueError(f"the env's action spec is {type(act).__name__} ({act.dtype}); morl_trl's methods take "
                             f"discrete (Categorical/OneHot) or bounded continuous (Bounded) actions")
        d["_reward_key"] = env.reward_key
        rshape = tuple(env.full_reward_spec[env.reward_key].shape)
        if len(rshape) != 1 or rshape[0] < 2:
            raise ValueError(f"the env's reward has shape {rshape} per sub-env; a multi-objective env gives a "
                             f"vector reward [k] with k >= 2 (MO-Gymnasium envs do; a Gymnasium env with a "
                             f"scalar reward is single-objective)")
        k = rshape[0]
        names = tuple(objective_names) if objective_names else tuple(f"objective_{i}" for i in range(k))
        if len(names) != k:
            raise ValueError(f"objective_names {list(names)} has {len(names)} names; the env's reward has {k} entries")
        d["objective_names"] = names

    def _domain_observation_spec(self):
        return {"observation": self._obs_spec}

    def _domain_action_spec(self):
        return self._act_spec

    # ------------------------------------------------------------------ hooks
    def _convert_obs(self, td) -> dict[str, torch.Tensor]:
        obs = td.get(self._obs_key)
        if self._to_chw:
            obs = obs.movedim(-1, -3)
        if self._resize is not None:  # area-average down to IMAGE_SIZE x IMAGE_SIZE
            lead = obs.shape[:-3]
            small = torch.nn.functional.interpolate(obs.reshape(-1, *obs.shape[-3:]).float(), size=self._resize,
                                                    mode="area")
            obs = small.reshape(*lead, *small.shape[-3:])
            if self._obs_dtype == torch.uint8:
                obs = obs.round()
        return {"observation": obs.to(self.device, self._obs_dtype)}

    def _reset_subenvs(self, idx: torch.Tensor, context: torch.Tensor) -> None:
        new = self._convert_obs(self._batch.reset(idx))["observation"]
        if self._obs is None or idx.numel() == self.num_envs:
            self.__dict__["_obs"] = {"observation": new}
        else:
            merged = self._obs["observation"].clone()
            merged[idx] = new[idx]
            self.__dict__["_obs"] = {"observation": merged}
        self._inner_truncated[idx] = False

    def _observe(self) -> dict[str, torch.Tensor]:
        return dict(self._obs)

    def _step_subenvs(self, action: torch.Tensor):
        if self._one_hot:
            action = torch.nn.functional.one_hot(action, self._act_spec.space.n)
        nxt = self._batch.step(action, self._action_key)
        self.__dict__["_obs"] = self._convert_obs(nxt)
        n = self.num_envs
        reward = nxt.get(self._reward_key if isinstance(nxt, TensorDict) else "reward")
        reward = reward.reshape(n, -1).to(self.device, torch.float32)
        terminated = nxt.get("terminated").reshape(n).to(self.device, torch.bool)
        truncated = nxt.get("truncated", None)
        self.__dict__["_inner_truncated"] = (torch.zeros_like(terminated) if truncated is None
                                             else truncated.reshape(n).to(self.device, torch.bool))
        return dict(self._obs), reward, None, terminated

    def _step(self, tensordict):
        out = super()._step(tensordict)
        cut = self._inner_truncated
        if bool(cut.any()):  # the env's own time limit: a truncation
            truncated = out.get("truncated") | (cut & ~out.get("terminated").view(-1)).view(-1, 1)
            out.set("truncated", truncated)
            out.set("done", out.get("terminated") | truncated)
        return out

    def _seed_subenvs(self, seed: int) -> None:
        self._batch.seed(seed)

    def close(self, *, raise_if_closed: bool = True):
        batch = self.__dict__.get("_batch")
        if batch is not None:
            batch.close()
        return super().close(raise_if_closed=raise_if_closed)


def _one_env_factory(source) -> Callable[[], EnvBase]:
    """A function building one unbatched TorchRL sub-env of ``source`` (see :class:`ForeignMOEnv`)."""
    if isinstance(source, EnvBase):
        copies = itertools.count()

        def copy_of() -> EnvBase:
            if next(copies) == 0:
                return source
            try:
                return drop_step_hook(copy.deepcopy(source))  # (the first sub-env's first-steps check: not the copy's)
            except Exception as err:  # (simulators holding handles)
                raise ValueError(f"the env instance {type(source).__name__} cannot be copied for a further "
                                 f"sub-env ({err}); pass a function that builds one env instead") from None

        return copy_of
    if callable(source):
        return source
    raise ValueError(f"an env must be an id (str), a callable returning a TorchRL EnvBase, or an EnvBase; "
                     f"got {type(source).__name__}")


def _gym_facts(env_id: str, env_kwargs: dict) -> dict[str, Any]:
    """What a Gymnasium id's registration and env say: horizon, objectives, true front."""
    import gymnasium

    spec = gymnasium.spec(env_id)
    facts: dict[str, Any] = {"max_episode_steps": env_kwargs.get("max_episode_steps", spec.max_episode_steps)}
    env = make_gym_env(env_id, env_kwargs)
    try:
        facts["has_front"] = callable(getattr(env.unwrapped, "pareto_front", None))
    finally:
        env.close()
    return facts


@functools.lru_cache(maxsize=None)
def _true_front(env_id: str, kwargs_items: tuple, gamma: float) -> np.ndarray:
    env = make_gym_env(env_id, dict(kwargs_items))
    try:
        return np.asarray(env.unwrapped.pareto_front(gamma=gamma), dtype=np.float64)
    finally:
        env.close()


def foreign_domain(source, *, name: str | None = None, ref_point: Sequence[float] | None = None,
                   objective_names: Sequence[str] | None = None, max_episode_steps: int | None = None,
                   env_kwargs: dict | None = None) -> DomainSpec:
    """The :class:`~morl_trl.envs.DomainSpec` of a foreign env (see the module docstring).

    ``name`` is its id (default: the Gymnasium id; required for a callable or an instance).
    ``ref_point`` replaces :func:`~morl_trl.envs.ref_point.reference_point`'s rule. The spec
    has one context, the id itself, which is also its evaluation suite.

    Example:
        >>> spec = foreign_domain("deep-sea-treasure-v0")
        >>> spec.hv_ref_point, spec.objective_names, spec.evaluation_ids, spec.max_episode_steps
        ((0.0, -25.0), ('treasure', 'time_penalty'), ('deep-sea-treasure-v0',), 100)
        >>> spec.true_front(0.99).shape
        (10, 2)
    """
    env_kwargs = dict(env_kwargs or {})
    true_front = None
    ref_source = "given (ref_point=)" if ref_point is not None else None
    if isinstance(source, str):
        if not is_gym_id(source):
            raise ValueError(f"{source!r} is not a Gymnasium / MO-Gymnasium id")
        name = name or source
        facts = _gym_facts(source, env_kwargs)
        max_episode_steps = max_episode_steps or facts["max_episode_steps"]
        if ref_point is None:
            ref_point, ref_source = reference_point(source, env_kwargs, max_episode_steps)
        objective_names = objective_names or MO_GYMNASIUM_OBJECTIVES.get(source)
        if facts["has_front"]:
            true_front = functools.partial(_true_front, source, tuple(sorted(env_kwargs.items())))
    elif not name:
        raise ValueError("a callable or EnvBase env needs a name (its id in configs, logs and reports)")
    if objective_names is None or ref_point is not None and len(ref_point) != len(objective_names):
        probe = ForeignMOEnv(num_envs=1, seed=0, source=source, env_kwargs=env_kwargs, objective_names=None)
        k = probe.num_objectives
        probe.close()
        objective_names = objective_names or tuple(f"objective_{i}" for i in range(k))
    if ref_point is not None:
        ref_point = tuple(float(v) for v in ref_point)
        if len(ref_point) != len(objective_names) or not all(np.isfinite(ref_point)):
            raise ValueError(f"ref_point {list(ref_point)} must be {len(objective_names)} finite numbers "
                             f"(one per objective of {name}: {list(objective_names)})")
    kwargs = {"source": source, "objective_names": tuple(objective_names), "name": name}
    if env_kwargs:
        kwargs["env_kwargs"] = env_kwargs
    if max_episode_steps:
        kwargs["max_episode_steps"] = int(max_episode_steps)
    return DomainSpec(
        name=name, train_id=name, env_class="morl_trl.envs.foreign:ForeignMOEnv", context_space=NO_CONTEXT,
        contexts={name: {}}, evaluation_ids=(name,), objective_names=tuple(objective_names), env_kwargs=kwargs,
        hv_ref_point=ref_point, hv_ref_point_source=ref_source, max_episode_steps=int(max_episode_steps or _NO_LIMIT),
        true_front=true_front,
        foreign=True,
    )
