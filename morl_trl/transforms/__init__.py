"""TorchRL transforms for contextual multi-objective RL.

Compose them in a :class:`~torchrl.envs.TransformedEnv` like TorchRL's own transforms. All
are batched (any ``[*B]``), honour partial resets (``"_reset"``), transform their specs, and
work inside and outside ``SerialEnv``/``ParallelEnv``.

=========================  ===================================================================
transform                  writes
=========================  ===================================================================
DomainRandomization        ``"context"`` in the reset TensorDict: a new context per sub-env
                           at each of its resets (the env reads it), for envs you compose
                           yourself; ``make_env`` of a DR id needs none (its env draws
                           with its own :class:`~morl_trl.envs.ContextSampler`)
StateActionHistory         ``(s_{t-2}, a_{t-2}, s_{t-1}, a_{t-1}, s_t)`` into ``"observation"``
                           (default, replacing it) or ``out_key``
ContextObservation         ``[obs, c]`` (``c`` optionally normalized) into ``"observation"``
                           (default) or ``out_key``
PreferenceConditioning     ``"preference"`` ``[*B, k]``, one ``w`` per sub-env and episode
                           (observation and state spec)
LinearScalarization        ``("next", "scalar_reward")`` ``[*B, 1]`` = ``w . r`` (a second
                           reward key), or replaces ``"reward"``
DiscountedVectorReturn     ``"episode_return"``, ``"episode_discounted_return"`` ``[*B, k]``,
                           ``"episode_discount"`` ``[*B, 1]``
=========================  ===================================================================

Composition helpers: :func:`compose_policy_env` (the env + the observation transforms a policy
was trained with: what the evaluator runs) and :func:`compose_training_env` (that + a
preference per sub-env and episode + vector returns: what the training recipes run).

Order: put :class:`ContextObservation` after :class:`StateActionHistory` (otherwise the
history repeats the context), and :class:`LinearScalarization` after
:class:`PreferenceConditioning`. A policy then reads ``"observation"`` and ``"preference"``.

Example:
    >>> from torchrl.envs import Compose, TransformedEnv
    >>> from morl_trl.envs.toy import ToyContextEnv, TOY_CONTEXT
    >>> env = TransformedEnv(ToyContextEnv(num_envs=4, seed=0), Compose(
    ...     DomainRandomization(TOY_CONTEXT), StateActionHistory(2), ContextObservation(normalize="unit"),
    ...     PreferenceConditioning(), LinearScalarization(), DiscountedVectorReturn(gamma=0.99)))
    >>> td = env.rollout(10, break_when_any_done=False)
    >>> td["observation"].shape, td["preference"].shape, td["next", "scalar_reward"].shape
    (torch.Size([4, 10, 10]), torch.Size([4, 10, 2]), torch.Size([4, 10, 1]))
"""

from morl_trl.transforms.compose import compose_policy_env, compose_training_env
from morl_trl.transforms.context_observation import ContextObservation
from morl_trl.transforms.domain_randomization import DomainRandomization
from morl_trl.transforms.history import StateActionHistory
from morl_trl.transforms.lean_env import LeanTransformedEnv
from morl_trl.transforms.preference import PreferenceConditioning
from morl_trl.transforms.returns import DiscountedVectorReturn
from morl_trl.transforms.scalarization import LinearScalarization

__all__ = [
    "ContextObservation",
    "DiscountedVectorReturn",
    "DomainRandomization",
    "LeanTransformedEnv",
    "LinearScalarization",
    "PreferenceConditioning",
    "StateActionHistory",
    "compose_policy_env",
    "compose_training_env",
]
