"""A contextual multi-objective domain as data: :class:`DomainSpec`.

Each built-in domain describes itself in a ``spec`` module inside its own folder
(``morl_trl/envs/<domain>/spec.py``, a tuple ``SPECS`` of :class:`DomainSpec`), which imports
neither the registry nor a simulator; :mod:`morl_trl.envs.registry` reads those tuples.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import torch

from morl_trl.envs.context import ContextSpace

__all__ = ["DomainSpec", "SORLReward"]


@dataclass(frozen=True)
class SORLReward:
    """A domain's single-objective reward f_SORL: the scalar a single-objective agent (the paper's
    SAC baseline) is trained on, and the paper's "Scalar reward is not enough" analysis scores
    every method by (its appendix "Single Objective Utility Function Results").

    The env emits it per step as ``"original_reward"`` ``[*B, 1]`` (the authors'
    ``info["original_scalar_reward"]``); the evaluator sums that entry. This record says what it
    is in terms of the vector reward ``r_t`` ``[*B, k]``: per step ``weights . r_t + offset``
    (``offset`` collects the terms the vector reward adds to every objective, e.g. a healthy
    bonus), exactly when ``exact``; ``note`` says where the paper's formula, the authors' code
    and the env differ.

    Args:
        paper: the paper's formula, as its appendix writes it (``""``: not in the paper).
        weights: coefficient of each objective, in ``objective_names`` order.
        offset: constant added per step.
        exact: the env's ``original_reward`` equals ``weights . r_t + offset`` at every step.
        note: where it differs, and why.

    Example:
        >>> import torch
        >>> from morl_trl.envs import domain_of
        >>> sorl = domain_of("MOHalfCheetahDR-v5").sorl
        >>> sorl.paper, sorl.weights, sorl.exact
        ('1.0 v_x + 0.1 c', (1.0, 0.1), True)
        >>> sorl.scalarize(torch.tensor([[2.0, -3.0]]))    # 2.0 + 0.1 * -3.0
        tensor([1.7000])
    """

    paper: str
    weights: tuple[float, ...]
    offset: float = 0.0
    exact: bool = True
    note: str = ""

    def scalarize(self, reward: torch.Tensor) -> torch.Tensor:
        """``weights . reward + offset`` over the last axis (``[*B, k] -> [*B]``)."""
        w = torch.as_tensor(self.weights, dtype=reward.dtype, device=reward.device)
        if reward.shape[-1] != w.numel():
            raise ValueError(f"reward has {reward.shape[-1]} objectives; f_SORL weights {len(self.weights)}")
        return (reward * w).sum(-1) + self.offset


@dataclass(frozen=True)
class DomainSpec:
    """A contextual multi-objective domain as data.

    Args:
        name: human name, e.g. ``"MO-LunarLander"``.
        train_id: the domain-randomized training id, e.g. ``"MOLunarLanderDR-v0"``.
        env_class: ``"module:Class"`` of the batched :class:`~torchrl.envs.EnvBase`; imported
            only when an env is built. The class takes ``num_envs``, ``context``, ``device``,
            ``seed`` and the ``env_kwargs`` below.
        context_space: the domain's :class:`ContextSpace`.
        contexts: every fixed-context id of the domain mapped to its parameter overrides
            (the rest stays at the default).
        evaluation_ids: the paper's evaluation suite for ``train_id`` (a subset of ``contexts``).
        env_kwargs: extra constructor arguments (e.g. ``continuous=True``).
        gamma: the discount the paper evaluates with.
        hv_ref_point: the paper's unnormalized hypervolume reference point.
        hv_ref_point_source: where ``hv_ref_point`` comes from, when it is not the paper's (a
            foreign env's: :mod:`morl_trl.envs.ref_point`).
        objective_names: names of the reward entries, in order.
        max_episode_steps: the truncation horizon.
        history_len: the paper's state-action history length (``StateActionHistory``; 0: none).
        train_frames: the paper's training length in environment frames.
        eval_interval: the paper's evaluation period in frames.
        eval_weights: the paper's number of evaluation weights (energy weights, SPEC §2).
        true_front: ``gamma -> [n, k]`` array of the env's true Pareto front (discounted with
            ``gamma``), where the env knows it (MO-Gymnasium's ``pareto_front``); gives IGD and
            the hypervolume ratio in evaluations.
        foreign: an env from outside morl_trl (a MO-Gymnasium id, a user's TorchRL env;
            :mod:`morl_trl.envs.foreign`): no context parameters, no paper protocol.
        sorl: the domain's single-objective reward f_SORL in terms of the vector reward
            (:class:`SORLReward`); ``None`` where the paper gives none.

    Example:
        >>> from morl_trl.envs import domain_of
        >>> spec = domain_of("MOHopperHard-v5")  # any id of the domain
        >>> spec.train_id, spec.objective_names, spec.history_len, spec.train_frames
        ('MOHopperDR-v5', ('forward', 'jump', 'energy'), 2, 3000000)
    """

    name: str
    train_id: str
    env_class: str
    context_space: ContextSpace
    contexts: Mapping[str, Mapping[str, Any]]
    evaluation_ids: tuple[str, ...]
    objective_names: tuple[str, ...]
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    gamma: float = 0.99
    hv_ref_point: tuple[float, ...] | None = None
    hv_ref_point_source: str | None = None
    max_episode_steps: int = 1000
    # the paper's training and evaluation protocol (SPEC §2, §4)
    history_len: int = 0
    train_frames: int = 1_000_000
    eval_interval: int = 50_000
    eval_weights: int = 100
    true_front: Callable[[float], Any] | None = None
    foreign: bool = False
    sorl: SORLReward | None = None

    def __post_init__(self) -> None:
        missing = [e for e in self.evaluation_ids if e not in self.contexts]
        if missing:
            raise ValueError(f"{self.name}: evaluation ids {missing} have no context")
        if self.sorl is not None and len(self.sorl.weights) != len(self.objective_names):
            raise ValueError(f"{self.name}: f_SORL has {len(self.sorl.weights)} weights for "
                             f"{len(self.objective_names)} objectives {self.objective_names}")

    @property
    def num_objectives(self) -> int:
        return len(self.objective_names)

    def ids(self) -> list[str]:
        return [self.train_id, *self.contexts]

    def env_cls(self) -> type:
        module, _, cls = self.env_class.partition(":")
        return getattr(importlib.import_module(module), cls)

    def context_of(self, env_id: str) -> torch.Tensor:
        """The fixed context of ``env_id`` (the default context for the training id)."""
        if env_id == self.train_id:
            return self.context_space.default_tensor()
        return self.context_space.make(self.contexts[env_id])
