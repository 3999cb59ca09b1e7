"""MO-LunarLander (SPEC §1.1) as a batched TorchRL environment (needs the ``box2d`` extra).

Modules: :mod:`.physics` (one Box2D world, Gymnasium's constants), :mod:`.random_streams`
(per-sub-env generators with block-fetched per-step draws), :mod:`.env`
(:class:`MOLunarLanderEnv`), :mod:`.render` (RGB arrays with Pillow).
"""

from morl_trl.envs.lunar_lander.env import MOLunarLanderEnv

__all__ = ["MOLunarLanderEnv"]
