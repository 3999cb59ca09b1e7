"""Every morl_trl id as a Gymnasium / MO-Gymnasium environment.

Importing this module registers every id under the ``morl_trl/`` namespace::

    import gymnasium, mo_gymnasium
    import morl_trl.gym                                            # registers morl_trl/<id>
    env = mo_gymnasium.make("morl_trl/MOLunarLanderDR-v0")         # vector reward, np.float32 [4]
    env = gymnasium.make("morl_trl.gym:morl_trl/MOHopperDR-v5")    # imports and registers itself

Gymnasium 1.x has no plugin entry points (it dropped ``gymnasium.envs`` entry points in 1.0):
the ``"morl_trl.gym:"`` prefix (Gymnasium's ``module:id`` form) imports this module first, so
no explicit import is needed. :func:`register_gymnasium_envs` registers again (e.g. domains
added with :func:`morl_trl.envs.register_domain` since).
"""

from __future__ import annotations

import gymnasium

from morl_trl.envs import list_envs
from morl_trl.gym.env import MOGymnasiumEnv, spec_to_space

__all__ = ["NAMESPACE", "MOGymnasiumEnv", "gymnasium_id", "register_gymnasium_envs", "spec_to_space"]

#: the Gymnasium namespace of every morl_trl id
NAMESPACE = "morl_trl"


def gymnasium_id(env_id: str) -> str:
    """The Gymnasium id of a morl_trl id: ``"morl_trl/<env_id>"``."""
    return f"{NAMESPACE}/{env_id}"


def register_gymnasium_envs() -> list[str]:
    """Register every morl_trl id (``list_envs()``) with Gymnasium as ``morl_trl/<id>``
    (:class:`MOGymnasiumEnv`, no env checker or ``TimeLimit``: episodes end in the env);
    ids already registered are left as they are. Returns the Gymnasium ids."""
    ids = []
    for env_id in list_envs():
        gid = gymnasium_id(env_id)
        if gid not in gymnasium.registry:
            gymnasium.register(
                id=gid,
                entry_point="morl_trl.gym.env:MOGymnasiumEnv",
                kwargs={"env_id": env_id},
                disable_env_checker=True,  # its reward is a vector: Gymnasium's checker expects a scalar
                order_enforce=True,
            )
        ids.append(gid)
    return ids


register_gymnasium_envs()
