"""MO-Hopper, MO-HalfCheetah and MO-Humanoid as batched contextual TorchRL environments.

Importing this package needs the ``mujoco`` extra (``pip install morl-trl[mujoco]``). The XML
assets beside it derive from Gymnasium's (MIT); see ``assets/GYMNASIUM_LICENSE.txt``.

Example:
    >>> from morl_trl.envs import make_env
    >>> env = make_env("MOHopperDR-v5", num_envs=8, seed=0)   # a new context per episode
    >>> env.rollout(4)["next", "reward"].shape
    torch.Size([8, 4, 3])
"""

from morl_trl.envs.mujoco.base import MujocoContextEnv
from morl_trl.envs.mujoco.half_cheetah import MOHalfCheetahEnv
from morl_trl.envs.mujoco.hopper import MOHopperEnv
from morl_trl.envs.mujoco.humanoid import MOHumanoidEnv

__all__ = ["MOHalfCheetahEnv", "MOHopperEnv", "MOHumanoidEnv", "MujocoContextEnv"]
