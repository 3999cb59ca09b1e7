"""Envelope Q-learning (Yang et al., 2019): ``morl-trl train envelope``, read top to bottom.

:func:`train_envelope` builds the env (a preference ``w`` per sub-env, vector rewards), the modules
(:func:`make_envelope_agent`: the vector Q-network ``Q(s, ., w)``, its greedy policy
``argmax_a w · Q(s, a, w)``, ε-greedy on top, :class:`~morl_trl.objectives.EnvelopeQLoss`, Adam, the
hard target copy), the prioritized replay buffer and TorchRL's collector; per batch :func:`on_batch`
stores it and runs the :func:`update` calls due, then the ε and homotopy :func:`schedules`.
``compile`` / ``cudagraphs`` capture the same :func:`gradient_step` (:mod:`morl_trl.training.capture`).

Faithful to the authors' runs by default (config keys in brackets): ``w`` concatenated after the
first hidden layer with orthogonal init (``envelope_network="authors"``; ``"mb"``: at the input,
MORL-Baselines 1.3.0's ``QNet``; ``"input"``: at the input, PyTorch's init), homotopy ``lambda`` fixed
at ``homotopy_lambda0`` (``homotopy_final`` anneals it over ``homotopy_frames``), PER priorities from
the first sampled preference without importance weights (``envelope_priority``,
``per_importance_weights``), gradient norm clipped at 1 (``max_grad_norm``), ``|N(0, I)|``
preferences for acting and for the loss alike (``preference_distribution``: one key for both, as the
authors' ``dist``).

Example:
    >>> from morl_trl.envs import make_env
    >>> from morl_trl.recipes import resolve_config
    >>> from morl_trl.transforms import compose_training_env
    >>> cfg = resolve_config("envelope", "MOLavaGridDR-v0", quick=True, hidden=(16,))
    >>> env = compose_training_env(make_env(cfg.env_id, num_envs=2), gamma=0.995)
    >>> agent = make_envelope_agent(cfg, env, gamma=0.995, device=torch.device("cpu"))
    >>> agent.eval_policy(env.reset())["action"].shape
    torch.Size([2])
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase

from morl_trl.objectives import EnvelopeQLoss, LeanSequential, MOQValueModule, make_vector_q_network
from morl_trl.training.agent import (Agent, action_spec, adam, captured_update, counted_update, epsilon,
                                     epsilon_greedy, eval_exploration, fused_choice, is_discrete, num_objectives,
                                     obs_shape, target_updater, updates_due)
from morl_trl.training.allocator import tune_malloc
from morl_trl.training.optim import optimizer_step
from morl_trl.training.parts import (check_buffer_memory, checkpoint_snapshot, load_agent_state, load_reference,
                                     make_collector, make_evaluator, make_replay_buffer, make_training_env,
                                     run_discount, run_domain, start_notes)
from morl_trl.runs.run import Run

__all__ = ["make_envelope_agent", "train_envelope", "gradient_step", "update", "on_batch", "schedules"]


def make_envelope_agent(cfg, env, *, gamma: float, device: torch.device) -> Agent:
    """Envelope's modules for ``env`` (discrete actions), held by an :class:`~morl_trl.training.agent.Agent`
    (its policies, state and checkpoint format; ``morl-trl evaluate`` and
    :func:`~morl_trl.recipes.policy.load_policy` rebuild it from a run's config)."""
    spec = action_spec(env)
    if not is_discrete(spec):
        raise ValueError(f"envelope needs discrete actions; {cfg.env_id} has {type(spec).__name__}: use capql or mosac")
    form = cfg.envelope_network
    qnet = make_vector_q_network(obs_shape(env), spec.space.n, num_objectives(env), num_cells=cfg.hidden,
                                 # the authors concatenate w after the first hidden layer, or after the CNN;
                                 # MORL-Baselines 1.3.0 ("mb") at the input (after the CNN), both with orthogonal init
                                 preference_layer=1 if form == "authors" and len(obs_shape(env)) == 1 else 0,
                                 init="default" if form == "input" else "orthogonal").to(device)
    greedy = LeanSequential(qnet, MOQValueModule())  # (TensorDictSequential's result, less plumbing per call)
    egreedy = epsilon_greedy(cfg, env)
    anneal = cfg.homotopy_final is not None
    loss = EnvelopeQLoss(
        qnet, num_preference_samples=cfg.num_sampled_prefs, homotopy_lambda=cfg.homotopy_lambda0,
        final_homotopy_lambda=cfg.homotopy_final if anneal else cfg.homotopy_lambda0,
        homotopy_steps=(cfg.homotopy_frames or cfg.frames) if anneal else None,
        priority=cfg.envelope_priority, use_prioritized_weights=cfg.per_importance_weights,
        # one distribution for the acting w and the loss's sampled ones, as the authors' random_weights(dist)
        preference_distribution=cfg.preference_distribution,
    )
    loss.make_value_estimator(gamma=gamma)
    optimizers = {"qvalue": adam(loss.parameters(), cfg.lr, fused=fused_choice(cfg))}
    return Agent(cfg, loss, LeanSequential(greedy, egreedy), greedy, optimizers, target_updater(cfg, loss),
                 device=device, exploration_module=egreedy, eval_exploration=eval_exploration(cfg), capturable=True)


def train_envelope(run: Run) -> tuple[dict, Agent]:
    """Train Envelope in ``run`` (:func:`~morl_trl.recipes.off_policy.open_run`: a new run or the
    continuation of one); returns ``(last evaluation summary, agent)``."""
    cfg = run.cfg
    device = torch.device(cfg.device)
    spec = run_domain(cfg)

    # 1. the env (everything is built before the run directory is touched: a failed start writes nothing)
    env = make_training_env(cfg, device)

    # 2. the modules: Q-network, greedy and ε-greedy policies, the loss, Adam, the target updater
    tune_malloc()  # (the allocator for training, as build_agent)
    agent = make_envelope_agent(cfg, env, gamma=run_discount(cfg, spec), device=device)
    reference = load_reference(cfg, spec)
    evaluator = make_evaluator(cfg, agent, spec, reference)  # (the greedy policy on the evaluation suite)

    # 3. the replay buffer, a resumed run's state, the collector
    check_buffer_memory(cfg, env, device)
    buffer = make_replay_buffer(cfg, device)
    state = run.restore(buffer, map_location=device, env=env)
    if state is not None:
        load_agent_state(agent, state, run.resume_from, cfg.algo)
        schedules(agent, run.frames)
    # (return_same_td: each batch is stored and logged before the next one is collected)
    collector = make_collector(cfg, env, agent.explore_policy, device, frames_done=run.frames, return_same_td=True)

    snapshot = checkpoint_snapshot(agent, env, collector, device)  # (what a checkpoint holds)

    # 4. the loop. One iteration = one batch: store it, update, the schedules, then (run.step) evaluate
    # and checkpoint when due. A checkpoint is the state at the end of a batch, so the batch after it
    # is the same whether the run resumes or not.
    with run.session(spec, reference, evaluator=evaluator, snapshot=snapshot, buffer=buffer, collector=collector,
                     notes=start_notes(cfg, run, spec, reference)):
        for batch in collector:  # (uniformly random actions for the first init_random_frames)
            frames = run.collected(batch)
            losses, updates = on_batch(agent, batch, buffer, frames)  # store, the updates due, the schedules
            collector.update_policy_weights_()
            run.step(losses, updates, epsilon=agent.epsilon)
    return run.summary, agent


def gradient_step(agent: Agent, batch: TensorDictBase, actor_turn: bool = True, *, on_device: bool = False):
    """The loss (it writes the batch's PER priorities), backward, clipping and Adam: the part of
    :func:`update` that ``compile`` / CUDA graphs capture. Returns ``(losses, found_inf)`` (see
    :func:`~morl_trl.training.optim.optimizer_step`; ``actor_turn``: unused, Envelope has no actor)."""
    out = agent.loss(batch)
    found_inf = optimizer_step(out["loss_qvalue"], [agent.optimizers["qvalue"]], max_grad_norm=agent.cfg.max_grad_norm,
                               losses={"loss_qvalue": out["loss_qvalue"]}, on_device=on_device)
    return out, found_inf


def update(agent: Agent, buffer) -> TensorDictBase:
    """One update: sample, :func:`gradient_step`, the target updater (a hard copy every
    ``target_update_period`` updates), the PER priorities; captured, the same step in ``agent.captured``."""
    agent.critic_steps += 1  # (the update counter the checkpoint keeps)
    if agent.captured is None:  # (decided on the first update, after a resumed run's state is loaded)
        agent.captured = captured_update(agent, gradient_step)
    if agent.captured:
        return agent.captured(buffer)
    batch = buffer.sample().to(agent.device)
    out, _ = gradient_step(agent, batch)
    agent.target_updater.step()
    if agent.cfg.prioritized:
        buffer.update_tensordict_priority(batch)
    return out.detach()


def on_batch(agent: Agent, batch: TensorDictBase, buffer, frames: int) -> tuple[TensorDictBase | None, int]:
    """One collected batch ending at ``frames`` frames: store it, from ``init_random_frames`` on the
    :func:`update` calls due, then the schedules. Returns ``(the last update's losses or None, updates done)``."""
    cfg = agent.cfg
    agent.store(buffer, batch)
    losses, updates = None, 0
    if frames >= cfg.init_random_frames:
        updates = updates_due(cfg, frames, batch.numel())
        for done in range(updates):
            with counted_update(done):  # (a non-finite loss: the run counts the updates applied before it)
                losses = update(agent, buffer)
    schedules(agent, frames)
    return losses, updates


def schedules(agent: Agent, frames: int) -> None:
    """Envelope's frame-based schedules after ``frames`` frames: ε of the exploration
    (:func:`~morl_trl.training.agent.epsilon`) and the homotopy ``λ`` of the loss."""
    agent.exploration_module.eps.fill_(epsilon(agent.cfg, frames))
    agent.loss.update_homotopy(frames)
