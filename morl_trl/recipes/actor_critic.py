"""CAPQL (Lu, Herman & Yu, 2023), multi-objective SAC (MORL/D's building block, continuous and
discrete) and the single-objective SAC baseline: ``morl-trl train capql|mosac|mosac_discrete|sac``,
read top to bottom.

The agents: a preference-conditioned actor ``pi(a | s, w)`` (tanh-Gaussian or categorical), two
vector critics ``Q(s, a, w)`` ``[k]`` with Polyak (or hard) targets, Adam for actor, critics and,
when learned, the temperature (SAC's: :func:`morl_trl.recipes.sac.make_sac_agent`, TorchRL's
losses on the scalar reward). :func:`train_actor_critic` is the recipe of all four, in the spirit
of TorchRL's sota-implementations; with the loss it calls (:class:`~morl_trl.objectives.CAPQLLoss`,
:class:`~morl_trl.objectives.MOSACLoss`, :class:`~morl_trl.objectives.DiscreteMOSACLoss`,
:mod:`morl_trl.objectives.sac`) it is everything these algorithms do per frame:

1. the env (:func:`~morl_trl.recipes.parts.make_training_env`);
2. the modules (``make_*_agent``): actor, critics, the loss with its value estimator, Adam, the
   target updater;
3. the replay buffer and TorchRL's collector;
4. the loop, inside :meth:`Run.session <morl_trl.runs.Run.session>`: store the batch, then one
   update per ``update_frequency`` frames (or ``updates_per_batch`` per batch): sample; the
   critic step; on an actor turn (every ``policy_freq``-th update) ``policy_freq`` x (the actor
   step, the temperature step); the target step; the PER priorities (``joint_update=true``: one
   step of the summed losses instead).

Example:
    >>> from morl_trl.envs import make_env
    >>> from morl_trl.recipes import resolve_config
    >>> from morl_trl.transforms import compose_training_env
    >>> cfg = resolve_config("capql", "MOHopperDR-v5", quick=True, hidden=(16,))
    >>> env = compose_training_env(make_env(cfg.env_id, num_envs=2), gamma=0.99)
    >>> agent = make_capql_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
    >>> sorted(agent.optimizers)
    ['actor', 'qvalue']
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.envs.utils import ExplorationType, set_exploration_type

from morl_trl.objectives import (
    CAPQLLoss,
    DiscreteMOSACLoss,
    MOSACLoss,
    make_categorical_actor,
    make_gaussian_actor,
    make_vector_critic,
    make_vector_q_network,
)
from morl_trl.objectives.networks import orthogonal_init_
from morl_trl.recipes.agent import (
    Agent,
    apply_updates,
    action_spec,
    actor_critic_optimizers,
    eval_exploration,
    is_discrete,
    num_objectives,
    obs_shape,
    orthogonal_critic_copies_,
    target_updater,
    updates_due,
)
from morl_trl.recipes.allocator import tune_malloc
from morl_trl.recipes.optim import optimizer_step
from morl_trl.recipes.parts import (
    load_agent_state,
    checkpoint_snapshot,
    check_buffer_memory,
    load_reference,
    make_collector,
    make_evaluator,
    make_replay_buffer,
    make_training_env,
    run_discount,
    run_domain,
    start_notes,
)
from morl_trl.recipes.sac import make_sac_agent
from morl_trl.runs.run import Run

__all__ = ["make_capql_agent", "make_mosac_agent", "make_discrete_mosac_agent", "train_actor_critic"]


def _continuous(cfg, env, device):
    spec = action_spec(env)
    if is_discrete(spec):
        raise ValueError(f"{cfg.algo} needs continuous actions; {cfg.env_id} is discrete: use envelope or mosac_discrete")
    (obs_dim,) = obs_shape(env)
    k = num_objectives(env)
    actor = make_gaussian_actor(obs_dim, spec.to(device), k, num_cells=cfg.hidden, scale=cfg.actor_scale).to(device)
    critic = make_vector_critic(obs_dim, spec.shape[-1], k, num_cells=cfg.hidden).to(device)
    # the authors' init of every layer: orthogonal (gain 1), zero biases (capql.py:118,169)
    return spec, orthogonal_init_(actor), orthogonal_init_(critic)


def _agent(cfg, loss, actor, gamma, device, **kwargs) -> Agent:
    loss.make_value_estimator(gamma=gamma)
    return Agent(cfg, loss, actor, actor, actor_critic_optimizers(cfg, loss), target_updater(cfg, loss),
                 device=device, eval_exploration=eval_exploration(cfg), **kwargs)


class DeterministicActing(TensorDictModuleBase):
    """Acts with ``policy`` under ``ExplorationType.DETERMINISTIC`` whatever the caller asks (the
    collector's random exploration): the authors' CAPQL collects with ``tanh(mean)`` after
    ``learning_starts`` (their ``capql.py:454-459``); before it, the collector's random actions."""

    def __init__(self, policy) -> None:
        super().__init__()
        self.policy = policy
        self.in_keys, self.out_keys = list(policy.in_keys), list(policy.out_keys)

    def forward(self, tensordict):
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            return self.policy(tensordict)


def _loss_kwargs(cfg) -> dict:
    return dict(resample_preferences=cfg.loss_fresh_preferences, use_prioritized_weights=cfg.per_importance_weights)


def make_capql_agent(cfg, env, *, gamma: float, device: torch.device) -> Agent:
    """CAPQL: per-objective min of the critics, fixed temperature.

    As the authors by default: the acting preference is redrawn every step from the 22.5-degree
    cone and stored with the transition (``preference_distribution="cone"``,
    ``preference_resample="step"``, set on the training env), the loss trains on the stored
    preference (``loss_fresh_preferences=true``: fresh uniform ones per sample) and the actor's
    log-std is clamped to [-20, 2] (``actor_scale="softplus"``: TorchRL's biased softplus). Data is
    collected with the deterministic action ``tanh(mean)`` (``capql_deterministic_collection``;
    false: sampled actions).
    """
    _, actor, critic = _continuous(cfg, env, device)
    loss = CAPQLLoss(actor, critic, alpha=cfg.alpha, **_loss_kwargs(cfg))
    orthogonal_critic_copies_(loss, critic)
    agent = _agent(cfg, loss, actor, gamma, device)
    if cfg.capql_deterministic_collection:
        agent.explore_policy = DeterministicActing(actor)
    return agent


def make_mosac_agent(cfg, env, *, gamma: float, device: torch.device) -> Agent:
    """MOSAC: the episode's preference from the batch, scalarized critic min, learned temperature;
    evaluated with sampled actions as the paper's MORL/D (``eval_exploration="deterministic"``: the mean)."""
    spec, actor, critic = _continuous(cfg, env, device)
    loss = MOSACLoss(actor, critic, alpha_init=cfg.alpha, fixed_alpha=not cfg.learn_alpha, action_spec=spec,
                     alpha_loss_form=cfg.alpha_loss_form, **_loss_kwargs(cfg))
    orthogonal_critic_copies_(loss, critic)
    return _agent(cfg, loss, actor, gamma, device)


def make_discrete_mosac_agent(cfg, env, *, gamma: float, device: torch.device) -> Agent:
    """Discrete MOSAC: a categorical actor and vector Q-networks; evaluated with sampled actions."""
    spec = action_spec(env)
    if not is_discrete(spec):
        raise ValueError(f"mosac_discrete needs discrete actions; {cfg.env_id} is continuous: use mosac or capql")
    n, k, obs = spec.space.n, num_objectives(env), obs_shape(env)
    actor = make_categorical_actor(obs, n, k, num_cells=cfg.hidden, action_spec=spec).to(device)
    critic = make_vector_q_network(obs, n, k, num_cells=cfg.hidden).to(device)
    loss = DiscreteMOSACLoss(actor, critic, num_actions=n, alpha_init=cfg.alpha, fixed_alpha=not cfg.learn_alpha,
                             target_entropy=cfg.target_entropy_scale * math.log(n),
                             use_prioritized_weights=cfg.per_importance_weights, alpha_loss_form=cfg.alpha_loss_form)
    return _agent(cfg, loss, actor, gamma, device)


def train_actor_critic(run: Run) -> tuple[dict, Agent]:
    """Train CAPQL, MOSAC, discrete MOSAC or SAC (``run.cfg.algo``) in ``run`` (opened by
    :func:`~morl_trl.recipes.off_policy.run_training`: a new run or the continuation of one); returns
    ``(last evaluation summary, agent)``."""
    cfg = run.cfg
    device = torch.device(cfg.device)
    spec = run_domain(cfg)

    # 1. the env (everything is built before the run directory is touched: a failed start writes nothing)
    env = make_training_env(cfg, device)

    # 2. the modules: actor, critics (TorchRL's copies, orthogonal init), the loss, Adam, the target updater
    tune_malloc()  # (the allocator for training, as build_agent)
    make_agent = {"capql": make_capql_agent, "mosac": make_mosac_agent, "mosac_discrete": make_discrete_mosac_agent,
                  "sac": make_sac_agent}[cfg.algo]
    agent = make_agent(cfg, env, gamma=run_discount(cfg, spec), device=device)
    loss, optimizers, target = agent.loss, agent.optimizers, agent.target_updater
    reference = load_reference(cfg, spec)
    evaluator = make_evaluator(cfg, agent, spec, reference)  # (the actor, eval_exploration, on the evaluation suite)

    # 3. the replay buffer, a resumed run's state, the collector
    check_buffer_memory(cfg, env, device)
    buffer = make_replay_buffer(cfg, device)
    state = run.restore(buffer, map_location=device, env=env)
    if state is not None:
        load_agent_state(agent, state, run.resume_from, cfg.algo)  # networks, optimizers, the target updater, critic_steps
    collector = make_collector(cfg, env, agent.explore_policy, device, frames_done=run.frames)
    clip = dict(max_grad_norm=cfg.max_grad_norm)
    alpha_optimizer = optimizers.get("alpha")  # (a learned temperature)
    last_actor: dict = {}  # the last actor turn's losses, logged with the critic-only updates after it

    def update() -> TensorDictBase:
        """One update on a sampled batch (a non-finite loss raises before its own step)."""
        if agent.captured_update:  # compile / cudagraphs / fused on an accelerator: the same step, captured
            return agent.update(buffer)  # (recipes/capture.py: its non-finite guard stays on the device)
        batch = buffer.sample().to(device)
        agent.critic_steps += 1  # (the update counter the checkpoint keeps: the delayed actor's clock)
        actor_turn = agent.critic_steps % agent.policy_freq == 0  # every policy_freq-th update (the 2nd, 4th, ...)
        if not agent.steps_each_loss:  # joint_update=true: one step of the summed losses, the actor on the old critics
            out = loss(batch)
            optimizer_step(sum(out[k] for k in agent.loss_keys), optimizers.values(),
                           losses={k: out[k] for k in agent.loss_keys}, **clip)
        else:  # the authors' order (their sac_continuous.py:435-456, mosac_continuous_action.py:460-482)
            # the critic step: the targets (target critics, the actor's next actions, the temperature), the critics
            loss_qvalue, _ = loss.qvalue_loss(batch)
            optimizer_step(loss_qvalue, [optimizers["qvalue"]], losses={"loss_qvalue": loss_qvalue}, **clip)
            if actor_turn:  # policy_freq x (the actor step on the updated critics, the temperature step)
                dist = None
                for i in range(agent.policy_freq):
                    loss_actor, meta = loss.actor_loss(batch) if dist is None else loss.actor_loss(batch, dist)
                    optimizer_step(loss_actor, [optimizers["actor"]], losses={"loss_actor": loss_actor}, **clip)
                    last_actor.update(loss_actor=loss_actor.detach(), entropy=-meta["log_prob"].mean(-1))
                    if alpha_optimizer is not None:
                        if loss.fresh_temperature_sample:  # continuous: a fresh sample of the updated actor,
                            # which is also the next actor step's sample (the actor does not change in between)
                            dist = loss.actor_dist(batch) if i + 1 < agent.policy_freq else None
                            loss_alpha = loss.temperature_loss(batch, dist=dist)
                        else:  # discrete: the actor step's log-probabilities (mosac_discrete_action.py:490-492)
                            loss_alpha = loss.temperature_loss(batch, meta["log_prob"])
                        optimizer_step(loss_alpha, [alpha_optimizer], losses={"loss_alpha": loss_alpha}, **clip)
                        last_actor["loss_alpha"] = loss_alpha.detach()
            elif not last_actor:  # no actor turn yet: NaN actor losses
                nan = torch.full_like(loss_qvalue.detach(), float("nan"))
                last_actor.update(loss_actor=nan, entropy=torch.full_like(loss.log_alpha.detach(), float("nan")))
                if alpha_optimizer is not None:
                    last_actor["loss_alpha"] = nan
            with torch.no_grad():
                alpha = loss.log_alpha.exp()
            out = TensorDict({"loss_qvalue": loss_qvalue.detach(), **last_actor, "alpha": alpha}, batch_size=[])
        target.step()  # Polyak averaging with tau (a hard copy every target_update_period updates without)
        if cfg.prioritized:
            buffer.update_tensordict_priority(batch)
        return out.detach()

    snapshot = checkpoint_snapshot(agent, env, collector, device)  # (what a checkpoint holds)

    # 4. the loop. One iteration = one batch: store it, update, then (run.step) evaluate and checkpoint
    # when due. A checkpoint is the state at the end of a batch, so the batch after it is the same whether
    # the run resumes or not.
    with run.session(spec, reference, evaluator=evaluator, snapshot=snapshot, buffer=buffer, collector=collector,
                     notes=start_notes(cfg, run, spec, reference)):
        for batch in collector:  # (uniformly random actions for the first init_random_frames)
            frames = run.collected(batch)
            agent.store(buffer, batch)  # the entries the loss reads
            losses, updates = None, 0
            if frames >= cfg.init_random_frames:
                updates = updates_due(cfg, frames, batch.numel())  # one per update_frequency frames, or per batch
                losses = apply_updates(update, updates)  # (a non-finite loss raises, counting those applied)
            collector.update_policy_weights_()
            run.step(losses, updates, epsilon=None)
    return run.summary, agent
