"""PGMORL (Xu et al. 2020): ``morl-trl train pgmorl``, read top to bottom.

:func:`train_pgmorl` is the recipe (env -> modules and loss -> collector -> the loop). A :class:`PGMORLAgent` holds
what lives between iterations and in checkpoints (the population, the weights, the performance buffer, the Pareto
archive, the prediction model, the ``VecNorm`` statistics). The loop and anything driving an agent batch by batch
call :func:`on_batch` (:func:`advantages`, :func:`minibatches`, :func:`update`, the evolution when due); the frame
budget is :func:`counted_frames` and :func:`frames_to_collect`.

A population of ``P`` PPO agents with vector critics, ONE batched module
(:mod:`morl_trl.objectives.pgmorl`) on ``P x pgmorl_envs_per_member`` sub-envs (member ``p`` owns
sub-envs ``p*E .. p*E+E-1``). One collector batch is one iteration of ``frames_per_batch / num_envs``
steps per member (the authors: 4 envs x 2048 steps); an iteration counts ONE member's frames (``E x 2048``
= 8192) against ``frames``, and the run ends after the warm-up and the whole generation that reaches the
budget (:func:`pgmorl_iterations`: Hopper 3M -> 400 iterations, 3.28M counted frames, 19.7M env steps):

1. per-objective GAE on the normalised rewards (:func:`~morl_trl.objectives.pgmorl.vector_gae`), the
   advantage scalarised with the member's weight and standardised per member and minibatch;
2. ``pgmorl_epochs`` x ``pgmorl_minibatches`` minibatches per member with TorchRL's ``ClipPPOLoss``
   (ratio and value clip ``pgmorl_clip``, no entropy bonus, value loss ``0.5 * 0.5 * max(unclipped,
   clipped)``), the loss scaled by ``P`` so each member's gradient is its own, each member's gradient
   norm clipped to ``max_grad_norm`` (0.5), Adam (eps 1e-5);
3. after ``pgmorl_warmup`` iterations and then every ``pgmorl_evo_iterations``: every member's
   evaluation enters the performance buffer, the Pareto archive and the prediction model, and the task
   selection (:mod:`morl_trl.algorithms.pgmorl.evolution`) gives each slot a (policy, weight) pair: the
   slot copies that policy (Adam moments reset: our choice, the record does not say what the authors'
   copy keeps) and trains it with that weight.

The initial weights are the first ``P`` of the authors' ``generate_weights(delta_weight)``. Observations
and each objective's reward are normalised by TorchRL's ``VecNorm`` and clipped at +-10 (rewards into
``"reward_norm"``, statistics updated with the batch first): the authors' ``NormalizeObservation`` /
``MONormalizeReward`` / clip wrappers of ``mo_ppo.make_env``.

Evaluation acts, for each weight, with the Pareto archive's snapshot of nearest weight (the authors'
``PGMORL.eval``; the population member of nearest weight before the first evaluation), sampling its
actions. ``pgmorl_eval_obs="raw"`` (default) feeds it raw
observations as the authors' evaluation did (SPEC §5, 12), ``"normalized"`` the frozen training normalisation.

Known differences from the authors: a member's evaluation is the mean discounted raw-reward return of its
episodes that ended in the iteration's rollout, not a separate evaluation episode; ``VecNorm`` standardises
the rewards where gym's ``NormalizeReward`` scales them by the std of the discounted return; truncation
bootstraps; the task selection's sparsity is computed on the non-dominated subset
(:func:`morl_trl.metrics.sparsity`). Every iteration starts from a
reset of all sub-envs as the authors' (``pgmorl_reset_each_iteration``), the simulators re-seeded
at that reset with the member's seed as the authors' ``envs.reset(seed=member.seed)``
(``pgmorl_reseed_each_iteration``: member ``p``'s sub-env ``i`` with ``seed + i``, 42 + i once the member
is a copy).

Example:
    >>> from morl_trl.recipes import resolve_config
    >>> cfg = resolve_config("pgmorl", "MOHalfCheetahDR-v5", quick=True, pgmorl_pop=2, num_envs=2,
    ...                      pgmorl_envs_per_member=1, hidden=(8,))
    >>> env = make_pgmorl_training_env(cfg, torch.device("cpu"))
    >>> agent = make_pgmorl_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
    >>> agent.weights.tolist()
    [[0.0, 1.0], [0.20000000298023224, 0.800000011920929]]
"""

from __future__ import annotations

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.envs import ClipTransform
from torchrl.envs.utils import ExplorationType, exploration_type
from torchrl.objectives import ClipPPOLoss

from morl_trl._torchrl_compat import VecNormNonNegativeVar, transform_step
from morl_trl.envs import domain_of, make_env
from morl_trl.metrics import is_nondominated
from morl_trl.objectives.pgmorl import (make_population_ppo_actor, make_population_value_network, scalarize_advantage,
                                        vector_gae)
from morl_trl.training.agent import Agent, action_spec, eval_exploration, is_discrete, num_objectives, obs_shape
from morl_trl.training.allocator import tune_malloc
from morl_trl.training.optim import NonFiniteLossError, adam, fused_choice, optimizer_step
from morl_trl.algorithms.pgmorl.evolution import (PerformanceBuffer, PerformancePredictor, generate_weights,
                                                  nondominated, select_tasks)
from morl_trl.training.parts import (load_agent_state, checkpoint_snapshot, load_reference, make_collector,
                                     make_evaluator, run_discount, run_domain, start_notes)
from morl_trl.runs.run import Run
from morl_trl.transforms import DiscountedVectorReturn, compose_policy_env

__all__ = ["PGMORLAgent", "advantages", "counted_frames", "frames_to_collect", "make_pgmorl_agent",
           "make_pgmorl_training_env", "minibatches", "on_batch", "pgmorl_iterations", "train_pgmorl", "update"]


def pgmorl_iterations(frames: int, frames_per_iteration: int, warmup: int, evo_iterations: int) -> int:
    """The PPO iterations PGMORL runs for a budget of ``frames`` (the authors' count: one member's
    frames, ``frames_per_iteration`` = envs per member x steps per iteration = 8192).

    As the authors' ``PGMORL.train`` (SPEC §6; hyperparameters.toml ``pgmorl.*.derived``):
    ``max_iterations = frames // frames_per_iteration``; all ``warmup`` iterations, then whole
    generations of ``evo_iterations`` while fewer than ``max_iterations`` have run, so the last
    generation overruns the budget (Hopper: 3M frames -> 366 -> 400 iterations, 3.28M frames).

    Example:
        >>> pgmorl_iterations(3_000_000, 4 * 2048, warmup=200, evo_iterations=40)
        400
        >>> pgmorl_iterations(5_000_000, 4 * 2048, warmup=80, evo_iterations=20)
        620
    """
    target = frames // frames_per_iteration
    return warmup + -(-max(0, target - warmup) // evo_iterations) * evo_iterations


def _check_layout(cfg) -> int:
    P, E = cfg.pgmorl_pop, cfg.pgmorl_envs_per_member
    if cfg.num_envs != P * E:
        raise ValueError(f"config key 'num_envs' is {cfg.num_envs}; valid: pgmorl_pop x pgmorl_envs_per_member = "
                         f"{P} x {E} = {P * E} (each member collects on its own sub-envs)")
    if cfg.frames_per_batch % cfg.num_envs:
        raise ValueError(f"config key 'frames_per_batch' is {cfg.frames_per_batch}; valid: a multiple of num_envs "
                         f"({cfg.num_envs}): each sub-env collects frames_per_batch / num_envs steps per iteration")
    return cfg.frames_per_batch // cfg.num_envs


def make_pgmorl_training_env(cfg, device: torch.device):
    """``P x E`` sub-envs of ``cfg.env_id`` + history + ``VecNorm``/clip on observations + vector returns
    (the rewards are normalised on the collected batch, :attr:`PGMORLAgent.reward_norm`: a second reward
    key in the env would make its reward key ambiguous)."""
    _check_layout(cfg)
    gamma = cfg.gamma if cfg.gamma is not None else domain_of(cfg.env_id).gamma
    env = compose_policy_env(make_env(cfg.env_id, num_envs=cfg.num_envs, device=device, seed=cfg.seed),
                             history_len=cfg.history_len)
    spec = action_spec(env)
    if not is_discrete(spec):  # the authors' ClipAction: the env gets the clipped action, the rollout keeps the sample
        env.append_transform(ClipTransform(in_keys_inv=["action"], out_keys_inv=["action"],
                                           low=float(spec.space.low.min()), high=float(spec.space.high.max())).to(device))
    env.append_transform(VecNormNonNegativeVar(in_keys=["observation"], decay=1.0, eps=1e-8, reduce_batch_dims=True))
    # ClipTransform keeps its bounds where it was built: on the env's device (the GPU run found them on the CPU)
    env.append_transform(ClipTransform(in_keys=["observation"], low=-10.0, high=10.0).to(device))
    env.append_transform(DiscountedVectorReturn(gamma))
    return env


class PGMORLEvalPolicy(TensorDictModuleBase):
    """For each row: the Pareto archive's snapshot whose weight is nearest to ``"preference"`` acts on
    ``"observation"`` (raw, or normalised with the training ``VecNorm``'s frozen statistics), as the
    authors' ``PGMORL.eval`` (ties: the first snapshot; theirs: a random one); before the archive holds
    any, the population member of nearest weight. ``snapshots_fn() -> (weights [S, k], states)``:
    ``states[s]`` is a member state of the actor head (:meth:`member_state`)."""

    def __init__(self, head, weights_fn, obs_norm=None, *, low=None, high=None, snapshots_fn=None) -> None:
        super().__init__()
        self.head, self.weights_fn, self.obs_norm = head, weights_fn, obs_norm
        self.snapshots_fn = snapshots_fn
        self.low, self.high = low, high
        self.in_keys, self.out_keys = ["observation", "preference"], ["action"]

    def _snapshot_outputs(self, flat, member, states, P):
        """``(loc, scale)`` per row of the snapshot ``member[row]``: the used snapshots run ``P`` at a time."""
        from torch.func import functional_call

        rows = torch.arange(flat.shape[0], device=flat.device)
        loc = scale = None
        used = member.unique().tolist()
        x = flat.unsqueeze(0).expand(P, *flat.shape)
        for c in range(0, len(used), P):
            chunk = used[c:c + P]
            padded = chunk + [chunk[0]] * (P - len(chunk))
            params = {n: torch.stack([states[i][n] for i in padded]).to(flat.device) for n in states[padded[0]]}
            l, sc = functional_call(self.head, params, (x,))
            if loc is None:
                loc, scale = torch.empty_like(l[0]), torch.empty_like(sc[0])
            for j, i in enumerate(chunk):
                sel = member == i
                loc[sel], scale[sel] = l[j, rows[sel]], sc[j, rows[sel]]
        return loc, scale

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        obs = td.get("observation").float()
        if self.obs_norm is not None:
            loc, scale = self.obs_norm.loc["observation"], self.obs_norm.scale["observation"]
            obs = ((obs - loc.to(obs.device)) / scale.to(obs.device)).clamp(-10.0, 10.0)
        w = td.get("preference").float()
        weights = self.weights_fn().to(w.device)
        flat = obs.reshape(-1, obs.shape[-1])
        P = weights.shape[0]
        snapshots = self.snapshots_fn() if self.snapshots_fn is not None else None
        if snapshots is not None and len(snapshots[1]):
            member = torch.cdist(w.reshape(-1, w.shape[-1]), snapshots[0].to(w.device, torch.float32)).argmin(-1)
            loc, scale = self._snapshot_outputs(flat, member, snapshots[1], P)
        else:
            member = torch.cdist(w.reshape(-1, w.shape[-1]), weights).argmin(-1)
            loc, scale = self.head(flat.unsqueeze(0).expand(P, *flat.shape))
            rows = torch.arange(flat.shape[0], device=flat.device)
            loc, scale = loc[member, rows], scale[member, rows]
        action = loc + scale * torch.randn_like(loc) if exploration_type() == ExplorationType.RANDOM else loc
        if self.low is not None:  # the env's bounds (the authors' ClipAction)
            action = torch.maximum(torch.minimum(action, self.high.to(action.device)), self.low.to(action.device))
        return td.set("action", action.reshape(*obs.shape[:-1], -1))


class PGMORLAgent(Agent):
    """The PGMORL :class:`~morl_trl.training.agent.Agent` (see the module)."""

    def __init__(self, cfg, loss, actor, critic, eval_policy, optimizer, *, weights, steps, gamma, ref_point,
                 device, obs_norm=None) -> None:
        super().__init__(cfg, loss, actor, eval_policy, {"ppo": optimizer}, None, device=device,
                         eval_exploration=eval_exploration(cfg))
        self.actor, self.critic = actor, critic
        self.obs_norm = obs_norm  # the training env's observation VecNorm (its statistics travel with the agent)
        self.head = actor.module[0].module if hasattr(actor.module[0], "module") else actor.module[0]
        self.weights = weights  # [P, k]
        self.P, self.E, self.T = cfg.pgmorl_pop, cfg.pgmorl_envs_per_member, steps
        self.gamma, self.ref_point = gamma, np.asarray(ref_point, dtype=np.float64)
        k = weights.shape[-1]
        self.population = PerformanceBuffer(cfg.pgmorl_num_buffers, cfg.pgmorl_buffer_size, self.ref_point)
        self.predictor = PerformancePredictor()
        self.archive: list = []  # the Pareto archive's evaluations (the task selection's front)
        self.archive_members: list[dict] = []  # its snapshots: {"perf", "weight", "actor"} (the evaluation acts with them)
        self.evals_before = np.full((self.P, k), np.nan)  # NaN: no episode of the member has ended yet
        self.performance = np.full((self.P, k), np.nan)
        self.iteration = 0
        self.generation = 0
        self.rng = np.random.default_rng(cfg.seed)
        #: each member's seed: the run's, then 42 once the task selection made it a copy (the authors'
        #: MOPPO copies are built without a seed, mo_ppo.py:355-377); re-seeds its sub-envs per iteration
        self.member_seeds = [int(cfg.seed)] * self.P
        self.sim_env = None  # the training env's simulators (reseed_env), when pgmorl_reseed_each_iteration
        self.generator = torch.Generator().manual_seed(cfg.seed + 11)
        # TorchRL's VecNorm + clip on the batch's vector rewards -> ("next", "reward_norm")
        self.reward_norm = VecNormNonNegativeVar(in_keys=["reward"], out_keys=["reward_norm"], decay=1.0, eps=1e-8,
                                                 reduce_batch_dims=True)
        self.reward_clip = ClipTransform(in_keys=["reward_norm"], low=-10.0, high=10.0).to(device)

    # ------------------------------------------------------------------ the iteration's data and evolution
    def prepare_batch(self, batch: TensorDictBase) -> TensorDictBase:
        """The collected ``batch`` ``[P * E, T]`` as ``[P, E, T]``: each member's performance recorded from its
        episodes that ended in it (:meth:`record_performance`), then the entries PPO reads, with the vector
        rewards normalised (``VecNorm``, its statistics updated with the batch first) and clipped at +-10 into
        ``("next", "reward_norm")``."""
        b = batch.reshape(self.P, self.E, batch.shape[-1])
        self.record_performance(b)
        b = b.select("observation", "action", "action_log_prob", ("next", "observation"), ("next", "reward"),
                     ("next", "done"), ("next", "terminated")).detach()
        self.reward_clip(transform_step(self.reward_norm, b, b.get("next")))
        return b

    def generation_ends(self) -> bool:
        """Whether the iterations done (:attr:`iteration`) end the warm-up (``pgmorl_warmup``) or a generation
        (every ``pgmorl_evo_iterations`` after it): the members are evaluated and the tasks selected."""
        W, G = self.cfg.pgmorl_warmup, self.cfg.pgmorl_evo_iterations
        return self.iteration == W or (self.iteration > W and (self.iteration - W) % G == 0)

    def reseed_env(self) -> None:
        """The authors' ``envs.reset(seed=member.seed)`` at every member's ``train()`` (``mo_ppo.py:628``):
        member ``p``'s sub-env ``i`` (``p * E + i``) gets ``member_seeds[p] + i`` before the iteration's
        reset; the DR contexts keep their stream (the authors' draw from the global RNG, SPEC §1)."""
        if self.sim_env is not None:
            self.sim_env.reseed_subenvs([self.member_seeds[p] + i for p in range(self.P) for i in range(self.E)])

    def record_performance(self, b: TensorDictBase) -> None:
        """Each member's mean discounted return (raw rewards) over its episodes ending in ``b`` ``[P, E, T]``
        (one host read); a member none of whose episodes ended keeps its last one."""
        k = self.performance.shape[-1]
        done = b.get(("next", "done")).reshape(self.P, -1, 1)  # [P, E * T, 1]
        ret = b.get(("next", "episode_discounted_return")).double().reshape(self.P, -1, k)
        sums = torch.where(done, ret, 0.0).sum(1)
        stats = torch.cat([sums, done.sum(1).double()], -1).cpu().numpy()  # [P, k + 1]: sums, count
        ended = stats[:, k] > 0
        self.performance[ended] = stats[ended, :k] / stats[ended, k:]

    def _member_state(self, p: int) -> dict:
        return {"actor": self.head.member_state(p), "critic": self.critic.module.member_state(p)}

    def evaluate_members(self, *, add_to_prediction: bool) -> None:
        """Every member's evaluation (:attr:`performance`) into the performance buffer (with a copy of the member)
        and the Pareto archive (with a snapshot of its actor); with ``add_to_prediction``, the sample
        (weight, evaluation before, evaluation now) to the prediction model."""
        for p in range(self.P):
            perf = self.performance[p].copy()
            if not np.isfinite(perf).all():
                continue  # not evaluated yet (no episode of it has ended)
            state = self._member_state(p)
            self.population.add(state, perf)
            self.archive = nondominated(self.archive + [perf])
            self._archive_snapshot(perf, self.weights[p].detach().cpu().clone(), state["actor"])
            if add_to_prediction and np.isfinite(self.evals_before[p]).all():
                self.predictor.add(self.weights[p].cpu().numpy(), self.evals_before[p], perf)
            self.evals_before[p] = perf

    def _archive_snapshot(self, perf, weight, actor_state) -> None:
        """The authors' ``ParetoArchive.add``: keep the non-dominated (evaluation, policy copy) pairs."""
        entries = self.archive_members + [{"perf": np.asarray(perf, np.float64), "weight": weight, "actor": actor_state}]
        keep = is_nondominated(np.stack([e["perf"] for e in entries]))
        self.archive_members = [e for e, k in zip(entries, keep) if k]

    def snapshots(self):
        """``(weights [S, k], actor states)`` of the archive (what the evaluation acts with)."""
        if not self.archive_members:
            return None
        return torch.stack([e["weight"] for e in self.archive_members]), [e["actor"] for e in self.archive_members]

    def select_tasks(self) -> None:
        """The prediction-guided task selection (:func:`~morl_trl.algorithms.pgmorl.evolution.select_tasks`, once the
        prediction model has 4 distinct samples): slot ``p`` takes a copy of the chosen policy of the performance
        buffer (its Adam moments reset, seed 42) and trains it with the chosen weight; a new generation."""
        if len({tuple(a) for a in self.predictor.after}) < 4 or not self.population.individuals:
            return  # the prediction model needs 4 distinct samples: the members keep their tasks
        tasks = select_tasks(self.population, self.archive, self.predictor, self.P,
                             delta_weight=self.cfg.pgmorl_delta_weight, ref_point=self.ref_point,
                             sparsity_coef=self.cfg.pgmorl_sparsity, rng=self.rng)
        individuals = self.population.individuals
        opt = self.optimizers["ppo"]
        for p, (i, w, _) in enumerate(tasks):
            state = individuals[i]
            self.head.load_member_state(p, state["actor"])
            self.critic.module.load_member_state(p, state["critic"])
            self.weights[p] = torch.as_tensor(w, dtype=self.weights.dtype)
            self.member_seeds[p] = 42  # (a copy: MOPPO's default seed)
            for group in opt.param_groups:  # a fresh optimizer for the copy (ours: not in the record)
                for param in group["params"]:
                    st = opt.state.get(param, {})
                    for key in ("exp_avg", "exp_avg_sq"):
                        if key in st:
                            st[key][p].zero_()
        self.generation += 1

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        state = super().state_dict()
        state.update(weights=self.weights.clone(), population=self.population.state_dict(), archive=list(self.archive),
                     archive_members=list(self.archive_members),
                     predictor=(list(self.predictor.weights), list(self.predictor.before), list(self.predictor.after)),
                     evals_before=self.evals_before.copy(), performance=self.performance.copy(),
                     iteration=self.iteration, generation=self.generation, member_seeds=list(self.member_seeds),
                     rng=self.rng.bit_generator.state,
                     generator=self.generator.get_state(), reward_norm=self.reward_norm.state_dict(),
                     obs_norm=self.obs_norm.state_dict() if self.obs_norm is not None else None)
        return state

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self.weights.copy_(state["weights"])
        self.population.load_state_dict(state["population"])
        self.archive = list(state["archive"])
        self.archive_members = list(state.get("archive_members", []))
        self.predictor.weights, self.predictor.before, self.predictor.after = (list(x) for x in state["predictor"])
        self.evals_before, self.performance = state["evals_before"].copy(), state["performance"].copy()
        self.iteration, self.generation = state["iteration"], state["generation"]
        # (an older state: every member a copy once a task selection ran; approximately, none may have)
        self.member_seeds = [int(x) for x in state.get("member_seeds", [42 if self.generation else self.cfg.seed] * self.P)]
        self.rng.bit_generator.state = state["rng"]
        self.generator.set_state(state["generator"])
        self.reward_norm.load_state_dict(state["reward_norm"])
        if self.obs_norm is not None and state.get("obs_norm") is not None:
            self.obs_norm.load_state_dict(state["obs_norm"])


def _obs_vecnorm(env):
    from morl_trl.runs.env_state import transforms_of

    for t in transforms_of(env):
        if type(t).__name__.startswith("VecNorm"):
            if "observation" in [k if isinstance(k, str) else k[-1] for k in t.in_keys]:
                return t
    raise ValueError("the PGMORL agent needs its training env (make_pgmorl_training_env)")


def make_pgmorl_agent(cfg, env, *, gamma: float, device: torch.device) -> PGMORLAgent:
    """The PGMORL :class:`PGMORLAgent` of ``cfg`` for ``env`` (:func:`make_pgmorl_training_env`; continuous actions)."""
    steps = _check_layout(cfg)
    spec = action_spec(env)
    if is_discrete(spec):
        raise ValueError(f"pgmorl needs continuous actions (the authors' MO-PPO); {cfg.env_id} has discrete ones")
    k = num_objectives(env)
    if k not in (2, 3):
        raise ValueError(f"pgmorl's performance buffer supports 2 or 3 objectives; {cfg.env_id} has {k}")
    obs_dim = int(np.prod(obs_shape(env)))
    act_dim = int(spec.shape[-1])
    P = cfg.pgmorl_pop
    actor = make_population_ppo_actor(P, obs_dim, act_dim, cfg.hidden).to(device)
    critic = make_population_value_network(P, obs_dim, k, cfg.hidden).to(device)
    loss = ClipPPOLoss(actor, critic, clip_epsilon=cfg.pgmorl_clip, entropy_bonus=False, critic_coeff=0.25,
                       loss_critic_type="l2", normalize_advantage=False, clip_value=cfg.pgmorl_clip)
    optimizer = adam(loss.parameters(), cfg.lr, fused=fused_choice(cfg), eps=1e-5)  # the authors' eps
    grid = torch.as_tensor(generate_weights(cfg.pgmorl_delta_weight, k))
    weights = grid[torch.arange(P) % grid.shape[0]].clone().to(device)
    head = actor.module[0].module
    holder: dict = {}
    obs_norm = _obs_vecnorm(env)
    eval_policy = PGMORLEvalPolicy(head, lambda: holder["agent"].weights,
                                   obs_norm if cfg.pgmorl_eval_obs == "normalized" else None, low=spec.space.low.float(),
                                   high=spec.space.high.float(), snapshots_fn=lambda: holder["agent"].snapshots())
    ref = domain_of(cfg.env_id).hv_ref_point or (-100.0,) * k
    agent = PGMORLAgent(cfg, loss, actor, critic, eval_policy, optimizer, weights=weights, steps=steps, gamma=gamma,
                        ref_point=ref, device=device, obs_norm=obs_norm)
    if cfg.pgmorl_reseed_each_iteration:
        sim = env
        while hasattr(sim, "base_env"):
            sim = sim.base_env
        agent.sim_env = sim
        try:
            agent.reseed_env()  # (checked at once)
        except NotImplementedError as err:
            raise ValueError(f"pgmorl_reseed_each_iteration=true re-seeds every sub-env at each iteration; {err}: "
                             f"set pgmorl_reseed_each_iteration=false") from None
    holder["agent"] = agent
    return agent


def counted_frames(agent: PGMORLAgent, batch: TensorDictBase) -> int:
    """The frames an iteration's ``batch`` counts against the run's budget ``frames``: one member's (``E x T``,
    the authors' 8192). All ``P`` members collect, but the authors' ``global_step`` counts one member's steps
    (SPEC §6)."""
    return batch.numel() // agent.P


def frames_to_collect(agent: PGMORLAgent, frames_done: int) -> int:
    """The collector's frames (all members') of the iterations :func:`pgmorl_iterations` still runs when
    ``frames_done`` frames (as :func:`counted_frames` counts them) are done."""
    cfg, per = agent.cfg, agent.E * agent.T
    total = pgmorl_iterations(cfg.frames, per, cfg.pgmorl_warmup, cfg.pgmorl_evo_iterations)
    return max(0, total - frames_done // per) * cfg.frames_per_batch


@torch.no_grad()
def advantages(agent: PGMORLAgent, b: TensorDictBase) -> TensorDictBase:
    """``[P, E * T]``: each member's transitions of ``b`` ``[P, E, T]`` (:meth:`PGMORLAgent.prepare_batch`) with its
    critic's values, the per-objective GAE (:func:`~morl_trl.objectives.pgmorl.vector_gae` on the normalised
    rewards) and the value targets."""
    critic = agent.critic.module
    value = critic(b.get("observation"))
    next_value = critic(b.get(("next", "observation")))
    adv, target = vector_gae(agent.gamma, agent.cfg.pgmorl_gae_lambda, value, next_value,
                             b.get(("next", "reward_norm")).to(value.dtype), b.get(("next", "done")),
                             b.get(("next", "terminated")))
    return TensorDict({"observation": b.get("observation"), "action": b.get("action"),
                       "action_log_prob": b.get("action_log_prob"), "state_value": value,
                       "value_target": target, "advantage_vector": adv}, b.shape).reshape(agent.P, -1)


def minibatches(agent: PGMORLAgent, flat: TensorDictBase):
    """One epoch: ``pgmorl_minibatches`` minibatches ``[P, N / pgmorl_minibatches]`` of ``flat`` ``[P, N]``, each
    member's own random permutation (``agent.generator``), the advantage scalarised with the member's weight
    and standardised per member and minibatch (``"advantage"``)."""
    P, N = agent.P, flat.shape[1]
    size = max(1, N // agent.cfg.pgmorl_minibatches)
    members = torch.arange(P).unsqueeze(-1)
    perm = torch.rand(P, N, generator=agent.generator).argsort(-1)
    for start in range(0, N, size):
        td = flat[members, perm[:, start:start + size]]
        td.set("advantage", scalarize_advantage(td.get("advantage_vector"), agent.weights, normalize_dims=(1,)))
        yield td


def update(agent: PGMORLAgent, td: TensorDictBase) -> TensorDictBase:
    """One PPO step of every member on its minibatch ``td`` ``[P, n]`` (:func:`minibatches`; PPO has no replay
    buffer): ``ClipPPOLoss`` (ratio and value clip ``pgmorl_clip``, no entropy bonus, value loss
    ``0.25 * max(unclipped, clipped)``), the loss scaled by ``P`` so each member's gradient is its own, each
    member's gradient norm clipped to ``max_grad_norm``, Adam. Returns the losses; a non-finite loss raises
    :class:`NonFiniteLossError` before anything changes."""
    out = agent.loss(td)
    total = (out["loss_objective"] + out["loss_critic"]) * agent.P
    optimizer_step(total, [agent.optimizers["ppo"]], max_grad_norm=agent.cfg.max_grad_norm, population=agent.P,
                   losses={k: out[k] for k in ("loss_objective", "loss_critic")})
    return TensorDict({k: out[k].detach() for k in ("loss_objective", "loss_critic")}, [])


def on_batch(agent: PGMORLAgent, batch: TensorDictBase, buffer, frames: int) -> tuple[TensorDictBase | None, int]:
    """One iteration on the collected ``batch`` ``[P * E, T]``; returns ``(last losses, PPO updates done)``.
    ``buffer`` and ``frames`` are unused (PPO learns from the batch alone; the iterations are counted by
    ``agent.iteration``).

    Each member's evaluation from its episodes that ended in the batch and the normalised rewards
    (:meth:`PGMORLAgent.prepare_batch`); at the first iteration the untrained members enter the population (no
    prediction sample); the GAE (:func:`advantages`); ``pgmorl_epochs`` epochs of :func:`minibatches`, one
    :func:`update` each; at the end of the warm-up and of every generation (:meth:`PGMORLAgent.generation_ends`)
    the members' evaluations -> performance buffer, Pareto archive, prediction model, then the task selection.
    A :class:`NonFiniteLossError` carries ``updates_done``: the updates of this iteration applied before it."""
    b = agent.prepare_batch(batch)
    if agent.iteration == 0:  # the untrained members: the population's first entries (no prediction sample)
        agent.evaluate_members(add_to_prediction=False)
    flat = advantages(agent, b)
    losses, updates = None, 0
    for _ in range(agent.cfg.pgmorl_epochs):
        for td in minibatches(agent, flat):
            try:
                losses = update(agent, td)
            except NonFiniteLossError as err:
                err.updates_done = updates  # (the run counts the updates applied before it)
                raise
            updates += 1
    agent.iteration += 1
    if agent.generation_ends():  # the warm-up's end, then every pgmorl_evo_iterations iterations
        # each member's evaluation -> performance buffer, Pareto archive (+ snapshot), prediction sample
        agent.evaluate_members(add_to_prediction=True)
        agent.select_tasks()  # each slot: a copy of a buffer policy + a weight (predicted HV gain + sparsity)
    return losses, updates


def train_pgmorl(run: Run) -> tuple[dict, PGMORLAgent]:
    """Train PGMORL in ``run`` (opened by :func:`~morl_trl.recipes.off_policy.run_training`: a new run or the
    continuation of one); returns ``(last evaluation summary, agent)``."""
    cfg = run.cfg
    device = torch.device(cfg.device)
    spec = run_domain(cfg)

    # 1. the env (everything is built before the run directory is touched: a failed start writes nothing):
    # P x E sub-envs (member p owns sub-envs p*E .. p*E+E-1) + history + VecNorm/clip on the observations
    # + the vector returns of the members' evaluation
    env = make_pgmorl_training_env(cfg, device)

    # 2. the modules (make_pgmorl_agent): the population's actor and vector critic as ONE batched module each,
    # ClipPPOLoss, Adam (eps 1e-5), the members' weights (the authors' grid), the performance buffer, the Pareto
    # archive, the prediction model, the reward VecNorm; the evaluation acts with the archive's snapshots
    tune_malloc()  # (the allocator for training, as build_agent)
    agent = make_pgmorl_agent(cfg, env, gamma=run_discount(cfg, spec), device=device)
    reference = load_reference(cfg, spec)
    evaluator = make_evaluator(cfg, agent, spec, reference)

    # 3. a resumed run's state (PPO has no replay buffer: the population, archive and statistics are all in the
    # agent's state), the collector of the iterations still to run (pgmorl_iterations: whole generations;
    # every member collects, one member's frames are counted)
    state = run.restore(None, map_location=device, env=env)
    if state is not None:
        load_agent_state(agent, state, run.resume_from, cfg.algo)
    collector = make_collector(cfg, env, agent.explore_policy, device, frames_done=run.frames,
                               frames_to_go=frames_to_collect(agent, run.frames))
    agent.reseed_env()  # each member's sub-envs re-seeded for the first iteration's reset (the authors' seed)

    snapshot = checkpoint_snapshot(agent, env, collector, device)  # (what a checkpoint holds)

    # 4. the loop. One iteration = one batch (every sub-env reset at its start: pgmorl_reset_each_iteration):
    # GAE; pgmorl_epochs epochs of pgmorl_minibatches PPO updates per member; at the end of the warm-up and of
    # every generation, the members' evaluations -> performance buffer, Pareto archive, prediction model, then
    # the task selection; then (run.step) evaluate and checkpoint when due. A checkpoint is the state at the end
    # of an iteration.
    with run.session(spec, reference, evaluator=evaluator, snapshot=snapshot, collector=collector,
                     notes=start_notes(cfg, run, spec, reference)):
        for batch in collector:  # [P * E, T]
            frames = run.collected(batch, counted_frames(agent, batch))  # one member's frames (E x T), as the authors
            losses, updates = on_batch(agent, batch, None, frames)  # GAE, the PPO epochs, the evolution when due
            agent.reseed_env()  # the next iteration's sub-envs re-seeded with their member's seed
            collector.update_policy_weights_()
            run.step(losses, updates, epsilon=agent.epsilon)
    return run.summary, agent
