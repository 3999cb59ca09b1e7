"""CAPQL (Lu, Herman & Yu, 2023), multi-objective SAC (MORL/D's building block, continuous and
discrete) and the single-objective SAC baseline: ``morl-trl train capql|mosac|mosac_discrete|sac``,
read top to bottom.

The agents (``make_*_agent``): a preference-conditioned actor ``pi(a | s, w)`` (tanh-Gaussian or
categorical), two vector critics ``Q(s, a, w)`` ``[k]`` with Polyak (or hard) targets, Adam for actor,
critics and, when learned, the temperature (SAC: :func:`~morl_trl.algorithms.actor_critic.sac.make_sac_agent`,
TorchRL's losses on the scalar reward). :func:`train_actor_critic`, the loop of all four, builds the env,
the agent, the replay buffer and TorchRL's collector; per batch :func:`on_batch` stores it, then runs
one :func:`update` per ``update_frequency`` frames (or ``updates_per_batch``): sample,
:func:`gradient_step` (the critic step; every ``policy_freq``-th update ``policy_freq`` x the actor and
temperature steps; ``joint_update=true``: one step of the summed losses), the target step, the PER
priorities. ``compile`` / ``cudagraphs`` capture the same :func:`gradient_step`.

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

from morl_trl.objectives import (CAPQLLoss, DiscreteMOSACLoss, MOSACLoss, make_categorical_actor, make_gaussian_actor,
                                 make_vector_critic, make_vector_q_network)
from morl_trl.objectives.networks import orthogonal_init_
from morl_trl.training.agent import (Agent, action_spec, actor_critic_optimizers, captured_update, counted_update,
                                     eval_exploration, is_discrete, num_objectives, obs_shape,
                                     orthogonal_critic_copies_, target_updater, updates_due)
from morl_trl.training.allocator import tune_malloc
from morl_trl.training.optim import optimizer_step
from morl_trl.training.parts import (check_buffer_memory, checkpoint_snapshot, load_agent_state, load_reference,
                                     make_collector, make_evaluator, make_replay_buffer, make_training_env,
                                     run_discount, run_domain, start_notes)
from morl_trl.runs.run import Run

__all__ = ["make_capql_agent", "make_mosac_agent", "make_discrete_mosac_agent", "train_actor_critic", "policy_freq",
           "steps_each_loss", "delayed_actor_step", "gradient_step", "update", "on_batch"]


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
                 device=device, eval_exploration=eval_exploration(cfg), capturable=True, **kwargs)


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
    """CAPQL: per-objective min of the critics, fixed temperature. As the authors by default: the acting
    preference redrawn every step from the 22.5-degree cone and stored (``preference_distribution="cone"``,
    ``preference_resample="step"``), the loss on the stored preference (``loss_fresh_preferences``), the
    actor's log-std clamped to [-20, 2] (``actor_scale``), the log-probability with ``1e-6`` in the squashing's
    Jacobian and clamped to [-1000, 1000] (``capql_log_prob``), collection with ``tanh(mean)``
    (``capql_deterministic_collection``)."""
    _, actor, critic = _continuous(cfg, env, device)
    loss = CAPQLLoss(actor, critic, alpha=cfg.alpha, log_prob_form=cfg.capql_log_prob, **_loss_kwargs(cfg))
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


def train_actor_critic(run: Run, make_agent) -> tuple[dict, Agent]:
    """Train CAPQL, MOSAC, discrete MOSAC or SAC (``make_agent``: its builder, bound by the registry) in
    ``run`` (:func:`~morl_trl.recipes.off_policy.open_run`); returns ``(last evaluation summary, agent)``."""
    cfg = run.cfg
    device = torch.device(cfg.device)
    spec = run_domain(cfg)

    # 1. the env (everything is built before the run directory is touched: a failed start writes nothing)
    env = make_training_env(cfg, device)

    # 2. the modules: actor, critics (TorchRL's copies, orthogonal init), the loss, Adam, the target updater
    tune_malloc()  # (the allocator for training, as build_agent)
    agent = make_agent(cfg, env, gamma=run_discount(cfg, spec), device=device)
    reference = load_reference(cfg, spec)
    evaluator = make_evaluator(cfg, agent, spec, reference)  # (the actor, eval_exploration, on the evaluation suite)

    # 3. the replay buffer, a resumed run's state, the collector
    check_buffer_memory(cfg, env, device)
    buffer = make_replay_buffer(cfg, device)
    state = run.restore(buffer, map_location=device, env=env)
    if state is not None:
        load_agent_state(agent, state, run.resume_from, cfg.algo)  # networks, optimizers, the target updater, critic_steps
    # (return_same_td: each batch is stored and logged before the next one is collected)
    collector = make_collector(cfg, env, agent.explore_policy, device, frames_done=run.frames, return_same_td=True)
    snapshot = checkpoint_snapshot(agent, env, collector, device)  # (what a checkpoint holds)

    # 4. the loop. One iteration = one batch: store it, update, then (run.step) evaluate and checkpoint
    # when due. A checkpoint is the state at the end of a batch, so the batch after it is the same whether
    # the run resumes or not.
    with run.session(spec, reference, evaluator=evaluator, snapshot=snapshot, buffer=buffer, collector=collector,
                     notes=start_notes(cfg, run, spec, reference)):
        for batch in collector:  # (uniformly random actions for the first init_random_frames)
            frames = run.collected(batch)
            losses, updates = on_batch(agent, batch, buffer, frames)  # store, the updates due
            collector.update_policy_weights_()
            run.step(losses, updates, epsilon=None)
    return run.summary, agent


def policy_freq(agent: Agent) -> int:
    """``cfg.policy_freq``: 1, an actor step every update; ``n > 1``, the delayed actor, as the authors' continuous
    SAC and MOSAC (2)."""
    return int(getattr(agent.cfg, "policy_freq", 1))


def steps_each_loss(agent: Agent) -> bool:
    """Whether the update steps critics, actor and temperature one after the other (:func:`delayed_actor_step`),
    not one joint step of the summed losses (``joint_update=true``, or a loss without the three parts)."""
    loss = agent.loss
    return (not getattr(agent.cfg, "joint_update", False) and {"qvalue", "actor"} <= set(agent.optimizers)
            and all(hasattr(loss, m) for m in ("qvalue_loss", "actor_loss", "temperature_loss")))


def delayed_actor_step(agent: Agent, batch: TensorDictBase, actor_turn: bool, *, on_device: bool = False):
    """The authors' actor-critic step (CleanRL's SAC; their ``sac_continuous.py:435-456``,
    ``mosac_continuous_action.py:460-482``), each loss alone: the critic step (``qvalue_loss``), then on an
    actor turn ``policy_freq`` times the actor step (``actor_loss``: fresh actions, the updated critics)
    and, when learned, the temperature step -- on a fresh sample of the updated actor
    (``fresh_temperature_sample``, continuous: the authors' ``_, log_pi, _ = actor.get_action(obs)``) or
    on the actor step's log-probabilities (discrete, ``mosac_discrete_action.py:490-492``). A non-finite
    loss is never applied (the earlier steps of the update stay). Returns ``(losses, found_inf)``; on a
    critic-only update the actor's losses are the last actor turn's (NaN before the first)."""
    loss, optimizers, n_actor = agent.loss, agent.optimizers, policy_freq(agent)
    kw = dict(max_grad_norm=agent.cfg.max_grad_norm, on_device=on_device)
    loss_qvalue, _ = loss.qvalue_loss(batch)
    found = optimizer_step(loss_qvalue, [optimizers["qvalue"]], losses={"loss_qvalue": loss_qvalue}, **kw)
    last = agent.last_actor_losses
    if actor_turn:
        alpha_opt = optimizers.get("alpha")
        dist = None
        for i in range(n_actor):
            loss_actor, meta = loss.actor_loss(batch) if dist is None else loss.actor_loss(batch, dist)
            # on the device a skipped part skips the rest of the update (found_inf carried on)
            found = optimizer_step(loss_actor, [optimizers["actor"]], losses={"loss_actor": loss_actor},
                                   found_inf=found, **kw)
            last = {"loss_actor": loss_actor.detach(), "entropy": -meta["log_prob"].mean(-1)}
            if alpha_opt is not None:
                if loss.fresh_temperature_sample:
                    # one forward of the updated actor for the temperature's fresh sample and, drawn after
                    # it, the next actor step's sample (the actor does not change in between)
                    dist = loss.actor_dist(batch) if i + 1 < n_actor else None
                    loss_alpha = loss.temperature_loss(batch, dist=dist)
                else:
                    loss_alpha = loss.temperature_loss(batch, meta["log_prob"])
                found = optimizer_step(loss_alpha, [alpha_opt], losses={"loss_alpha": loss_alpha},
                                       found_inf=found, **kw)
                last["loss_alpha"] = loss_alpha.detach()
    elif last is None:  # no actor turn yet
        nan = torch.full_like(loss_qvalue.detach(), float("nan"))
        last = {"loss_actor": nan, "entropy": torch.full_like(loss.log_alpha.detach(), float("nan"))}
        if "alpha" in optimizers:
            last["loss_alpha"] = nan
    agent.last_actor_losses = last
    with torch.no_grad():
        alpha = loss.log_alpha.exp()
    return TensorDict({"loss_qvalue": loss_qvalue.detach(), **last, "alpha": alpha}, batch_size=[]), found


def gradient_step(agent: Agent, batch: TensorDictBase, actor_turn: bool, *, on_device: bool = False):
    """The losses' steps on ``batch``: :func:`delayed_actor_step`, or with ``joint_update=true`` one step of
    the summed losses. The part of :func:`update` that ``compile`` / CUDA graphs capture."""
    if steps_each_loss(agent):
        return delayed_actor_step(agent, batch, actor_turn, on_device=on_device)
    out = agent.loss(batch)
    keys = [k for k in agent.loss.out_keys if k.startswith("loss_")]
    found = optimizer_step(sum(out[k] for k in keys), agent.optimizers.values(), max_grad_norm=agent.cfg.max_grad_norm,
                           losses={k: out[k] for k in keys}, on_device=on_device)
    return out, found


def update(agent: Agent, buffer) -> TensorDictBase:
    """One update: sample, :func:`gradient_step` (an actor turn every ``policy_freq``-th update: the 2nd, 4th,
    ... for 2, as the authors' ``global_step % policy_freq == 0``), the target step (Polyak with ``tau``, or a hard copy every
    ``target_update_period``), the PER priorities; captured, the same step in ``agent.captured``."""
    agent.critic_steps += 1  # (the update counter the checkpoint keeps: the delayed actor's clock)
    actor_turn = agent.critic_steps % policy_freq(agent) == 0
    if agent.captured is None:  # (decided on the first update, after a resumed run's state is loaded)
        agent.captured = captured_update(agent, gradient_step)
    if agent.captured:
        return agent.captured(buffer, actor_turn)
    batch = buffer.sample().to(agent.device)
    out, _ = gradient_step(agent, batch, actor_turn)
    agent.target_updater.step()
    if agent.cfg.prioritized:
        buffer.update_tensordict_priority(batch)
    return out.detach()


def on_batch(agent: Agent, batch: TensorDictBase, buffer, frames: int) -> tuple[TensorDictBase | None, int]:
    """One collected batch ending at ``frames`` frames: store it, then from ``init_random_frames`` on the
    :func:`update` calls due. Returns ``(the last update's losses or None, updates done)``."""
    cfg = agent.cfg
    agent.store(buffer, batch)
    if frames < cfg.init_random_frames:
        return None, 0
    updates, losses = updates_due(cfg, frames, batch.numel()), None
    for done in range(updates):
        with counted_update(done):  # (a non-finite loss: the run counts the updates applied before it)
            losses = update(agent, buffer)
    return losses, updates
