"""MORL/D (Felten et al., 2024) with a shared replay buffer: ``morl-trl train morld|morld_psa <id>``.

A population of ``P`` MOSAC learners (continuous or discrete actions), member ``p`` with its own
scalarization weight ``w_p`` (the authors: pymoo's energy weights for ``P``, ``seed`` = the run's
seed), all trained from ONE shared replay buffer (SB). Every ``exchange_every`` frames the members'
returns go into a Pareto archive and, with ``weight_adaptation="psa"`` (SB+PSA), each weight moves by
Pareto simulated annealing away from its nearest archived neighbour. Evaluation: for each evaluation
weight the archive's snapshot of nearest weight acts (:class:`ArchiveSnapshotRouter`), sampling actions.

:func:`train_morld` is the recipe (env -> population, loss, optimizers -> shared buffer and collector ->
the loop); a :class:`MORLDAgent` holds what lives between batches and in checkpoints. The loop, and
anything driving an agent batch by batch, calls ``on_batch(agent, batch, buffer, frames)`` (record the
returns, store, the updates, the exchange), whose one gradient update is :func:`update`.

The population is ONE batched module (:class:`~morl_trl.objectives.population.PopulationMOSACLoss`:
every parameter stacked ``[P, ...]``), trained on one of two schedules (``morld_schedule``):

* ``"round_robin"`` (default, the authors' ``MORLD.train``, ``morld.py:421-431,559-567``): member
  ``p = e mod P`` acts alone for the ``e``-th turn of ``exchange_every`` frames, one update of ITS
  parameters per ``update_frequency`` frames once the shared frame counter passed ``init_random_frames`` (its
  actor steps and target copies on the shared counter's clock, as the authors' ``global_step``).
  At the end of the turn every other member gets ``morld_update_passes`` (10) catch-up updates, the
  members are evaluated and archived (PSA adapts the weights) and the env is reset
  (:meth:`MORLDAgent.env_reset_due`: each member's ``train()`` starts with ``env.reset()``). An update
  steps only its members (:class:`~morl_trl.training.optim.MemberAdam`, :class:`MemberTargetUpdate`);
  the others' parameters, moments and targets stay bit for bit. The acting member's updates compute it
  alone (:meth:`PopulationMOSACLoss.only_member
  <morl_trl.objectives.population.PopulationMOSACLoss.only_member>`, ``1 / P`` of the work), equal to
  float rounding to a masked update of all (``MORLDAgent.slice_acting_member = False``; compared in
  ``tests/recipes/test_morld_round_robin.py``). ``frames`` counts the acting member's frames: the run
  takes ``ceil(frames / exchange_every)`` turns (:func:`round_robin_turns`).
* ``"concurrent"`` (faster, most of all on a GPU; not the authors'): ``P * num_envs`` sub-envs, member
  ``p`` acting in block ``p``; one optimizer step updates all members, one update per
  ``update_frequency`` of its own frames, with no catch-up updates and no reset at an exchange.

After every exchange each member is evaluated as the authors': the mean discounted vector return
of ``morld_eval_episodes`` (5) episodes with sampled actions on a DR env of its own
(:meth:`MORLDAgent.evaluate_members`); ``0`` archives the mean return of its training episodes since
the last exchange instead. A new run first evaluates and archives the untrained members the same way
(:meth:`MORLDAgent.archive_initial_members`, ``morld_archive_initial``). The PSA rule, ``delta = 0.1``, the archive's distance threshold (0.01) and
the weights' L1 renormalisation are MORL-Baselines 1.3.0's.

Example:
    >>> from morl_trl.recipes import resolve_config
    >>> cfg = resolve_config("morld_psa", "MOLavaGridDR-v0", quick=True, hidden=(16,))
    >>> env = make_morld_training_env(cfg, torch.device("cpu"))
    >>> env.batch_size, cfg.pop_size, cfg.weight_adaptation, cfg.morld_schedule
    (torch.Size([1]), 5, 'psa', 'round_robin')
    >>> agent = make_morld_agent(cfg, env, gamma=0.995, device=torch.device("cpu"))
    >>> agent.loss.weights.shape, agent.active
    (torch.Size([5, 2]), 0)
    >>> round_robin_turns(3_000_000, 20_000, 6)  # the authors' Hopper: 150 turns, 25 per member
    [25, 25, 25, 25, 25, 25]
"""

from __future__ import annotations

import contextlib
import math
import warnings

import torch
from tensordict import TensorDictBase
from torch import nn
from torchrl.envs.utils import ExplorationType, set_exploration_type

from morl_trl._torchrl_compat import reset_collector
from morl_trl.envs import domain_of, make_env
from morl_trl.metrics import is_nondominated
from morl_trl.objectives import PolyakUpdate
from morl_trl.objectives.batched import BatchedLinear
from morl_trl.objectives.networks import categorical_actor, tanh_normal_actor
from morl_trl.algorithms.actor_critic.recipe import gradient_step, orthogonal_critic_copies_
from morl_trl.objectives.population import (PopulationMOSACLoss, nearest_member, make_population_categorical_actor,
                                            make_population_critic, make_population_gaussian_actor,
                                            make_population_q_network, population_policies)
from morl_trl.preferences import energy_weights
from morl_trl.training.agent import (Agent, NonFiniteLossError, action_spec, actor_critic_optimizers, eval_exploration,
                                     is_discrete, num_objectives, obs_shape, target_updater)
from morl_trl.training.allocator import tune_malloc
from morl_trl.training.optim import MemberAdam, fused_choice
from morl_trl.training.parts import (load_agent_state, checkpoint_snapshot, check_buffer_memory, load_reference,
                                     make_collector, make_evaluator, make_replay_buffer, run_discount, run_domain,
                                     start_notes)
from morl_trl.runs.run import Run
from morl_trl.transforms import DiscountedVectorReturn, compose_policy_env

__all__ = ["ActiveMemberRouter", "ArchiveSnapshotRouter", "MORLDAgent", "MemberTargetUpdate", "ParetoArchive",
           "archive_eval_policy", "catch_up_updates", "count_update", "frames_to_collect", "make_member_env",
           "make_morld_agent", "make_morld_training_env", "member_optimizers", "on_batch",
           "orthogonal_population_init_", "own_updates", "psa_weights", "round_robin_turns", "sample_members",
           "train_morld", "update", "update_clocks", "updates_at"]

#: MORL-Baselines 1.3.0: an archived evaluation closer than this (squared distance) is the member itself
PSA_MIN_DISTANCE = 0.01


def psa_weights(weights: torch.Tensor, evaluations: torch.Tensor, archive: torch.Tensor, delta: float,
                min_distance: float = PSA_MIN_DISTANCE) -> torch.Tensor:
    """Pareto simulated annealing (Czyżak & Jaszkiewicz, 1998) as MORL/D adapts its weights.

    For each member (row of ``weights`` ``[P, k]`` with evaluation ``evaluations[p]`` ``[k]``), the nearest
    archived evaluation ``c`` (squared distance above ``min_distance``) is found; objective ``i`` where the member
    is at least as good as ``c`` gets ``w_i * (1 + delta)``, the others ``w_i / (1 + delta)``; the result is
    renormalised to sum 1 (below: the member itself, at distance 0, is skipped and (0, 1) is its neighbour). A
    member with no such neighbour (or a NaN evaluation: not evaluated) keeps its weight.

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


def round_robin_turns(frames: int, exchange_every: int, pop_size: int) -> list[int]:
    """Turns of ``exchange_every`` frames each member gets in a round-robin run of ``frames``
    frames: ``ceil(frames / exchange_every)`` turns, member ``e mod P`` taking the ``e``-th (the authors' loop runs
    whole turns while ``global_step < total_timesteps``; the record's ``derived.exchanges_per_member``).

    Example:
        >>> round_robin_turns(5_000_000, 10_000, 6)  # Half-Cheetah: 500 turns
        [84, 84, 83, 83, 83, 83]
    """
    turns = -(-frames // exchange_every)
    return [turns // pop_size + (1 if p < turns % pop_size else 0) for p in range(pop_size)]


def update_clocks(cfg, start: int, frames: int) -> list[int]:
    """Round robin: the shared-counter frames of the acting member's updates in the batch of frames
    ``start .. frames - 1``, as the authors' MOSAC: after the step of shared index ``g`` (0-based), an
    update when ``g > learning_starts`` and ``g % update_frequency == 0``
    (``mosac_continuous_action.py:558-559``; discrete: ``update_frequency``).

    Example:
        >>> from types import SimpleNamespace
        >>> update_clocks(SimpleNamespace(init_random_frames=4, update_frequency=2), 0, 10)
        [6, 8]
    """
    return [g for g in range(max(start, cfg.init_random_frames + 1), frames) if g % cfg.update_frequency == 0]


def _member_view(mask: torch.Tensor, ndim: int, dim: int) -> torch.Tensor:
    """``[P]`` ``mask`` shaped to broadcast over a ``ndim``-dim tensor with the members along ``dim``."""
    shape = [1] * ndim
    shape[dim] = mask.shape[0]
    return mask.view(shape)


class ActiveMemberRouter(nn.Module):
    """Acting in the round-robin training env: every sub-env is driven by the member ``active``
    (a 0-dim long tensor the agent fills in place at each exchange, so a collector's policy sees it).

    The ``[N, ...]`` inputs run through the population network as ``[P, N, ...]`` (every member
    computes; the rows of ``active`` are kept).
    """

    def __init__(self, net: nn.Module, population: int, active: torch.Tensor) -> None:
        super().__init__()
        self.net, self.population = net, population
        self.active = active  # (not registered: the agent's)

    def forward(self, *inputs: torch.Tensor):
        out = self.net(*(x.unsqueeze(0).expand(self.population, *x.shape) for x in inputs))
        idx = self.active.view(1)
        if isinstance(out, tuple):
            return tuple(o.index_select(0, idx).squeeze(0) for o in out)
        return out.index_select(0, idx).squeeze(0)


class MemberTargetUpdate:
    """The target critics of the round robin, stepped for the members of ``agent.members`` only.

    With ``tau`` (continuous MOSAC): Polyak ``target += tau (source - target)`` at every update;
    without (discrete MOSAC): a hard copy when the update's frame (``agent.clock``, the authors'
    shared ``global_step``) is a multiple of ``period_frames`` (``target_net_freq``,
    ``mosac_discrete_action.py:488-491``). The other members' targets are left as they are (a
    Polyak step of a member that did not learn would still move its targets).
    """

    def __init__(self, loss: PopulationMOSACLoss, agent: "MORLDAgent", *, tau: float | None,
                 period_frames: int) -> None:
        self.sources, self.targets = PolyakUpdate(loss, tau=0.5).leaves()  # (the leaves only: stepped here)
        p = loss.population
        for t in self.targets:
            if t.ndim < 2 or t.shape[1] != p:
                raise ValueError(f"a target critic leaf of shape {tuple(t.shape)} is not [n, P={p}, ...]")
        self.tau, self.period_frames = tau, int(period_frames)
        self._agent = agent

    @torch.no_grad()
    def step(self) -> None:
        agent = self._agent
        clock = agent.clock if agent.clock is not None else agent.critic_steps  # (off the shared clock: updates)
        if self.tau is None and clock % self.period_frames:
            return
        if agent.sliced_member is not None:  # one member: its slices alone (the masked step's arithmetic)
            m = agent.sliced_member
            for source, target in zip(self.sources, self.targets):
                t, s = target.select(1, m), source.select(1, m)
                t.copy_(s if self.tau is None else t.lerp(s, self.tau))
            return
        for source, target in zip(self.sources, self.targets):
            new = source if self.tau is None else target.lerp(source, self.tau)
            target.copy_(torch.where(_member_view(agent.members, target.ndim, 1), new, target))


def member_optimizers(cfg, loss: PopulationMOSACLoss) -> dict:
    """:func:`~morl_trl.training.agent.actor_critic_optimizers` as :class:`~morl_trl.training.optim.MemberAdam`
    (the same learning rates, ``adam_eps`` and ``fused_optimizer``): actor ``[P, ...]``, critics ``[n, P, ...]``, temperatures ``[P]``."""
    kw = {"fused": fused_choice(cfg)}  # (torch's fused kernel where it has one, as the other recipes' adam())
    if cfg.adam_eps is not None:
        kw["eps"] = cfg.adam_eps
    q_lr = cfg.lr if cfg.q_lr is None else cfg.q_lr
    p = loss.population
    opts = {"actor": MemberAdam(loss.actor_network_params.values(True, True), cfg.lr, population=p, **kw),
            "qvalue": MemberAdam(loss.qvalue_network_params.values(True, True), q_lr, population=p, member_dim=1, **kw)}
    if isinstance(getattr(loss, "log_alpha", None), nn.Parameter):
        alpha_lr = cfg.lr if cfg.alpha_lr is None else cfg.alpha_lr
        opts["alpha"] = MemberAdam([loss.log_alpha], alpha_lr, population=p, **kw)
    return opts


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
    """The MORL/D population and what lives between batches (see the module docstring): the members'
    returns, the archive, the exchanges, the turn and the counters. Its updates are :func:`update`'s.

    Round robin: :attr:`active` is the member whose turn it is, :attr:`members` the ``[P]`` mask of the members the
    current update steps, :attr:`clock` that update's frame on the shared counter; :attr:`member_updates` /
    :attr:`member_frames` count, per member, the updates it received (its own and the catch-up ones) and the frames
    it collected, :attr:`env_resets` the resets at exchanges.
    """

    #: round robin: the acting member's own updates compute that member alone (``False``: every
    #: member computes and the step is masked to it, the reference the tests compare against;
    #: slower by about the population size)
    slice_acting_member: bool = True

    def __init__(self, cfg, loss: PopulationMOSACLoss, explore_policy, eval_policy, optimizers, updater, *, device,
                 num_envs_per_member: int, eval_exploration, member_policy=None) -> None:
        super().__init__(cfg, loss, explore_policy, eval_policy, optimizers, updater, device=device,
                         eval_exploration=eval_exploration)
        self.population = loss.population
        self.num_envs_per_member = num_envs_per_member
        self.round_robin = cfg.morld_schedule == "round_robin"
        self.member_policy = member_policy if member_policy is not None else explore_policy  # sub-env i: member i // n
        self.archive = ParetoArchive()
        k = loss.num_objectives
        P = self.population
        self._return_sum = torch.zeros(P, k, dtype=torch.float64, device=device)
        self._return_count = torch.zeros(P, dtype=torch.long, device=device)
        self._next_exchange = cfg.exchange_every
        self._member_frames = 0  # member frames not yet turned into updates (update_frequency)
        self.exchanges = 0
        self.eval_episodes = 0  # archive-evaluation episodes run so far (not training frames)
        self._eval_env = None  # the members' evaluation env (evaluate_members), built on first use
        self._snapshots = (None, None)  # (archive version, stacked snapshots) cache of snapshots()
        # round robin
        self.active_member = torch.zeros((), dtype=torch.long, device=device)  # read by the acting router
        self.members = torch.ones(P, dtype=torch.bool, device=device)  # who the next update steps (updated in place)
        for opt in optimizers.values():
            if isinstance(opt, MemberAdam):
                opt.members = self.members
        self.clock: int | None = None  # (None: an update off the shared clock, counted as the concurrent schedule's)
        self.turn_frames = 0
        self.member_updates = torch.zeros(P, dtype=torch.long)
        self.member_frames = torch.zeros(P, dtype=torch.long)
        self.env_resets = 0
        self._reset_due = False  # (env_reset_due)
        #: the member whose own update, computed for it alone, is running (``None`` outside one)
        self.sliced_member: int | None = None

    @property
    def active(self) -> int:
        """The member whose turn it is (round robin)."""
        return int(self.active_member)

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

    # ------------------------------------------------------------------ schedules
    def concurrent_updates_due(self, batch: TensorDictBase) -> int:
        """Concurrent: the updates of all members this batch earns, ``cfg.updates_per_batch``, or (0) one
        per ``update_frequency`` of each member's frames (a remainder carries over to the next batch)."""
        if self.cfg.updates_per_batch:
            return self.cfg.updates_per_batch
        self._member_frames += batch.numel() // self.population
        n, self._member_frames = divmod(self._member_frames, self.cfg.update_frequency)
        return n

    def exchanges_due(self, frames: int) -> int:
        """Concurrent: the exchanges due after ``frames`` frames (one per ``exchange_every`` frames passed)."""
        n = 0
        while frames >= self._next_exchange:
            self._next_exchange += self.cfg.exchange_every
            n += 1
        return n

    @property
    def catch_up_passes(self) -> int:
        """Round robin: the catch-up updates each other member gets at an exchange (``morld_update_passes``;
        none with one member)."""
        return self.cfg.morld_update_passes if self.population > 1 else 0

    def next_turn(self) -> None:
        """Round robin: the next member's turn (``(active + 1) mod P``), on a reset env: :meth:`env_reset_due`
        says so once."""
        self.active_member.fill_((self.active + 1) % self.population)
        self.turn_frames = 0
        self._reset_due = True

    def env_reset_due(self) -> bool:
        """Round robin: ``True`` once after each :meth:`next_turn` (counted in :attr:`env_resets`): the training
        loop restarts every episode (``collector`` reset) before the next member's first batch, as the authors'
        ``train()`` starts with ``env.reset()`` (``mosac_continuous_action.py:526``)."""
        due, self._reset_due = self._reset_due, False
        self.env_resets += int(due)
        return due

    def record_returns(self, batch: TensorDictBase) -> None:
        """Add the discounted returns of the episodes ending in ``batch`` to their members' sums, on the
        device (no host read): round robin, all to the active member; concurrent (``[P * N, T]``), member
        ``p`` owns rows ``p * N .. p * N + N - 1``."""
        nxt = batch.get("next")
        p = 1 if self.round_robin else self.population
        k = self._return_sum.shape[-1]
        done = nxt.get("done").reshape(p, -1, 1)
        ret = nxt.get("episode_discounted_return").detach().reshape(p, -1, k)
        total = torch.where(done, ret.to(self._return_sum.dtype), 0.0).sum(1)
        count = done.sum((1, 2))
        if self.round_robin:
            a = self.active_member.view(1)
            self._return_sum.index_add_(0, a, total)
            self._return_count.index_add_(0, a, count)
        else:
            self._return_sum += total
            self._return_count += count

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
                td, root = env.step_and_maybe_reset(self.member_policy(td))
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
    def archive_initial_members(self) -> bool:
        """Before training: evaluate the untrained members (:meth:`evaluate_members`) and archive them, as the
        authors' and MORL-Baselines' ``train()`` does before its loop (SPEC §6; MB 1.3.0 ``morld.py:537-543``):
        no weight adaptation, no exchange counted. Only with ``cfg.morld_archive_initial``, separate evaluation
        episodes (``morld_eval_episodes > 0``) and an empty archive (a resumed run keeps its own); returns
        whether it archived."""
        cfg = self.cfg
        if not (cfg.morld_archive_initial and cfg.morld_eval_episodes) or len(self.archive):
            return False
        self._archive(self.evaluate_members())
        return True

    def _archive(self, evals: torch.Tensor) -> None:
        """Add the members with finite ``evals [P, k]`` and their current weights and actors to the archive
        (non-dominated filter)."""
        evaluated = ~torch.isnan(evals).any(-1)
        weights = self.loss.weights.detach().cpu()
        if evaluated.any():
            actor = self.loss.actor_network_params.detach().cpu()
            people = [{"weight": weights[p].clone(), "actor": actor.apply(lambda x: x[p].clone())}
                      for p in evaluated.nonzero().flatten().tolist()]
            self.archive.add(evals[evaluated], people)

    @torch.no_grad()
    def exchange(self) -> None:
        """Evaluate the members (:meth:`evaluate_members`; ``morld_eval_episodes=0``: their training
        episodes since the last exchange, :meth:`member_evaluations`), archive them (non-dominated
        filter); with PSA, adapt the weights."""
        evals = self.evaluate_members() if self.cfg.morld_eval_episodes else self.member_evaluations()
        self._archive(evals)
        if self.cfg.weight_adaptation == "psa" and len(self.archive):
            new = psa_weights(self.loss.weights.detach().cpu().double(), evals, self.archive.evaluations, self.cfg.psa_delta)
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
                          "eval_episodes": self.eval_episodes, "schedule": self.cfg.morld_schedule,
                          "active": self.active, "turn_frames": self.turn_frames,
                          "member_updates": self.member_updates.clone(), "frames_per_member": self.member_frames.clone(),
                          "env_resets": self.env_resets}
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
        schedule = m.get("schedule", "concurrent")  # (a state written before the round robin: concurrent)
        if schedule == "round_robin" and not self.round_robin:  # (its Adams count steps per member)
            raise ValueError("this MORL/D state was trained with morld_schedule='round_robin' (one Adam step count per "
                             "member); the config says 'concurrent': set morld_schedule='round_robin' to load it")
        # (older states: member 0's turn, nothing counted yet)
        self.active_member.fill_(int(m.get("active", 0)))
        self.turn_frames = int(m.get("turn_frames", 0))
        self.member_updates = torch.as_tensor(m.get("member_updates", torch.zeros(self.population)), dtype=torch.long).clone()
        self.member_frames = torch.as_tensor(m.get("frames_per_member", torch.zeros(self.population)),
                                             dtype=torch.long).clone()
        self.env_resets = int(m.get("env_resets", 0))


# ---------------------------------------------------------------------- learning
def frames_to_collect(cfg, frames_done: int) -> int:
    """The frames the collector still has to collect when ``frames_done`` are done: ``cfg.frames - frames_done``;
    round robin, those of the whole turns still to go (the run ends after the turn that reaches ``frames``, as
    the authors' ``while global_step < total_timesteps``).

    Example:
        >>> from types import SimpleNamespace
        >>> cfg = SimpleNamespace(morld_schedule="round_robin", frames=50_001, exchange_every=20_000)
        >>> frames_to_collect(cfg, 0), frames_to_collect(cfg, 40_000)
        (60000, 20000)
    """
    if cfg.morld_schedule != "round_robin":
        return cfg.frames - frames_done
    e = cfg.exchange_every
    return -(-cfg.frames // e) * e - frames_done


def sample_members(agent: MORLDAgent, buffer, *, catch_up: bool = False) -> TensorDictBase:
    """The batch of one update: ``[P, batch_size]`` transitions of the shared buffer, ``batch_size`` per member;
    round robin, the acting member's own update (not ``catch_up``): one ``batch_size`` draw, ``[1, batch_size]``
    when it is computed alone (:attr:`MORLDAgent.sliced_member`), else repeated over the rows (the others'
    updates are masked)."""
    p, b = agent.population, agent.cfg.batch_size
    if agent.sliced_member is not None:
        return buffer.sample(b).to(agent.device).unsqueeze(0)
    if agent.round_robin and not catch_up:
        return buffer.sample(b).to(agent.device).expand(p, b)
    with warnings.catch_warnings():  # the run's buffer is built with batch_size (one member's): P of them here
        warnings.filterwarnings("ignore", message="Got conflicting batch_sizes")
        batch = buffer.sample(p * b)
    return batch.to(agent.device).reshape(p, b)


def count_update(agent: MORLDAgent) -> bool:
    """Counts one more update (``agent.critic_steps``); whether it is an actor turn. On the shared clock (round
    robin, ``agent.clock`` set): when that frame is a multiple of ``policy_freq``, as the authors'
    ``global_step % policy_freq == 0`` (a catch-up update at an exchange, whose frame is a multiple of
    ``exchange_every``: the actor steps); otherwise every ``policy_freq``-th update (the 2nd, 4th, ... for 2)."""
    agent.critic_steps += 1
    clock = agent.clock if agent.round_robin and agent.clock is not None else agent.critic_steps
    return clock % agent.cfg.policy_freq == 0


def update(agent: MORLDAgent, buffer, *, catch_up: bool = False) -> TensorDictBase:
    """One gradient update of the members of ``agent.members`` (concurrent: all of them) on a sample of the
    shared ``buffer`` (:func:`sample_members`); returns its losses. ``catch_up``: a round robin's catch-up
    update of the other members at an exchange.

    The step is the actor-critics' (:func:`~morl_trl.algorithms.actor_critic.recipe.gradient_step`), in the
    authors' MOSAC order (``mosac_continuous_action.py:460-482``, ``mosac_discrete_action.py:480-492``): the
    critic step; on an actor turn (:func:`count_update`) ``policy_freq`` actor steps, each followed by the
    temperature's; then the target critics (round robin: :class:`MemberTargetUpdate`, the stepped members'
    only). A non-finite loss raises :class:`~morl_trl.training.optim.NonFiniteLossError` before its step.

    The acting member's own update (round robin, ``slice_acting_member``, not ``catch_up``) runs inside
    :meth:`PopulationMOSACLoss.only_member <morl_trl.objectives.population.PopulationMOSACLoss.only_member>`
    (a ``[1, batch_size]`` sample); its ``entropy`` is reported at its row of a ``[P]`` vector, NaN for the others.
    """
    loss = agent.loss
    member = agent.active if agent.round_robin and agent.slice_acting_member and not catch_up else None
    agent.sliced_member = member
    try:
        with loss.only_member(member) if member is not None else contextlib.nullcontext():
            batch = sample_members(agent, buffer, catch_up=catch_up)
            actor_turn = count_update(agent)
            out, _ = gradient_step(agent, batch, actor_turn)  # the actor-critics' step, on the population's loss
            agent.target_updater.step()
    finally:
        agent.sliced_member = None
    out = out.detach()
    entropy = out.get("entropy", None)
    if member is not None and entropy is not None and entropy.shape[-1:] == (1,) and agent.population > 1:
        full = torch.full((agent.population,), float("nan"), dtype=entropy.dtype, device=entropy.device)
        out.set("entropy", full.index_copy(0, agent.active_member.view(1), entropy.reshape(1)))
    return out


def updates_at(agent: MORLDAgent, buffer, clocks: list, *, catch_up: bool = False, done: int = 0):
    """One :func:`update` at each shared-counter frame of ``clocks`` (``None``: off the shared clock, the
    concurrent schedule's); returns the last losses (``None``: no update). A
    :class:`~morl_trl.training.optim.NonFiniteLossError` carries ``updates_done``: ``done`` (this batch's
    updates before these) plus those applied here."""
    losses = None
    try:
        for i, g in enumerate(clocks):
            agent.clock = g
            try:
                losses = update(agent, buffer, catch_up=catch_up)
            except NonFiniteLossError as err:
                err.updates_done = done + i
                raise
    finally:
        agent.clock = None
    return losses


def own_updates(agent: MORLDAgent, buffer, clocks: list[int]) -> TensorDictBase | None:
    """Round robin: one update of the acting member alone at each shared-counter frame of ``clocks`` (only its
    parameters, Adam moments and targets step); returns the last losses (``None``: none)."""
    a = agent.active
    agent.members.copy_(torch.arange(agent.population, device=agent.members.device) == a)  # (the optimizers' mask)
    losses = updates_at(agent, buffer, clocks)
    agent.member_updates[a] += len(clocks)
    return losses


def catch_up_updates(agent: MORLDAgent, buffer, frames: int, *, done: int) -> TensorDictBase | None:
    """Round robin, at the exchange after ``frames`` frames (the authors' ``morld.py:559-567``):
    :attr:`~MORLDAgent.catch_up_passes` updates of every member but the acting one, all at once (their own
    ``batch_size`` samples each, at the shared frame ``frames``); ``done``: the batch's updates before them."""
    passes = agent.catch_up_passes
    if not passes:
        return None
    agent.members.copy_(torch.arange(agent.population, device=agent.members.device) != agent.active)
    losses = updates_at(agent, buffer, [frames] * passes, catch_up=True, done=done)
    agent.member_updates[agent.members.cpu()] += passes
    return losses


def on_batch(agent: MORLDAgent, batch: TensorDictBase, buffer, frames: int) -> tuple[TensorDictBase | None, int]:
    """What :func:`train_morld`'s loop does with one collected ``batch`` (``frames``: the frames collected so
    far, this batch included); returns ``(last losses or None, updates done)``.

    Record the finished episodes' returns (the archive's evaluation with ``morld_eval_episodes=0``), store the
    batch in the buffer all members share, then: round robin, the acting member's own updates at the frames of
    :func:`update_clocks` and, at the end of its turn, the other members' catch-up updates, the exchange and the
    next member's turn (on a reset env: :meth:`MORLDAgent.env_reset_due`); concurrent, the updates of all members
    this batch earns once ``frames`` reaches ``init_random_frames``, and the exchanges due. A
    :class:`~morl_trl.training.optim.NonFiniteLossError` carries ``updates_done``: those applied before it.
    """
    cfg = agent.cfg
    agent.record_returns(batch)
    agent.store(buffer, batch)
    if not agent.round_robin:  # every member acts in its block of sub-envs, all updated together
        losses, updates = None, 0
        if frames >= cfg.init_random_frames:
            updates = agent.concurrent_updates_due(batch)
            losses = updates_at(agent, buffer, [None] * updates)
        for _ in range(agent.exchanges_due(frames)):
            agent.exchange()
        return losses, updates
    # the authors' MORLD.train: member `agent.active` acts for exchange_every frames
    agent.member_frames[agent.active] += batch.numel()
    agent.turn_frames += batch.numel()
    clocks = update_clocks(cfg, frames - batch.numel(), frames)  # one per update_frequency frames
    losses = own_updates(agent, buffer, clocks)
    updates = len(clocks)
    if agent.turn_frames >= cfg.exchange_every:  # the exchange (morld.py:559-578)
        out = catch_up_updates(agent, buffer, frames, done=updates)  # morld_update_passes per other member
        losses = out if out is not None else losses
        updates += agent.catch_up_passes
        agent.exchange()  # evaluate the members, archive them, PSA: adapt the weights
        agent.next_turn()  # the next member, on a reset env
    return losses, updates


# ---------------------------------------------------------------------- builders
def make_member_env(cfg, device: torch.device, per_member: int, *, seed: int, members: int | None = None):
    """``members * per_member`` sub-envs of ``cfg.env_id`` (default ``members = P``: member ``p`` owns a block
    of ``per_member``) + the policy's history + discounted vector returns. No preference: a member's
    weight lives in the loss, not in the data."""
    members = cfg.pop_size if members is None else members
    env = make_env(cfg.env_id, num_envs=members * per_member, device=device, seed=seed)
    env = compose_policy_env(env, history_len=cfg.history_len)
    env.append_transform(DiscountedVectorReturn(run_discount(cfg, domain_of(cfg.env_id))))
    return env


def make_morld_training_env(cfg, device: torch.device):
    """The training env: round robin, ``num_envs`` sub-envs the acting member steps; concurrent,
    :func:`make_member_env` with ``num_envs`` sub-envs per member."""
    if cfg.prioritized:
        raise ValueError("MORL/D samples its shared buffer uniformly: set prioritized=false")
    if cfg.morld_schedule == "round_robin":
        if cfg.frames_per_batch % cfg.num_envs or cfg.exchange_every % cfg.frames_per_batch:
            raise ValueError(f"round robin turns are whole batches of whole steps: exchange_every={cfg.exchange_every} "
                             f"must be a multiple of frames_per_batch={cfg.frames_per_batch}, itself a multiple of "
                             f"num_envs={cfg.num_envs} (e.g. frames_per_batch=50 with num_envs=1)")
        if cfg.updates_per_batch:
            raise ValueError(f"round robin updates the acting member once per update_frequency frames; "
                             f"updates_per_batch={cfg.updates_per_batch} is for morld_schedule='concurrent': set "
                             f"updates_per_batch=0")
        return make_member_env(cfg, device, cfg.num_envs, seed=cfg.seed, members=1)
    total = cfg.pop_size * cfg.num_envs
    if cfg.frames_per_batch % total:
        raise ValueError(f"frames_per_batch={cfg.frames_per_batch} must be a multiple of pop_size * num_envs = "
                         f"{cfg.pop_size} * {cfg.num_envs} = {total} (MORL/D's sub-envs), e.g. "
                         f"{total * max(1, cfg.frames_per_batch // total)}")
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
    by_member, _ = population_policies(actor, loss.weights)
    holder: dict = {}
    evaluate = archive_eval_policy(actor, loss.weights, lambda: holder["agent"].snapshots())
    kw = dict(device=device, num_envs_per_member=cfg.num_envs, eval_exploration=eval_exploration(cfg),
              member_policy=by_member)
    if cfg.morld_schedule == "concurrent":
        agent = MORLDAgent(cfg, loss, by_member, evaluate, actor_critic_optimizers(cfg, loss),
                           target_updater(cfg, loss), **kw)
    else:
        active = torch.zeros((), dtype=torch.long, device=device)
        tdm = actor.module[0]
        make = tanh_normal_actor if "loc" in tdm.out_keys else categorical_actor
        action_key = actor.module[-1].out_keys[0]
        explore = make(ActiveMemberRouter(tdm.module, p, active), tdm.in_keys, actor.spec[action_key], action_key)
        agent = MORLDAgent(cfg, loss, explore, evaluate, member_optimizers(cfg, loss), None, **kw)
        agent.active_member = active
        agent.target_updater = MemberTargetUpdate(
            loss, agent, tau=cfg.tau,
            period_frames=(cfg.target_update_period or 1) * cfg.update_frequency)  # (target_net_freq, in frames)
    holder["agent"] = agent
    return agent


# ---------------------------------------------------------------------- the recipe
def train_morld(run: Run) -> tuple[dict, MORLDAgent]:
    """Train MORL/D (``morld``, or ``morld_psa``: with Pareto simulated annealing of the weights) in ``run``
    (opened by :func:`~morl_trl.recipes.off_policy.run_training`: a new run or the continuation of one), on
    either schedule (``morld_schedule``, see the module docstring); returns ``(last evaluation summary, agent)``.
    """
    cfg = run.cfg
    device = torch.device(cfg.device)
    spec = run_domain(cfg)

    # 1. the env (everything is built before the run directory is touched: a failed start writes nothing).
    # Round robin: num_envs sub-envs the acting member steps; concurrent: num_envs per member, P blocks.
    env = make_morld_training_env(cfg, device)

    # 2. the modules (make_morld_agent): the population's actor and critics (every parameter [P, ...]), the
    # loss (PopulationMOSACLoss, each member's weight), the optimizers (round robin: MemberAdam, one Adam
    # per member) and targets (MemberTargetUpdate), the acting router, the Pareto archive's evaluation policy
    tune_malloc()  # (the allocator for training, as build_agent)
    agent = make_morld_agent(cfg, env, gamma=run_discount(cfg, spec), device=device)
    reference = load_reference(cfg, spec)
    evaluator = make_evaluator(cfg, agent, spec, reference)  # (the archive snapshot nearest each evaluation weight)

    # 3. the shared replay buffer, a resumed run's state, the collector (round robin: whole turns)
    check_buffer_memory(cfg, env, device)
    buffer = make_replay_buffer(cfg, device)
    state = run.restore(buffer, map_location=device, env=env)
    if state is not None:
        load_agent_state(agent, state, run.resume_from, cfg.algo)  # population, optimizers, archive, the turn and the counters
    else:  # a new run: the untrained members archived first (morld_archive_initial; before frame 0's evaluation)
        agent.archive_initial_members()
    collector = make_collector(cfg, env, agent.explore_policy, device, frames_done=run.frames,
                               frames_to_go=frames_to_collect(cfg, run.frames))

    snapshot = checkpoint_snapshot(agent, env, collector, device)  # (what a checkpoint holds)

    # 4. the loop. One iteration = one batch: on_batch (record the finished episodes' returns, store the batch,
    # the updates, the exchange when due), then (run.step) evaluate and checkpoint when due. A checkpoint is the
    # state at the end of a batch (after its evaluation), so the batch after it is the same on a resume.
    with run.session(spec, reference, evaluator=evaluator, snapshot=snapshot, buffer=buffer, collector=collector,
                     notes=start_notes(cfg, run, spec, reference)):
        for batch in collector:  # (uniformly random actions for the first init_random_frames)
            frames = run.collected(batch)
            losses, updates = on_batch(agent, batch, buffer, frames)
            if agent.env_reset_due():  # round robin: the next member starts on a reset env
                reset_collector(collector)
            collector.update_policy_weights_()
            run.step(losses, updates)
    return run.summary, agent
