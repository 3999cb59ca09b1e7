"""Envelope Q-learning (Yang et al., 2019): the agent that ``morl-trl train envelope`` trains.

A vector Q-network ``Q(s, ., w)`` ``[|A|, k]``, its greedy policy
``argmax_a w · Q(s, a, w)`` (:class:`~morl_trl.objectives.MOQValueModule`), TorchRL's
epsilon-greedy exploration on top, :class:`~morl_trl.objectives.EnvelopeQLoss` with a hard
target copy, Adam. The loop that drives it is :mod:`morl_trl.recipes.off_policy`.

Faithful to the authors' runs by default (config keys in brackets, ours as options):
``w`` concatenated after the first hidden layer with orthogonal init
(``envelope_network="authors"``; ``"input"``: at the input, PyTorch's init), homotopy
``lambda`` fixed at ``homotopy_lambda0`` (``homotopy_final=1.0`` anneals it over
``homotopy_frames``), PER priorities from the first sampled preference without
importance weights (``envelope_priority="mean"``, ``per_importance_weights=true``), gradient
norm clipped at 1 (``max_grad_norm``) and ``|N(0, I)|`` training preferences
(``preference_distribution="dirichlet"``).

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
from tensordict.nn import TensorDictSequential

from morl_trl.objectives import EnvelopeQLoss, MOQValueModule, make_vector_q_network
from morl_trl.recipes.agent import (
    Agent,
    action_spec,
    adam,
    epsilon_greedy,
    eval_exploration,
    fused_choice,
    is_discrete,
    num_objectives,
    obs_shape,
    target_updater,
)

__all__ = ["make_envelope_agent"]


def make_envelope_agent(cfg, env, *, gamma: float, device: torch.device) -> Agent:
    """The Envelope :class:`~morl_trl.recipes.agent.Agent` of ``cfg`` for ``env`` (discrete actions)."""
    spec = action_spec(env)
    if not is_discrete(spec):
        raise ValueError(f"envelope needs discrete actions; {cfg.env_id} has {type(spec).__name__}: use capql or mosac")
    authors = cfg.envelope_network == "authors"
    qnet = make_vector_q_network(obs_shape(env), spec.space.n, num_objectives(env), num_cells=cfg.hidden,
                                 # the authors concatenate w after the first hidden layer, or after the CNN
                                 preference_layer=1 if authors and len(obs_shape(env)) == 1 else 0,
                                 init="orthogonal" if authors else "default").to(device)
    greedy = TensorDictSequential(qnet, MOQValueModule())
    egreedy = epsilon_greedy(cfg, env)
    anneal = cfg.homotopy_final is not None
    loss = EnvelopeQLoss(
        qnet, num_preference_samples=cfg.num_sampled_prefs, homotopy_lambda=cfg.homotopy_lambda0,
        final_homotopy_lambda=cfg.homotopy_final if anneal else cfg.homotopy_lambda0,
        homotopy_steps=(cfg.homotopy_frames or cfg.frames) if anneal else None,
        priority=cfg.envelope_priority, use_prioritized_weights=cfg.per_importance_weights,
    )
    loss.make_value_estimator(gamma=gamma)
    optimizers = {"qvalue": adam(loss.parameters(), cfg.lr, fused=fused_choice(cfg))}
    return Agent(cfg, loss, TensorDictSequential(greedy, egreedy), greedy, optimizers, target_updater(cfg, loss),
                 device=device, exploration_module=egreedy, eval_exploration=eval_exploration(cfg))
