"""MORL/D (Felten et al., 2024) with a shared replay buffer: ``morl-trl train morld|morld_psa <id>``.

A population of ``P`` MOSAC learners (continuous or discrete actions), member ``p`` with its own
scalarization weight ``w_p`` (the authors: pymoo's energy weights for ``P``, ``seed`` = the run's
seed), all trained from ONE shared replay buffer (SB). Every ``exchange_every`` frames the members'
recent returns go into a Pareto archive and, with ``weight_adaptation="psa"`` (SB+PSA), each weight
moves by Pareto simulated annealing away from its nearest archived neighbour. Evaluation as the
authors': for each evaluation weight the Pareto archive's snapshot whose weight is nearest acts
(:class:`ArchiveSnapshotRouter`), with sampled actions.

Beyond MORL-Baselines (which trains one member at a time for ``exchange_every`` steps): the
population is ONE batched module (:class:`~morl_trl.objectives.population.PopulationMOSACLoss`),
one optimizer step updates all ``P`` members, and the members collect at the same time: the
training env holds ``P * num_envs`` sub-envs, member ``p`` acting in sub-envs
``p * num_envs .. (p + 1) * num_envs - 1``. Each member gets one update per ``update_frequency`` of
its own frames (``updates_per_batch = 0``), the authors' update-to-data ratio per member.

After every exchange each member is evaluated as the authors': the mean discounted vector return
of ``morld_eval_episodes`` (5) episodes with sampled actions on a DR env of its own
(:meth:`MORLDAgent.evaluate_members`, not training frames); ``morld_eval_episodes=0`` archives the
mean return of its training episodes since the last exchange instead.

Where this still differs from the authors' loop: the members train concurrently, not turn by turn
(so there is no "update the others ``update_passes`` times" step, no env reset at each exchange
and every member collects its own frames). The PSA rule, its ``delta = 0.1``, the archive's distance threshold (0.01)
and the weights' L1 renormalisation are MORL-Baselines 1.3.0's.

Example:
    >>> from morl_trl.recipes import resolve_config
    >>> cfg = resolve_config("morld_psa", "MOLavaGridDR-v0", quick=True, hidden=(16,))
    >>> env = make_morld_training_env(cfg, torch.device("cpu"))
    >>> env.batch_size, cfg.pop_size, cfg.weight_adaptation
    (torch.Size([10]), 5, 'psa')
    >>> agent = make_morld_agent(cfg, env, gamma=0.995, device=torch.device("cpu"))
    >>> agent.loss.weights.shape
    torch.Size([5, 2])
"""

from __future__ import annotations

import math
import warnings

import torch
from tensordict import TensorDictBase
from torch import nn
from torchrl.envs.utils import ExplorationType, set_exploration_type

from morl_trl.envs import domain_of, make_env
from morl_trl.metrics import is_nondominated
from morl_trl.objectives.batched import BatchedLinear
from morl_trl.objectives.networks import categorical_actor, tanh_normal_actor
from morl_trl.recipes.actor_critic import orthogonal_critic_copies_
from morl_trl.objectives.population import (
    PopulationMOSACLoss,
    nearest_member,
    make_population_categorical_actor,
    make_population_critic,
    make_population_gaussian_actor,
    make_population_q_network,
    population_policies,
)
from morl_trl.preferences import energy_weights
from morl_trl.recipes.agent import (
    Agent,
    NonFiniteLossError,
    action_spec,
    actor_critic_optimizers,
    eval_exploration,
    is_discrete,
    num_objectives,
    obs_shape,
    target_updater,
)
from morl_trl.recipes.parts import run_discount
from morl_trl.transforms import DiscountedVectorReturn, compose_policy_env

__all__ = ["ArchiveSnapshotRouter", "MORLDAgent", "ParetoArchive", "archive_eval_policy", "make_member_env",
           "make_morld_agent", "make_morld_training_env", "orthogonal_population_init_", "psa_weights"]

#: MORL-Baselines 1.3.0: an archived evaluation closer than this (squared distance) is the member itself
PSA_MIN_DISTANCE = 0.01


def psa_weights(weights: torch.Tensor, evaluations: torch.Tensor, archive: torch.Tensor, delta: float,
                min_distance: float = PSA_MIN_DISTANCE) -> torch.Tensor:
    """Pareto simulated annealing (Czyżak & Jaszkiewicz, 1998) as MORL/D adapts its weights.

    For each member (row of ``weights`` ``[P, k]`` with evaluation ``evaluations[p]`` ``[k]``), the
    nearest archived evaluation ``c`` (squared distance above ``min_distance``) is found; objective
    ``i`` where the member is at least as good as ``c`` gets ``w_i * (1 + delta)``, the others
    ``w_i / (1 + delta)``; the result is renormalised to sum 1 (below: the member itself, at
    distance 0, is skipped and (0, 1) is its neighbour). A member with no such neighbour
    (or a NaN evaluation: not evaluated) keeps its weight.

    Example:
        >>> w = torch.tensor([[0.5, 0.5]])
        >>> psa_weights(w, torch.tensor([[1.0, 0.0]]), torch.tensor([[1.0, 0.0], [0.0, 1.0]]), 0.1)
        tensor([[0.5475, 0.4525]])
    """
    new = weights.clone()
    for p in range(weights.shape[0]):
        e = evaluations[p]
        if torch.isnan(e).any() or archive.shape[0] == 0:
            continue
        d = (archive - e).pow(2).sum(-1)
        d = torch.where(d > min_distance, d, torch.full_like(d, math.inf))
        if not torch.isfinite(d.min()):
            continue
        closest = archive[d.argmin()]
        w = torch.where(e >= closest, weights[p] * (1 + delta), weights[p] / (1 + delta))
        new[p] = w / w.abs().sum()
    return new


class ParetoArchive:
    """The non-dominated (evaluation, policy) pairs seen so far, as MORL-Baselines' ``ParetoArchive``.

    ``evaluations`` ``[m, k]``; ``individuals[i]``: ``{"weight": [k], "actor": member's actor
    parameters}`` (on the CPU). Adding keeps the non-dominated points (the first copy of a duplicate).

    Example:
        >>> a = ParetoArchive()
        >>> a.add(torch.tensor([[1.0, 0.0], [0.5, 0.5], [0.2, 0.2]]), [{"id": 0}, {"id": 1}, {"id": 2}])
        >>> a.evaluations.tolist(), [i["id"] for i in a.individuals]
        ([[1.0, 0.0], [0.5, 0.5]], [0, 1])
    """

    def __init__(self) -> None:
        self.evaluations = torch.zeros(0, 0)
        self.individuals: list[dict] = []

    def __len__(self) -> int:
        return len(self.individuals)

    def add(self, evaluations: torch.Tensor, individuals: list[dict]) -> None:
        evaluations = evaluations.detach().double().cpu()
        points = evaluations if len(self) == 0 else torch.cat([self.evaluations, evaluations])
        people = self.individuals + list(individuals)
        keep = torch.as_tensor(is_nondominated(points.numpy()))
        self.evaluations = points[keep]
        self.individuals = [p for p, k in zip(people, keep.tolist()) if k]

    def state_dict(self) -> dict:
        return {"evaluations": self.evaluations.clone(), "individuals": list(self.individuals)}

    def load_state_dict(self, state: dict) -> None:
        self.evaluations = state["evaluations"].clone()
        self.individuals = list(state["individuals"])


class ArchiveSnapshotRouter(nn.Module):
    """Acting under the evaluator's preference: each row is driven by the Pareto archive's snapshot
    whose weight is nearest (squared distance; ties: the first, the authors' a random one) to its
    ``preference``, as the authors' MORL/D ``eval`` (``morld.py:434-488``); before the archive holds
    any, by the population member of nearest weight.

    ``net`` is the population network (``[P, *B, ...]``) of ``actor``; the used snapshots run
    ``P`` at a time with their parameters swapped into ``actor`` (``snapshots_fn() -> (weights
    [S, k], actor parameters [S, ...])`` or ``None``).
    """

    def __init__(self, net: nn.Module, actor: nn.Module, weights: torch.Tensor, snapshots_fn) -> None:
        super().__init__()
        self.net = net
        self._actor = [actor]  # (not registered: the parameters are the training actor's)
        self.weights = weights
        self.snapshots_fn = snapshots_fn

    def forward(self, *inputs: torch.Tensor):
        *obs, preference = inputs
        snapshots = self.snapshots_fn()
        batch = preference.shape[:-1]
        targets = self.weights if snapshots is None else snapshots[0]
        idx = nearest_member(preference.reshape(-1, preference.shape[-1]), targets.to(preference.device))
        m, P = idx.shape[0], self.weights.shape[0]
        flat = [x.reshape(m, *x.shape[len(batch):]) for x in obs]
        expanded = [x.unsqueeze(0).expand(P, *x.shape) for x in flat]
        if snapshots is None:
            chunks, params = [list(range(P))], None
        else:
            used = idx.unique().tolist()
            chunks, params = [used[c:c + P] for c in range(0, len(used), P)], snapshots[1]
        outputs = None
        for chunk in chunks:
            if params is None:
                out = self.net(*expanded)
            else:
                padded = chunk + [chunk[0]] * (P - len(chunk))
                with params[torch.as_tensor(padded)].to(preference.device).to_module(self._actor[0]):
                    out = self.net(*expanded)
            out = out if isinstance(out, tuple) else (out,)
            if outputs is None:
                outputs = [torch.empty(m, *o.shape[2:], dtype=o.dtype, device=o.device) for o in out]
            for j, i in enumerate(chunk):
                sel = idx == i
                for dest, o in zip(outputs, out):
                    dest[sel] = o[j][sel]
        result = tuple(o.reshape(*batch, *o.shape[1:]) for o in outputs)
        return result if len(result) > 1 else result[0]


def archive_eval_policy(actor, weights: torch.Tensor, snapshots_fn):
    """The evaluation actor of :class:`ArchiveSnapshotRouter` (reads ``"preference"`` too)."""
    tdm = actor.module[0]
    action_key = actor.module[-1].out_keys[0]
    make = tanh_normal_actor if "loc" in tdm.out_keys else categorical_actor
    router = ArchiveSnapshotRouter(tdm.module, actor, weights, snapshots_fn)
    return make(router, [*tdm.in_keys, "preference"], actor.spec[action_key], action_key)


class MORLDAgent(Agent):
    """The MORL/D population (see the module docstring): store, update all members, exchange."""

    def __init__(self, cfg, loss: PopulationMOSACLoss, explore_policy, eval_policy, optimizers, updater, *, device,
                 num_envs_per_member: int, eval_exploration) -> None:
        super().__init__(cfg, loss, explore_policy, eval_policy, optimizers, updater, device=device,
                         eval_exploration=eval_exploration)
        self.population = loss.population
        self.num_envs_per_member = num_envs_per_member
        self.archive = ParetoArchive()
        k = loss.num_objectives
        self._return_sum = torch.zeros(self.population, k, dtype=torch.float64, device=device)
        self._return_count = torch.zeros(self.population, dtype=torch.long, device=device)
        self._next_exchange = cfg.exchange_every
        self._member_frames = 0  # member frames not yet turned into updates (update_frequency)
        self.exchanges = 0
        self.eval_episodes = 0  # archive-evaluation episodes run so far (not training frames)
        self._eval_env = None  # the members' evaluation env (evaluate_members), built on first use
        self._snapshots = (None, None)  # (archive version, stacked snapshots) cache of snapshots()

    def snapshots(self):
        """``(weights [S, k], actor parameters [S, ...])`` of the archive, or ``None`` while it is empty."""
        if not len(self.archive):
            return None
        key = tuple(id(i) for i in self.archive.individuals)
        if self._snapshots[0] != key:
            people = self.archive.individuals
            self._snapshots = (key, (torch.stack([p["weight"] for p in people]).float(),
                                     torch.stack([p["actor"] for p in people])))
        return self._snapshots[1]

    # ------------------------------------------------------------------ learning
    def learn(self, batch: TensorDictBase, buffer, frames: int):
        """Record each member's finished episodes, store the batch in the shared buffer, update all
        members (one batched step per update), and exchange every ``cfg.exchange_every`` frames."""
        self._record_returns(batch)
        buffer.extend(batch.reshape(-1).select(*self.loss.in_keys, strict=False))  # what the loss reads, no more
        losses, n = None, 0
        if frames >= self.cfg.init_random_frames:
            if self.cfg.updates_per_batch:
                n = self.cfg.updates_per_batch
            else:
                self._member_frames += batch.numel() // self.population
                n, self._member_frames = divmod(self._member_frames, self.cfg.update_frequency)
            losses = self.run_updates(buffer, n)
        while frames >= self._next_exchange:
            self._next_exchange += self.cfg.exchange_every
            self.exchange()
        return losses, n

    def sample(self, buffer) -> TensorDictBase:
        """``P * batch_size`` transitions of the shared buffer, ``batch_size`` per member (``[P, batch_size]``)."""
        p, b = self.population, self.cfg.batch_size
        with warnings.catch_warnings():  # the run's buffer is built with batch_size (one member's): P of them here
            warnings.filterwarnings("ignore", message="Got conflicting batch_sizes")
            batch = buffer.sample(p * b)
        return batch.to(self.device).reshape(p, b)

    def _record_returns(self, batch: TensorDictBase) -> None:
        """Add the discounted returns of the episodes ending in ``batch`` ``[P * N, T]`` to their
        members' sums, on the device (member ``p`` owns rows ``p * N .. p * N + N - 1``): no host read."""
        nxt = batch.get("next")
        p = self.population
        done = nxt.get("done").reshape(p, -1, 1)
        ret = nxt.get("episode_discounted_return").detach().reshape(p, -1, self._return_sum.shape[-1])
        self._return_sum += torch.where(done, ret.to(self._return_sum.dtype), 0.0).sum(1)
        self._return_count += done.sum((1, 2))

    @torch.no_grad()
    def evaluate_members(self) -> torch.Tensor:
        """``[P, k]``: each member's mean discounted vector return over ``cfg.morld_eval_episodes``
        episodes with sampled actions on a DR env of its own (the authors' archive evaluation after
        every exchange: ``num_eval_episodes_for_front`` = 5 per member, ``morld.py:281-334,576-578``;
        not counted as training frames). All ``P * n`` episodes run at once, sub-env ``i`` driven
        by member ``i // n``; each sub-env's first episode counts."""
        cfg, P, n = self.cfg, self.population, self.cfg.morld_eval_episodes
        if self._eval_env is None:
            self._eval_env = make_member_env(cfg, self.device, n, seed=cfg.seed + 7919)
        env = self._eval_env
        k = self._return_sum.shape[-1]
        returns = torch.zeros(P * n, k, dtype=torch.float64, device=self.device)
        finished = torch.zeros(P * n, dtype=torch.bool, device=self.device)
        limit = domain_of(cfg.env_id).max_episode_steps or 100_000
        with set_exploration_type(ExplorationType.RANDOM):
            td = env.reset()
            for _ in range(limit):
                td, root = env.step_and_maybe_reset(self.explore_policy(td))
                nxt = td.get("next")
                done = nxt.get("done").reshape(-1)
                new = done & ~finished
                ret = nxt.get("episode_discounted_return").reshape(P * n, k).to(returns.dtype)
                returns = torch.where(new.unsqueeze(-1), ret, returns)
                finished |= done
                if bool(finished.all()):
                    break
                td = root
        self.eval_episodes += int(finished.sum())
        return returns.reshape(P, n, k).mean(1).cpu()

    def member_evaluations(self) -> torch.Tensor:
        """``[P, k]``: each member's mean discounted return since the last exchange (NaN: no episode ended)."""
        total, count = self._return_sum.cpu(), self._return_count.unsqueeze(-1).double().cpu()
        return torch.where(count > 0, total / count.clamp(min=1), torch.full_like(total, math.nan))

    @torch.no_grad()
    def exchange(self) -> None:
        """Evaluate the members (:meth:`evaluate_members`; ``morld_eval_episodes=0``: their training
        episodes since the last exchange, :meth:`member_evaluations`), archive them (non-dominated
        filter); with PSA, adapt the weights."""
        evals = self.evaluate_members() if self.cfg.morld_eval_episodes else self.member_evaluations()
        evaluated = ~torch.isnan(evals).any(-1)
        weights = self.loss.weights.detach().cpu()
        if evaluated.any():
            actor = self.loss.actor_network_params.detach().cpu()
            people = [{"weight": weights[p].clone(), "actor": actor.apply(lambda x: x[p].clone())}
                      for p in evaluated.nonzero().flatten().tolist()]
            self.archive.add(evals[evaluated], people)
        if self.cfg.weight_adaptation == "psa" and len(self.archive):
            new = psa_weights(weights.double(), evals, self.archive.evaluations, self.cfg.psa_delta)
            self.loss.set_weights(new.float())
        self._return_sum.zero_()
        self._return_count.zero_()
        self.exchanges += 1

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        state = super().state_dict()
        state["morld"] = {"archive": self.archive.state_dict(), "return_sum": self._return_sum.clone(),
                          "return_count": self._return_count.clone(), "next_exchange": self._next_exchange,
                          "member_frames": self._member_frames, "exchanges": self.exchanges,
                          "eval_episodes": self.eval_episodes}
        return state

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        m = state["morld"]
        self.archive.load_state_dict(m["archive"])
        self._return_sum.copy_(m["return_sum"])
        self._return_count.copy_(m["return_count"])
        self._next_exchange, self._member_frames = m["next_exchange"], m["member_frames"]
        self.exchanges = m["exchanges"]
        self.eval_episodes = m.get("eval_episodes", 0)


# ---------------------------------------------------------------------- builders
def make_member_env(cfg, device: torch.device, per_member: int, *, seed: int):
    """``P * per_member`` sub-envs of ``cfg.env_id`` (member ``p`` owns a block of ``per_member``) + the
    policy's history + discounted vector returns. No preference: a member's weight lives in the
    loss, not in the data."""
    env = make_env(cfg.env_id, num_envs=cfg.pop_size * per_member, device=device, seed=seed)
    env = compose_policy_env(env, history_len=cfg.history_len)
    env.append_transform(DiscountedVectorReturn(run_discount(cfg, domain_of(cfg.env_id))))
    return env


def make_morld_training_env(cfg, device: torch.device):
    """The training env: :func:`make_member_env` with ``num_envs`` sub-envs per member."""
    total = cfg.pop_size * cfg.num_envs
    if cfg.frames_per_batch % total:
        raise ValueError(f"frames_per_batch={cfg.frames_per_batch} must be a multiple of pop_size * num_envs = "
                         f"{cfg.pop_size} * {cfg.num_envs} = {total} (MORL/D's sub-envs), e.g. "
                         f"{total * max(1, cfg.frames_per_batch // total)}")
    if cfg.prioritized:
        raise ValueError("MORL/D samples its shared buffer uniformly: set prioritized=false")
    return make_member_env(cfg, device, cfg.num_envs, seed=cfg.seed)


@torch.no_grad()
def orthogonal_population_init_(module: nn.Module) -> nn.Module:
    """Every member's layers as the authors' ``layer_init``: orthogonal weights (gain 1), zero biases.

    Example:
        >>> from morl_trl.objectives.batched import BatchedLinear
        >>> lin = orthogonal_population_init_(BatchedLinear(2, 4, 3, init="torch"))
        >>> w = lin.weight[1]  # [in, out]
        >>> torch.allclose(w.T @ w, torch.eye(3), atol=1e-5), bool((lin.bias == 0).all())
        (True, True)
    """
    for m in module.modules():
        if isinstance(m, BatchedLinear):
            m.reset_parameters("orthogonal")
    return module


def make_morld_agent(cfg, env, *, gamma: float, device: torch.device) -> MORLDAgent:
    """The population (continuous or discrete, from the env's action spec), its loss, optimizers
    (one Adam per network kind over all members), targets and acting views."""
    spec = action_spec(env)
    (obs_dim,) = obs_shape(env)
    k = num_objectives(env)
    p = cfg.pop_size
    weights = energy_weights(k, p, seed=cfg.seed, dtype=torch.float32) if p >= k else None
    if weights is None:
        raise ValueError(f"pop_size={p} is below the number of objectives {k}: the energy weights include the "
                         f"{k} corners of the simplex; use pop_size >= {k}")
    if is_discrete(spec):
        n = spec.space.n
        actor = make_population_categorical_actor(p, obs_dim, n, num_cells=cfg.hidden, action_spec=spec).to(device)
        critic = make_population_q_network(p, obs_dim, n, k, num_cells=cfg.hidden).to(device)
        orthogonal_population_init_(actor), orthogonal_population_init_(critic)  # the authors' init
        loss = PopulationMOSACLoss(actor, critic, weights=weights, num_actions=n, alpha_init=cfg.alpha,
                                   fixed_alpha=not cfg.learn_alpha, target_entropy_weight=cfg.target_entropy_scale,
                                   alpha_loss_form=cfg.alpha_loss_form)
    else:
        actor = make_population_gaussian_actor(p, obs_dim, spec.to(device), num_cells=cfg.hidden,
                                               scale=cfg.actor_scale).to(device)
        critic = make_population_critic(p, obs_dim, spec.shape[-1], k, num_cells=cfg.hidden).to(device)
        orthogonal_population_init_(actor), orthogonal_population_init_(critic)  # the authors' init
        loss = PopulationMOSACLoss(actor, critic, weights=weights, alpha_init=cfg.alpha,
                                   fixed_alpha=not cfg.learn_alpha, action_spec=spec,
                                   alpha_loss_form=cfg.alpha_loss_form)
    orthogonal_critic_copies_(loss, critic, orthogonal_population_init_)  # (the loss re-draws its critic copies)
    loss.make_value_estimator(gamma=gamma)
    explore, _ = population_policies(actor, loss.weights)
    holder: dict = {}
    evaluate = archive_eval_policy(actor, loss.weights, lambda: holder["agent"].snapshots())
    agent = MORLDAgent(cfg, loss, explore, evaluate, actor_critic_optimizers(cfg, loss), target_updater(cfg, loss),
                       device=device, num_envs_per_member=cfg.num_envs, eval_exploration=eval_exploration(cfg))
    holder["agent"] = agent
    return agent
