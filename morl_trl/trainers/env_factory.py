"""The training and evaluation environments of a run, built from its config."""

from __future__ import annotations

import torch
from torchrl.envs import TransformedEnv

from morl_trl.envs import domain_of, make_env

__all__ = ["make_train_env", "make_eval_transform"]


def make_train_env(cfg, device: torch.device) -> TransformedEnv:
    """``make_env(cfg.env_id)`` (which draws its own contexts for a DR id) + history + preferences + returns.

    Transforms, in order: :class:`~morl_trl.transforms.StateActionHistory` (if
    ``cfg.history_len``), :class:`~morl_trl.transforms.PreferenceConditioning` (a uniform
    Dirichlet ``w`` per sub-env per episode) and
    :class:`~morl_trl.transforms.DiscountedVectorReturn` (the episode returns logged per objective).
    """
    from morl_trl.transforms import DiscountedVectorReturn, PreferenceConditioning, StateActionHistory

    spec = domain_of(cfg.env_id)
    env = TransformedEnv(make_env(cfg.env_id, num_envs=cfg.num_envs, device=device, seed=cfg.seed))
    if cfg.history_len:
        env.append_transform(StateActionHistory(cfg.history_len))
    env.append_transform(PreferenceConditioning(spec.num_objectives, seed=cfg.seed + 1))
    gamma = cfg.gamma if cfg.gamma is not None else spec.gamma
    env.append_transform(DiscountedVectorReturn(gamma))
    return env


def make_eval_transform(cfg):
    """A factory of the observation transforms the policy was trained with (for the evaluator)."""
    if not cfg.history_len:
        return None
    from morl_trl.transforms import StateActionHistory

    length = cfg.history_len
    return lambda: StateActionHistory(length)
