"""Test helpers for the transforms: a continuous toy env, a scripted policy, hand-built references."""

from __future__ import annotations

import torch
from torchrl.data import Bounded

from morl_trl.envs.base import ContextualMOEnv
from morl_trl.envs.context import ContextSpace

PLANE_CONTEXT = ContextSpace(("drag", "wind"), (0.5, 0.0), (0.0, -1.0), (1.0, 1.0))


class ToyContinuousEnv(ContextualMOEnv):
    """A point in the plane with bounded observations and actions (deterministic).

    Observation ``[x, y, t/10]`` in ``[-5, 5]^2 x [0, 1]``; action ``[dx, dy]`` in ``[-1, 1]^2``;
    ``x += dx * (1 - drag) + wind``, ``y += dy``, clipped to the box. Reward ``[x, -|a|^2]``.
    Truncates at 5 steps, never terminates.
    """

    objective_names = ("x", "effort")

    def __init__(self, num_envs=1, context=None, device="cpu", seed=None, max_episode_steps=5):
        super().__init__(
            context_space=PLANE_CONTEXT, num_envs=num_envs, context=context, device=device,
            seed=seed, max_episode_steps=max_episode_steps,
        )
        self._xy = torch.zeros(num_envs, 2, device=self.device)

    def _domain_observation_spec(self):
        low = torch.tensor([-5.0, -5.0, 0.0])
        high = torch.tensor([5.0, 5.0, 1.0])
        return {"observation": Bounded(low=low, high=high, shape=(3,), dtype=torch.float32)}

    def _domain_action_spec(self):
        return Bounded(-1.0, 1.0, shape=(2,), dtype=torch.float32)

    def _reset_subenvs(self, idx, context):
        self._xy[idx] = 0.0

    def _observe(self):
        return {"observation": torch.cat([self._xy, self._step_count.float().unsqueeze(-1) / 10], -1)}

    def _step_subenvs(self, action):
        drag, wind = self._context[:, 0], self._context[:, 1]
        dx = action[:, 0] * (1 - drag) + wind
        self._xy = torch.stack([self._xy[:, 0] + dx, self._xy[:, 1] + action[:, 1]], -1).clamp(-5, 5)
        reward = torch.stack([self._xy[:, 0], -(action**2).sum(-1)], -1)
        obs = torch.cat([self._xy, (self._step_count + 1).float().unsqueeze(-1) / 10], -1)
        return {"observation": obs}, reward, None, torch.zeros(self.num_envs, dtype=torch.bool)


class ScriptedPolicy:
    """Plays a fixed random table of actions, one row per call, whatever the observation."""

    def __init__(self, batch_shape, steps, *, n=2, continuous_dim=None, seed=0, key="action"):
        g = torch.Generator().manual_seed(seed)
        if continuous_dim is None:
            self.table = torch.randint(n, (steps, *batch_shape), generator=g)
        else:
            self.table = torch.rand(steps, *batch_shape, continuous_dim, generator=g) * 2 - 1
        self.i = 0
        self.key = key

    def __call__(self, td):
        td.set(self.key, self.table[self.i])
        self.i += 1
        return td


def episode_starts(td) -> torch.Tensor:
    """``[*B, T]`` bool: step t starts an episode (t = 0 or the previous step was done)."""
    done = td["next", "done"].squeeze(-1)
    start = torch.zeros_like(done)
    start[..., 0] = True
    start[..., 1:] = done[..., :-1]
    return start


def history_reference(obs, next_obs, action, starts, length):
    """The history at every root and next step, built with plain Python loops.

    ``obs``/``next_obs`` ``[R, T, d]``, ``action`` ``[R, T, a]`` (already encoded), ``starts``
    ``[R, T]``. Returns two ``[R, T, H]`` tensors.
    """
    R, T, d = obs.shape
    a = action.shape[-1]
    roots, nexts = [], []
    for r in range(R):
        states, actions = [], []  # of the running episode
        row_root, row_next = [], []
        for t in range(T):
            if starts[r, t]:
                states, actions = [], []
            states.append(obs[r, t])

            def hist(states, actions):
                out = []
                now = len(states) - 1
                for lag in range(length, 0, -1):
                    i = now - lag
                    out.append(states[i] if i >= 0 else states[0])
                    out.append(actions[i] if i >= 0 else torch.zeros(a))
                out.append(states[now])
                return torch.cat(out)

            row_root.append(hist(states, actions))
            actions.append(action[r, t])
            row_next.append(hist(states + [next_obs[r, t]], actions))
        roots.append(torch.stack(row_root))
        nexts.append(torch.stack(row_next))
    return torch.stack(roots), torch.stack(nexts)


def returns_reference(reward, starts, gamma):
    """Running undiscounted and discounted returns ``[R, T, k]`` after each step."""
    R, T, k = reward.shape
    ret = torch.zeros(R, T, k)
    disc = torch.zeros(R, T, k)
    for r in range(R):
        g, gd, f = torch.zeros(k), torch.zeros(k), 1.0
        for t in range(T):
            if starts[r, t]:
                g, gd, f = torch.zeros(k), torch.zeros(k), 1.0
            g = g + reward[r, t]
            gd = gd + f * reward[r, t]
            f *= gamma
            ret[r, t], disc[r, t] = g, gd
    return ret, disc
