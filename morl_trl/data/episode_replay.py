"""A replay of whole episodes ranked as Pareto Conditioned Networks rank them (Reymond et al. 2022).

Facts from the authors' implementation (MORL-Baselines ``multi_policy/pcn/pcn.py``), written
again on tensors:

* every stored step keeps its return-to-go ``R_t = r_t + gamma R_{t+1}`` and the steps left
  ``T - t`` (the desired return and horizon it is trained to reproduce);
* the replay holds at most ``capacity`` episodes; a new episode gets priority 1 (above every
  ranked one) and, when full, the episode with the smallest ``(priority, step added)`` leaves;
* ranking (:meth:`EpisodeReplay.nlargest`): priority = minus the distance of the episode's
  return to the nearest non-dominated return, minus 1e-5 for every episode that is not a
  first copy of a non-dominated return, doubled where the crowding distance is <= 0.2;
* commands (:meth:`EpisodeReplay.choose_command`): among the non-dominated returns of the
  ``n`` best episodes pick one uniformly, horizon = its length - 2, and add ``U(0, std)`` of
  those returns to one objective drawn uniformly.
"""

from __future__ import annotations

import torch

from morl_trl.metrics.pareto import is_nondominated

__all__ = ["EpisodeReplay", "crowding_distance", "nondominated_mask"]


def nondominated_mask(points: torch.Tensor) -> torch.Tensor:
    """``[n]`` bool: the first copy of every non-dominated row of ``points`` ``[n, k]`` (maximization)."""
    if points.shape[0] == 0:
        return torch.zeros(0, dtype=torch.bool)
    return torch.from_numpy(is_nondominated(points.detach().cpu().double()).copy())


def crowding_distance(points: torch.Tensor) -> torch.Tensor:
    """The authors' crowding distance ``[n]`` of ``points`` ``[n, k]``: per objective, normalised to
    [0, 1], the gap between a point's two sorted neighbours (1 at the extremes), summed.

    Example:
        >>> crowding_distance(torch.tensor([[0.0, 0.0], [1.0, 1.0], [2.0, 4.0], [4.0, 2.0]]))
        tensor([2.0000, 1.0000, 1.7500, 1.7500], dtype=torch.float64)
    """
    n, k = points.shape
    p = points.double()
    p = (p - p.min(0).values) / (p.max(0).values - p.min(0).values + 1e-8)
    if n < 3:
        return torch.full((n,), float(k), dtype=torch.float64)
    order = torch.argsort(p, dim=0, stable=True)
    sorted_p = torch.gather(p, 0, order)
    gaps = (sorted_p[:-2] - sorted_p[2:]).abs()
    ones = torch.ones(1, k, dtype=torch.float64)
    gaps = torch.cat([ones, gaps, ones], 0)
    out = torch.zeros_like(p)
    out.scatter_(0, order, gaps)
    return out.sum(-1)


class EpisodeReplay:
    """Whole episodes with their returns-to-go, ranked and sampled as PCN's authors do.

    Args:
        capacity: episodes kept (the authors' ``max_buffer_size``).
        gamma: discount of the returns-to-go (the authors' ``agent.gamma``).

    Example:
        >>> rb = EpisodeReplay(capacity=10, gamma=1.0)
        >>> rb.add(torch.zeros(3, 2), torch.tensor([0, 1, 0]), torch.tensor([[1.0, 0.0], [0.0, 1.0], [1.0, 0.0]]))
        >>> rb.episode_returns, rb.episode_lengths
        (tensor([[2., 1.]]), tensor([3]))
        >>> obs, action, ret, horizon = rb.sample(4, generator=torch.Generator().manual_seed(0))
        >>> ret.shape, horizon.shape
        (torch.Size([4, 2]), torch.Size([4, 1]))
    """

    def __init__(self, capacity: int, gamma: float) -> None:
        if isinstance(capacity, bool) or not isinstance(capacity, int) or capacity < 1:
            raise ValueError(f"capacity must be a positive int (episodes), got {capacity!r}")
        if not 0.0 <= float(gamma) <= 1.0:
            raise ValueError(f"gamma must be in [0, 1], got {gamma!r}")
        self.capacity, self.gamma = capacity, float(gamma)
        self._steps: dict[str, torch.Tensor] = {}  # observation, action, return_to_go, horizon (flat, all episodes)
        self._size = 0  # steps used in the flat storage (live and dead)
        self.start = torch.zeros(0, dtype=torch.long)
        self.length = torch.zeros(0, dtype=torch.long)
        self.priority = torch.zeros(0, dtype=torch.float64)
        self.added = torch.zeros(0, dtype=torch.long)  # the step count when added (the heap's tie-break)
        self.total_added = 0

    # ------------------------------------------------------------------ contents
    def __len__(self) -> int:
        return int(self.length.numel())

    @property
    def episode_returns(self) -> torch.Tensor:
        """``[E, k]``: the (discounted) return of every stored episode."""
        if not len(self):
            return torch.zeros(0, 0)
        return self._steps["return_to_go"][self.start]

    @property
    def episode_lengths(self) -> torch.Tensor:
        return self.length.clone()

    def add(self, observation: torch.Tensor, action: torch.Tensor, reward: torch.Tensor, *, step: int | None = None) -> None:
        """Store one episode: ``observation`` ``[T, ...]``, ``action`` ``[T, ...]``, vector ``reward`` ``[T, k]``."""
        T = reward.shape[0]
        if T == 0 or observation.shape[0] != T or action.shape[0] != T or reward.ndim != 2:
            raise ValueError(f"an episode needs T >= 1 steps of observation [T, ...], action [T, ...] and reward [T, k]; "
                             f"got {tuple(observation.shape)}, {tuple(action.shape)}, {tuple(reward.shape)}")
        rtg = reward.double().clone()
        for t in range(T - 2, -1, -1):
            rtg[t] += self.gamma * rtg[t + 1]
        steps = {"observation": observation, "action": action, "return_to_go": rtg.float(),
                 "horizon": torch.arange(T, 0, -1, dtype=torch.float32).unsqueeze(-1)}
        self.total_added += T
        step = self.total_added if step is None else int(step)
        if len(self) == self.capacity:  # heappushpop: the new episode (priority 1) stays, the smallest leaves
            self._remove(self._smallest())
        self._append_steps(steps)
        self.start = torch.cat([self.start, torch.tensor([self._size - T])])
        self.length = torch.cat([self.length, torch.tensor([T])])
        self.priority = torch.cat([self.priority, torch.tensor([1.0], dtype=torch.float64)])
        self.added = torch.cat([self.added, torch.tensor([step])])

    def _smallest(self) -> int:
        key = torch.stack([self.priority, self.added.double()], -1)
        order = torch.argsort(key[:, 1], stable=True)
        order = order[torch.argsort(key[order, 0], stable=True)]
        return int(order[0])

    def _remove(self, i: int) -> None:
        keep = torch.ones(len(self), dtype=torch.bool)
        keep[i] = False
        self.start, self.length = self.start[keep], self.length[keep]
        self.priority, self.added = self.priority[keep], self.added[keep]
        if self._size > 2 * int(self.length.sum()) + 1024:
            self._compact()

    def _append_steps(self, steps: dict[str, torch.Tensor]) -> None:
        T = steps["horizon"].shape[0]
        if not self._steps:
            cap = max(1024, 2 * T)
            self._steps = {k: torch.zeros(cap, *v.shape[1:], dtype=v.dtype) for k, v in steps.items()}
        cap = self._steps["horizon"].shape[0]
        if self._size + T > cap:
            new_cap = max(2 * cap, self._size + T)
            self._steps = {k: torch.cat([v, torch.zeros(new_cap - cap, *v.shape[1:], dtype=v.dtype)])
                           for k, v in self._steps.items()}
        for k, v in steps.items():
            self._steps[k][self._size:self._size + T] = v.detach().cpu().to(self._steps[k].dtype)
        self._size += T

    def _compact(self) -> None:
        idx = torch.cat([torch.arange(s, s + n) for s, n in zip(self.start.tolist(), self.length.tolist())])
        self._steps = {k: v[idx].clone() for k, v in self._steps.items()}
        self._size = idx.numel()
        self.start = torch.cumsum(self.length, 0) - self.length

    # ------------------------------------------------------------------ sampling and ranking
    def sample(self, batch_size: int, *, generator: torch.Generator | None = None):
        """``(observation, action, return_to_go [B, k], horizon [B, 1])``: episodes uniformly
        (with replacement), then a step uniformly within each."""
        if not len(self):
            raise ValueError("the episode replay is empty: add episodes before sampling")
        e = torch.randint(len(self), (batch_size,), generator=generator)
        length = self.length[e]
        t = (torch.rand(batch_size, generator=generator, dtype=torch.float64) * length).long()
        t = torch.minimum(t, length - 1)
        idx = self.start[e] + t
        s = self._steps
        return s["observation"][idx], s["action"][idx], s["return_to_go"][idx], s["horizon"][idx]

    def nlargest(self, n: int, threshold: float = 0.2) -> torch.Tensor:
        """Rank every episode (updating the priorities) and return the indices of the ``n`` best,
        from the ``n``-th best to the best (the authors' order)."""
        returns = self.episode_returns.double()
        crowd = crowding_distance(returns)
        nd = nondominated_mask(returns)
        front = returns[nd]
        l2 = -torch.cdist(returns, front).min(-1).values
        l2[~nd] -= 1e-5
        l2[crowd <= threshold] *= 2
        self.priority = l2
        order = torch.argsort(l2, stable=True)
        return order[-n:] if n > 0 else order[:0]

    def choose_command(self, n: int, *, generator: torch.Generator | None = None) -> tuple[torch.Tensor, float]:
        """The authors' ``_choose_commands(n)``: ``(desired_return [k], desired_horizon)``."""
        if not len(self):
            raise ValueError("the episode replay is empty: add episodes before choosing a command")
        best = self.nlargest(n)
        returns = self.episode_returns[best]
        horizons = self.length[best]
        nd = nondominated_mask(returns)
        returns, horizons = returns[nd], horizons[nd]
        i = int(torch.randint(len(returns), (1,), generator=generator))
        std = returns.double().std(0, unbiased=False)
        desired = returns[i].double().clone()
        j = int(torch.randint(desired.numel(), (1,), generator=generator))
        desired[j] += float(torch.rand(1, generator=generator, dtype=torch.float64)) * std[j]
        return desired.float(), float(horizons[i]) - 2.0

    def top_commands(self, n: int) -> tuple[torch.Tensor, torch.Tensor]:
        """``(returns [n, k], horizons [n])`` of the ``min(n, E)`` best episodes repeated to ``n``
        (the authors' evaluation commands).

        Ranks with :meth:`nlargest`, which stores the ranking as the priorities, as MB's ``PCN.evaluate`` does
        (``_nlargest`` re-prices its heap in place): an evaluation between two adds decides which episode the
        next add evicts (training re-ranks at every command, so only evictions within a round can differ). The
        parity benchmark restores the priorities around both libraries' evaluations."""
        best = self.nlargest(min(n, len(self)))
        reps = best[torch.arange(n) % best.numel()]
        return self.episode_returns[reps].float(), self.length[reps].float()

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        return {"steps": {k: v[:self._size].clone() for k, v in self._steps.items()}, "size": self._size,
                "start": self.start, "length": self.length, "priority": self.priority, "added": self.added,
                "total_added": self.total_added, "capacity": self.capacity, "gamma": self.gamma}

    def load_state_dict(self, state: dict) -> None:
        self._steps = {k: v.clone() for k, v in state["steps"].items()}
        self._size = int(state["size"])
        self.start, self.length = state["start"].clone(), state["length"].clone()
        self.priority, self.added = state["priority"].clone(), state["added"].clone()
        self.total_added = int(state["total_added"])
