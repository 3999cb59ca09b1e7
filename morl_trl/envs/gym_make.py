"""One MO-Gymnasium env as morl_trl builds it (for its batches, its facts and its reference point)."""

from __future__ import annotations

from morl_trl._quiet import quiet_gym

__all__ = ["make_gym_env"]


def make_gym_env(env_id: str, env_kwargs: dict | None = None):
    """``mo_gymnasium.make(env_id, **env_kwargs)`` without the dependencies' noise
    (:func:`morl_trl._quiet.quiet_gym`), a ``Dict`` observation flattened into one vector
    (Gymnasium's ``FlattenObservation``: discrete entries one-hot), as our policies read one entry."""
    import gymnasium
    import mo_gymnasium

    with quiet_gym():
        env = mo_gymnasium.make(env_id, **dict(env_kwargs or {}))
        if isinstance(env.observation_space, gymnasium.spaces.Dict):
            env = gymnasium.wrappers.FlattenObservation(env)
    return env
