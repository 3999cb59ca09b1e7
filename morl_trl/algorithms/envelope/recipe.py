"""Envelope Q-learning (Yang et al., 2019): ``morl-trl train envelope``, read top to bottom.

Everything Envelope does per frame is in this file and its loss,
:class:`~morl_trl.objectives.EnvelopeQLoss`; :func:`train_envelope` reads like TorchRL's
sota-implementations:

1. the env: the domain-randomized env, the policy's history, a preference ``w`` per sub-env,
   vector returns (:func:`~morl_trl.training.parts.make_training_env`);
2. the modules (:func:`make_envelope_agent`): a vector Q-network ``Q(s, ., w)`` ``[|A|, k]``, its
   greedy policy ``argmax_a w · Q(s, a, w)`` (:class:`~morl_trl.objectives.MOQValueModule`),
   TorchRL's ε-greedy exploration on top, the loss with its value estimator, Adam, the target
   updater (a hard copy every ``target_update_period`` updates);
3. the replay buffer (prioritized) and TorchRL's collector;
4. the loop, inside :meth:`Run.session <morl_trl.runs.Run.session>` (run directory, resume,
   logs, evaluations and checkpoints when due, Ctrl-C, a clean stop): per batch :func:`on_batch`
   stores it, runs the :func:`update` calls due (sample, :func:`gradient_step`: loss,
   :func:`~morl_trl.training.optim.optimizer_step`; the target update, PER priorities) and the ε
   and homotopy :func:`schedules`. ``compile`` / ``cudagraphs`` capture the same
   :func:`gradient_step` (:mod:`morl_trl.training.capture`).

Faithful to the authors' runs by default (config keys in brackets, ours as options):
``w`` concatenated after the first hidden layer with orthogonal init
(``envelope_network="authors"``; ``"mb"``: at the input with orthogonal init, MORL-Baselines 1.3.0's
``QNet`` and a foreign env's default; ``"input"``: at the input, PyTorch's init), homotopy
``lambda`` fixed at ``homotopy_lambda0`` (``homotopy_final=1.0`` anneals it over
``homotopy_frames``), PER priorities from the first sampled preference without
importance weights (``envelope_priority="mean"``, ``per_importance_weights=true``), gradient
norm clipped at 1 (``max_grad_norm``) and ``|N(0, I)|`` preferences, the acting ones and those
the loss samples alike (``preference_distribution``: one key for both, as the authors' ``dist``).

Example:
    >>> from morl_trl.envs import make_env
    >>> from morl_trl.recipes import resolve_config
    >>> from morl_trl.transforms import compose_training_env
    >>> cfg = resolve_config("envelope", "MOLavaGridDR-v0", quick=True, hidden=(16,))
    >>> env = compose_training_env(make_env(cfg.env_id, num_envs=2), gamma=0.995)
    >>> agent = make_envelope_agent(cfg, env, gamma=0.995, device=torch.device("cpu"))
    >>> agent.eval_policy(env.reset())["action"].shape
    torch.Size([2])

    Training (``morl-trl train envelope MOLavaGridDR-v0 --quick`` runs the same):

    >>> from morl_trl.recipes import train
    >>> summary = train(resolve_config("envelope", "MOLavaGridDR-v0", quick=True))  # doctest: +SKIP
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictSequential

from morl_trl.objectives import EnvelopeQLoss, MOQValueModule, make_vector_q_network
from morl_trl.training.agent import (
    Agent,
    apply_updates,
    action_spec,
    adam,
    epsilon,
    epsilon_greedy,
    eval_exploration,
    fused_choice,
    is_discrete,
    num_objectives,
    obs_shape,
    target_updater,
    updates_due,
)
from morl_trl.training.allocator import tune_malloc
from morl_trl.training.capture import captured_update
from morl_trl.training.optim import optimizer_step
from morl_trl.training.parts import (
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
    greedy = TensorDictSequential(qnet, MOQValueModule())
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
    return Agent(cfg, loss, TensorDictSequential(greedy, egreedy), greedy, optimizers, target_updater(cfg, loss),
                 device=device, exploration_module=egreedy, eval_exploration=eval_exploration(cfg), capturable=True)


def train_envelope(run: Run) -> tuple[dict, Agent]:
    """Train Envelope in ``run`` (opened by :func:`~morl_trl.recipes.off_policy.run_training`: a new
    run or the continuation of one); returns ``(last evaluation summary, agent)``."""
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
    """The envelope TD loss over the sampled preferences (it writes the batch's PER priorities), its
    backward, the gradient clipping and Adam: the part of :func:`update` that ``compile`` / CUDA
    graphs capture (:mod:`morl_trl.training.capture`). Returns ``(losses, found_inf)``: eager, a
    non-finite loss raises :class:`~morl_trl.training.optim.NonFiniteLossError` before the step
    (``found_inf`` is ``None``); ``on_device``, the step is skipped on the device and ``found_inf``
    says so. (``actor_turn``: unused, Envelope has no actor.)"""
    out = agent.loss(batch)
    found_inf = optimizer_step(out["loss_qvalue"], [agent.optimizers["qvalue"]], max_grad_norm=agent.cfg.max_grad_norm,
                               losses={"loss_qvalue": out["loss_qvalue"]}, on_device=on_device)
    return out, found_inf


def update(agent: Agent, buffer) -> TensorDictBase:
    """One gradient step on a sampled batch: sample, :func:`gradient_step`, the target updater (a hard
    copy every ``target_update_period`` updates), the PER priorities. Captured (``compile`` /
    ``cudagraphs``, or fused Adam on an accelerator) the same :func:`gradient_step` runs inside
    :class:`~morl_trl.training.capture.CapturedUpdate`, its non-finite guard on the device."""
    agent.critic_steps += 1  # (the update counter the checkpoint keeps)
    captured = captured_update(agent, gradient_step)
    if captured is not None:
        return captured(buffer)
    batch = buffer.sample().to(agent.device)
    out, _ = gradient_step(agent, batch)
    agent.target_updater.step()
    if agent.cfg.prioritized:
        buffer.update_tensordict_priority(batch)
    return out.detach()


def on_batch(agent: Agent, batch: TensorDictBase, buffer, frames: int) -> tuple[TensorDictBase | None, int]:
    """What the loop does with one collected batch ending at ``frames`` frames: store its transitions
    (the entries the loss reads), then, from ``init_random_frames`` on, the :func:`update` calls due
    (one per ``update_frequency`` frames, or ``updates_per_batch``), then the schedules. Returns
    ``(the last update's losses or None, updates done)``; a non-finite loss raises, counting the updates
    applied before it."""
    cfg = agent.cfg
    agent.store(buffer, batch)
    losses, updates = None, 0
    if frames >= cfg.init_random_frames:
        updates = updates_due(cfg, frames, batch.numel())
        losses = apply_updates(lambda: update(agent, buffer), updates)
    schedules(agent, frames)
    return losses, updates


def schedules(agent: Agent, frames: int) -> None:
    """Envelope's frame-based schedules after ``frames`` frames: ε of the exploration
    (:func:`~morl_trl.training.agent.epsilon`) and the homotopy ``λ`` of the loss."""
    agent.exploration_module.eps.fill_(epsilon(agent.cfg, frames))
    agent.loss.update_homotopy(frames)
