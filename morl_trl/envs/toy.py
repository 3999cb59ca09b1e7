"""A tiny pure-tensor contextual MO env: for examples, tests of transforms, evaluators and losses.

``ToyContextEnv``: each sub-env is a counter on a line. Context ``(speed, bias)``. Action 0
moves left, 1 right. Observation ``[position, step/10]``. Reward ``[speed*move+bias, -1]``
(objective "progress" and "time"). Terminates at |position| >= 3, truncates at 6 steps.
Everything is deterministic, so expected values can be worked out by hand.
"""

from __future__ import annotations

import torch
from torchrl.data import Categorical, Unbounded

from morl_trl.envs.base import ContextualMOEnv
from morl_trl.envs.context import ContextSpace

TOY_CONTEXT = ContextSpace(("speed", "bias"), (1.0, 0.0), (0.5, -1.0), (2.0, 1.0), positive=("speed",))


class ToyContextEnv(ContextualMOEnv):
    """A counter on a line per sub-env, context ``(speed, bias)`` (see the module docstring).

    Example:
        >>> import torch
        >>> env = ToyContextEnv(num_envs=2, context=torch.tensor([2.0, 0.5]))
        >>> td = env.rollout(2, lambda td: td.set("action", torch.ones(2, dtype=torch.long)))
        >>> td["next", "reward"][0].tolist()
        [[2.5, -1.0], [2.5, -1.0]]
    """

    objective_names = ("progress", "time")

    def __init__(self, num_envs=1, context=None, device="cpu", seed=None, max_episode_steps=6, context_sampler=None,
                 allow_extrapolation=False):
        super().__init__(
            context_space=TOY_CONTEXT, num_envs=num_envs, context=context, device=device,
            seed=seed, max_episode_steps=max_episode_steps, context_sampler=context_sampler,
            allow_extrapolation=allow_extrapolation,
        )
        self._pos = torch.zeros(num_envs, device=self.device)

    def _domain_observation_spec(self):
        return {"observation": Unbounded(shape=(2,), dtype=torch.float32)}

    def _domain_action_spec(self):
        return Categorical(2, shape=(), dtype=torch.long)

    def _reset_subenvs(self, idx, context):
        self._pos[idx] = 0.0

    def _observe(self):
        obs = torch.stack([self._pos, self._step_count.float() / 10], -1)
        return {"observation": obs}

    def _step_subenvs(self, action):
        move = action.float() * 2 - 1
        if self._active is not None:  # a partial step: the other sub-envs stay where they are
            move = move * self._active
        speed, bias = self._context[:, 0], self._context[:, 1]
        self._pos = self._pos + move
        reward = torch.stack([speed * move + bias, -torch.ones_like(move)], -1)
        terminated = self._pos.abs() >= 3
        steps = self._step_count + (1 if self._active is None else self._active.long())
        obs = torch.stack([self._pos, steps.float() / 10], -1)
        return {"observation": obs}, reward, reward.sum(-1, keepdim=True), terminated
