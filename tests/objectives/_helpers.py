"""Batches, problems and checks shared by the loss tests."""

from __future__ import annotations

import torch
from tensordict import TensorDict


def random_batch(batch, obs_dim, num_objectives, *, num_actions=None, action_dim=None, preference=True, seed=0):
    """A random transition batch with ``[B, k]`` rewards (discrete if ``num_actions`` else continuous)."""
    g = torch.Generator().manual_seed(seed)
    if num_actions is not None:
        action = torch.randint(num_actions, (batch,), generator=g)
    else:
        action = torch.rand(batch, action_dim, generator=g) * 2 - 1
    done = torch.rand(batch, 1, generator=g) < 0.2
    data = {
        "observation": torch.randn(batch, obs_dim, generator=g),
        "action": action,
        ("next", "observation"): torch.randn(batch, obs_dim, generator=g),
        ("next", "reward"): torch.randn(batch, num_objectives, generator=g),
        ("next", "done"): done,
        ("next", "terminated"): done.clone(),
    }
    if preference:
        w = torch.rand(batch, num_objectives, generator=g)
        data["preference"] = w / w.sum(-1, keepdim=True)
    return TensorDict(data, [batch])


def grads_of(params):
    """{name: has a non-zero gradient} for every leaf of a TensorDictParams / parameter list."""
    if hasattr(params, "items"):
        items = params.items(True, True)
    else:
        items = enumerate(params)
    return {k: (p.grad is not None and bool(p.grad.abs().sum() > 0)) for k, p in items}


def zero_grads(module):
    for p in module.parameters():
        p.grad = None


# ----------------------------------------------------------------------------------------------
# A deterministic two-objective problem with a known convex front.
#
# Two steps. From the start state s0 (observation [1, 0, 0]) action a in {0, 1, 2} leads to
# s1_a (observation [0, 1, a - 1]) with zero reward; from s1_a every action terminates with
# the vector reward R[a]: R[0] = (1, 0), R[1] = (0, 1), R[2] = (0.4, 0.4). The front of
# discounted returns is {gamma * (1, 0), gamma * (0, 1)} (action 2 is dominated by their
# mixtures: 0.4 + 0.4 < 1), so the optimal first action under preference w is 0 if w_0 > w_1
# and 1 if w_1 > w_0. Learning it requires bootstrapping through s1.
# ----------------------------------------------------------------------------------------------
FRONT_REWARDS = torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.4, 0.4]])
START = torch.tensor([1.0, 0.0, 0.0])


def after(a: torch.Tensor) -> torch.Tensor:
    return torch.stack([torch.zeros_like(a, dtype=torch.float), torch.ones_like(a, dtype=torch.float), a.float() - 1], -1)


def two_step_dataset(num_actions: int = 3, seed: int = 0, size: int = 512) -> TensorDict:
    """Uniform-random transitions of the two-step problem, with a random preference each."""
    g = torch.Generator().manual_seed(seed)
    half = size // 2
    a0 = torch.randint(num_actions, (half,), generator=g)
    first = {"observation": START.expand(half, 3), "action": a0}
    first_next = {
        "observation": after(a0),
        "reward": torch.zeros(half, 2),
        "done": torch.zeros(half, 1, dtype=torch.bool),
        "terminated": torch.zeros(half, 1, dtype=torch.bool),
    }
    s1 = torch.randint(num_actions, (size - half,), generator=g)
    a1 = torch.randint(num_actions, (size - half,), generator=g)
    second = {"observation": after(s1), "action": a1}
    second_next = {
        "observation": torch.zeros(size - half, 3),
        "reward": FRONT_REWARDS[s1],
        "done": torch.ones(size - half, 1, dtype=torch.bool),
        "terminated": torch.ones(size - half, 1, dtype=torch.bool),
    }
    w = torch.rand(size, 2, generator=g)
    return TensorDict(
        {
            "observation": torch.cat([first["observation"], second["observation"]]),
            "action": torch.cat([first["action"], second["action"]]),
            "preference": w / w.sum(-1, keepdim=True),
            "next": {k: torch.cat([first_next[k], second_next[k]]) for k in first_next},
        },
        [size],
    )


EXTREME_PREFERENCES = torch.tensor([[0.9, 0.1], [0.1, 0.9]])


def continuous_bandit_dataset(seed: int = 0, size: int = 512, scale: float = 5.0) -> TensorDict:
    """One-step problem with a strictly convex front: a in [-1, 1], theta = (a + 1) pi / 4,
    r = scale * (cos theta, sin theta) -- a quarter circle. Under w = (0.9, 0.1) the optimum is
    a = 4 atan(1/9) / pi - 1 = -0.86; under (0.1, 0.9) it is +0.86."""
    g = torch.Generator().manual_seed(seed)
    a = torch.rand(size, 1, generator=g) * 2 - 1
    theta = (a[:, 0] + 1) * torch.pi / 4
    w = torch.rand(size, 2, generator=g)
    return TensorDict(
        {
            "observation": torch.ones(size, 2),
            "action": a,
            "preference": w / w.sum(-1, keepdim=True),
            "next": {
                "observation": torch.ones(size, 2),
                "reward": scale * torch.stack([theta.cos(), theta.sin()], -1),
                "done": torch.ones(size, 1, dtype=torch.bool),
                "terminated": torch.ones(size, 1, dtype=torch.bool),
            },
        },
        [size],
    )
