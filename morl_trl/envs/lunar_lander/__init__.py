"""MO-LunarLander (SPEC §1.1) as a batched TorchRL environment (needs the ``box2d`` extra).

Modules: :mod:`.spec` (the context space and ids, data only), :mod:`.physics` (one Box2D
world, Gymnasium's constants), :mod:`.random_streams` (per-sub-env generators with
block-fetched per-step draws), :mod:`.env` (:class:`MOLunarLanderEnv`), :mod:`.render` (RGB
arrays with Pillow). Importing this package loads no simulator: ``MOLunarLanderEnv`` imports
Box2D on first use.
"""

__all__ = ["MOLunarLanderEnv"]


def __getattr__(name: str):
    if name == "MOLunarLanderEnv":  # Box2D on first use only (the spec module stays importable)
        from morl_trl.envs.lunar_lander.env import MOLunarLanderEnv

        return MOLunarLanderEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
