"""MO-Hopper, MO-HalfCheetah and MO-Humanoid as batched contextual TorchRL environments.

The envs need the ``mujoco`` extra (``pip install morl-trl[mujoco]``); importing this package
loads no simulator (the envs import ``mujoco`` on first use; :mod:`.spec`, the context spaces
and ids, is data only). The XML assets beside it derive from Gymnasium's (MIT); see
``assets/GYMNASIUM_LICENSE.txt``.

Example:
    >>> from morl_trl.envs import make_env
    >>> env = make_env("MOHopperDR-v5", num_envs=8, seed=0)   # a new context per episode
    >>> env.rollout(4)["next", "reward"].shape
    torch.Size([8, 4, 3])
"""

__all__ = ["MOHalfCheetahEnv", "MOHopperEnv", "MOHumanoidEnv", "MujocoContextEnv"]

_MODULES = {
    "MujocoContextEnv": "base",
    "MOHalfCheetahEnv": "half_cheetah",
    "MOHopperEnv": "hopper",
    "MOHumanoidEnv": "humanoid",
}


def __getattr__(name: str):
    module = _MODULES.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(f"morl_trl.envs.mujoco.{module}"), name)


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
