"""The paper's single-objective baseline: SAC on the domain's original scalar reward
(``morl-trl train sac <id>``), evaluated under the MORL protocol.

TorchRL's own :class:`~torchrl.objectives.SACLoss` (continuous actions: tanh-Gaussian actor, two
critics, Polyak targets) and :class:`~torchrl.objectives.DiscreteSACLoss` (categorical actor, two
Q-networks, hard target copies), with their parts apart (:mod:`morl_trl.objectives.sac`), learn from ``("next", "original_reward")`` ``[*B, 1]`` (the
authors' ``info['original_scalar_reward']``; SPEC §1 defines it per domain), read with
``loss.set_keys(reward="original_reward")``. The networks do not read the preference, so under
the MORL evaluation protocol every evaluation weight gets the same stochastic policy (sampled
actions, as the authors evaluate SAC) and the vector returns it earns form its front: its NHGR
sits in the same table as the MORL algorithms'. Training uses the same env stack as the others
(DR env + history + preferences that the SAC networks ignore + vector returns).

Example:
    >>> from morl_trl.recipes import resolve_config
    >>> from morl_trl.recipes.off_policy import make_training_env
    >>> cfg = resolve_config("sac", "MOLavaGridDR-v0", quick=True, hidden=(16,), num_envs=2)
    >>> env = make_training_env(cfg, torch.device("cpu"))
    >>> agent = make_sac_agent(cfg, env, gamma=0.995, device=torch.device("cpu"))
    >>> type(agent.loss).__name__, agent.loss.tensor_keys.reward
    ('DiscreteSACLoss', 'original_reward')
"""

from __future__ import annotations

import torch
from tensordict.nn import TensorDictModule
from torch import nn

from morl_trl.objectives import make_categorical_actor, make_gaussian_actor, make_vector_critic, make_vector_q_network
from morl_trl.objectives.networks import orthogonal_init_
from morl_trl.objectives.sac import DiscreteSACLoss, SACLoss
from morl_trl.training.agent import (
    Agent,
    action_spec,
    actor_critic_optimizers,
    eval_exploration,
    is_discrete,
    obs_shape,
    orthogonal_critic_copies_,
    target_updater,
)

__all__ = ["make_sac_agent", "ORIGINAL_REWARD_KEY"]

#: where every domain writes its single-objective (SORL) reward
ORIGINAL_REWARD_KEY = "original_reward"


class _DropObjectiveDim(nn.Module):
    """``[*B, |A|, 1] -> [*B, |A|]``: a one-objective Q-network as TorchRL's discrete SAC expects."""

    def __init__(self, net: nn.Module) -> None:
        super().__init__()
        self.net = net

    def forward(self, *inputs: torch.Tensor) -> torch.Tensor:
        return self.net(*inputs).squeeze(-1)


def make_sac_agent(cfg, env, *, gamma: float, device: torch.device) -> Agent:
    """SAC (continuous) or discrete SAC for ``env`` on its ``original_reward``; TorchRL's losses.

    The critic loss is the squared error (``loss_function="l2"``; the record does not give its form);
    the temperature starts at ``cfg.alpha`` and is tuned unless ``learn_alpha`` is false (discrete:
    towards ``target_entropy_scale * log |A|``).
    """
    spec = action_spec(env)
    obs = obs_shape(env)
    if is_discrete(spec):
        n = spec.space.n
        actor = make_categorical_actor(obs, n, 1, num_cells=cfg.hidden, preference_key=None, action_spec=spec)
        orthogonal_init_(actor)  # the authors' init of every layer: orthogonal (gain 1), zero biases
        q = orthogonal_init_(make_vector_q_network(obs, n, 1, num_cells=cfg.hidden, preference_key=None))
        critic = TensorDictModule(_DropObjectiveDim(q.module), in_keys=q.in_keys, out_keys=["action_value"])
        loss = DiscreteSACLoss(actor.to(device), critic.to(device), action_space=spec, num_actions=n,
                               loss_function="l2", alpha_init=cfg.alpha, fixed_alpha=not cfg.learn_alpha,
                               target_entropy_weight=cfg.target_entropy_scale, alpha_loss_form=cfg.alpha_loss_form)
    else:
        (obs_dim,) = obs
        actor = make_gaussian_actor(obs_dim, spec.to(device), 1, num_cells=cfg.hidden, preference_key=None,
                                    scale=cfg.actor_scale).to(device)
        critic = make_vector_critic(obs_dim, spec.shape[-1], 1, num_cells=cfg.hidden, preference_key=None).to(device)
        orthogonal_init_(actor), orthogonal_init_(critic)  # the authors' init: orthogonal (gain 1), zero biases
        loss = SACLoss(actor, critic, num_qvalue_nets=2, loss_function="l2", alpha_init=cfg.alpha,
                       fixed_alpha=not cfg.learn_alpha, action_spec=spec, alpha_loss_form=cfg.alpha_loss_form)
    orthogonal_critic_copies_(loss, critic)  # (the loss re-draws its critic copies with PyTorch's init)
    loss.set_keys(reward=ORIGINAL_REWARD_KEY)
    loss.make_value_estimator(gamma=gamma)
    return Agent(cfg, loss, actor, actor, actor_critic_optimizers(cfg, loss), target_updater(cfg, loss),
                 device=device, eval_exploration=eval_exploration(cfg), capturable=True)
