"""CAPQL (Lu, Herman & Yu, 2023) and multi-objective SAC (MORL/D's building block, continuous
and discrete): the agents that ``morl-trl train capql|mosac|mosac_discrete`` train.

A preference-conditioned actor ``pi(a | s, w)`` (tanh-Gaussian or categorical), two vector
critics ``Q(s, a, w)`` ``[k]`` with Polyak (or hard) targets, Adam for actor, critics and,
when learned, the temperature. The loop that drives them is :mod:`morl_trl.recipes.off_policy`.

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

from morl_trl.objectives import (
    CAPQLLoss,
    DiscreteMOSACLoss,
    MOSACLoss,
    make_categorical_actor,
    make_gaussian_actor,
    make_vector_critic,
    make_vector_q_network,
)
from morl_trl.recipes.agent import (
    Agent,
    action_spec,
    actor_critic_optimizers,
    eval_exploration,
    is_discrete,
    num_objectives,
    obs_shape,
    target_updater,
)

__all__ = ["make_capql_agent", "make_mosac_agent", "make_discrete_mosac_agent"]


def _continuous(cfg, env, device):
    spec = action_spec(env)
    if is_discrete(spec):
        raise ValueError(f"{cfg.algo} needs continuous actions; {cfg.env_id} is discrete: use envelope or mosac_discrete")
    (obs_dim,) = obs_shape(env)
    k = num_objectives(env)
    actor = make_gaussian_actor(obs_dim, spec.to(device), k, num_cells=cfg.hidden, scale=cfg.actor_scale).to(device)
    critic = make_vector_critic(obs_dim, spec.shape[-1], k, num_cells=cfg.hidden).to(device)
    return spec, actor, critic


def _agent(cfg, loss, actor, gamma, device, **kwargs) -> Agent:
    loss.make_value_estimator(gamma=gamma)
    return Agent(cfg, loss, actor, actor, actor_critic_optimizers(cfg, loss), target_updater(cfg, loss),
                 device=device, eval_exploration=eval_exploration(cfg), **kwargs)


def _loss_kwargs(cfg) -> dict:
    return dict(resample_preferences=cfg.loss_fresh_preferences, use_prioritized_weights=cfg.per_importance_weights)


def make_capql_agent(cfg, env, *, gamma: float, device: torch.device) -> Agent:
    """CAPQL: per-objective min of the critics, fixed temperature.

    As the authors by default: the acting preference is redrawn every step from the 22.5-degree
    cone and stored with the transition (``preference_distribution="cone"``,
    ``preference_resample="step"``, set on the training env), the loss trains on the stored
    preference (``loss_fresh_preferences=true``: fresh uniform ones per sample) and the actor's
    log-std is clamped to [-20, 2] (``actor_scale="softplus"``: TorchRL's biased softplus).
    """
    _, actor, critic = _continuous(cfg, env, device)
    return _agent(cfg, CAPQLLoss(actor, critic, alpha=cfg.alpha, **_loss_kwargs(cfg)), actor, gamma, device)


def make_mosac_agent(cfg, env, *, gamma: float, device: torch.device) -> Agent:
    """MOSAC: the episode's preference from the batch, scalarized critic min, learned temperature;
    evaluated with sampled actions as the paper's MORL/D (``eval_exploration="deterministic"``: the mean)."""
    spec, actor, critic = _continuous(cfg, env, device)
    loss = MOSACLoss(actor, critic, alpha_init=cfg.alpha, fixed_alpha=not cfg.learn_alpha, action_spec=spec,
                     **_loss_kwargs(cfg))
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
                             use_prioritized_weights=cfg.per_importance_weights)
    return _agent(cfg, loss, actor, gamma, device)
