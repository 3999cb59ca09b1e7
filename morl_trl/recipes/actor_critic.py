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

import copy
import math

import torch
from tensordict import TensorDict
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
    # the authors' init of every layer: orthogonal (gain 1), zero biases (capql.py:118,169)
    return spec, orthogonal_init_(actor), orthogonal_init_(critic)


def _agent(cfg, loss, actor, gamma, device, **kwargs) -> Agent:
    loss.make_value_estimator(gamma=gamma)
    return Agent(cfg, loss, actor, actor, actor_critic_optimizers(cfg, loss), target_updater(cfg, loss),
                 device=device, eval_exploration=eval_exploration(cfg), **kwargs)


@torch.no_grad()
def orthogonal_critic_copies_(loss, critic, init_=None) -> None:
    """Give each of the loss's ``num_qvalue_nets`` critic copies (TorchRL re-draws the copies with
    PyTorch's init) its own orthogonal init (``init_``, default :func:`orthogonal_init_`: gain 1,
    zero biases; the authors' ``layer_init``), and its target the same values."""
    init_ = orthogonal_init_ if init_ is None else init_
    params = loss.qvalue_network_params.data
    for i in range(params.batch_size[0]):
        params[i].update_(TensorDict.from_module(init_(copy.deepcopy(critic))).data)
    target = getattr(loss, "target_qvalue_network_params", None)
    if target is not None:
        target.data.update_(params)


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
