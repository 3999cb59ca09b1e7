"""Env composition helpers: what a preference-conditioned policy observes, and what training adds.

A run builds two stacks from one description, so training and evaluation cannot drift:

* the **policy stack** (:func:`compose_policy_env`): the env plus the observation transforms
  the policy was trained with (the paper's state–action history). The evaluator builds its
  envs with this stack and adds the preferences and returns itself.
* the **training stack** (:func:`compose_training_env`): the policy stack plus a preference
  per sub-env and episode and the episode's vector returns.

An env that is not a ``TransformedEnv`` yet is wrapped in a
:class:`~morl_trl.transforms.lean_env.LeanTransformedEnv` (TorchRL's, with a short
``step_and_maybe_reset`` over our envs and transforms); a ``TransformedEnv`` given is extended as it is.
"""

from __future__ import annotations

from torchrl.envs import EnvBase, TransformedEnv

from morl_trl.transforms.history import StateActionHistory
from morl_trl.transforms.lean_env import LeanTransformedEnv
from morl_trl.transforms.preference import PreferenceConditioning
from morl_trl.transforms.returns import DiscountedVectorReturn

__all__ = ["compose_policy_env", "compose_training_env"]


def _as_transformed(env: EnvBase) -> TransformedEnv:
    return env if isinstance(env, TransformedEnv) else LeanTransformedEnv(env)


def compose_policy_env(env: EnvBase, *, history_len: int = 0) -> TransformedEnv:
    """``env`` with the observation transforms of the policy: ``StateActionHistory(history_len)`` if > 0.

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = compose_policy_env(make_env("MOLunarLanderHard-v0", num_envs=2), history_len=2)
        >>> env.reset()["observation"].shape          # (s, a, s, a, s): 8 + 1 + 8 + 1 + 8
        torch.Size([2, 26])
    """
    if isinstance(history_len, bool) or not isinstance(history_len, int) or history_len < 0:
        raise ValueError(f"history_len must be an int >= 0, got {history_len!r}")
    env = _as_transformed(env)
    if history_len:
        env.append_transform(StateActionHistory(history_len))
    return env


def compose_training_env(
    env: EnvBase,
    *,
    gamma: float,
    history_len: int = 0,
    preference_seed: int | None = None,
    preference_mode: str = "dirichlet",
    preference_resample: str = "episode",
) -> TransformedEnv:
    """The policy stack plus :class:`PreferenceConditioning` (a new ``w`` per sub-env and episode,
    or per step with ``preference_resample="step"``, drawn as ``preference_mode``) and
    :class:`DiscountedVectorReturn` (the episode's vector returns).

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = compose_training_env(make_env("MOLavaGridDR-v0", num_envs=4, seed=0), gamma=0.995, preference_seed=1)
        >>> td = env.rollout(3, break_when_any_done=False)
        >>> td["preference"].shape, td["next", "episode_return"].shape
        (torch.Size([4, 3, 2]), torch.Size([4, 3, 2]))
    """
    env = compose_policy_env(env, history_len=history_len)
    k = int(env.full_reward_spec[env.reward_key].shape[-1])
    env.append_transform(PreferenceConditioning(k, mode=preference_mode, resample=preference_resample, seed=preference_seed))
    env.append_transform(DiscountedVectorReturn(gamma))
    return env
