"""Contextual multi-objective domains on the DeepMind Control Suite (beyond the paper).

Walker (walk, run), Cheetah (run) and Hopper (hop) from ``dm_control.suite``, batched like the
paper's MuJoCo domains (one ``step`` advances N sub-envs, each its own context, through
MuJoCo's batched C++ stepping). :mod:`.spec` states the objectives, their scales and the
CARL-style contexts. The envs need the ``dmc`` extra (``pip install 'morl-trl[dmc]'``);
importing this package loads no simulator.

Example:
    >>> from morl_trl.envs import make_env, evaluation_suite
    >>> evaluation_suite("DMCWalkerDR-v0")[:3]
    ['DMCWalkerDefault-v0', 'DMCWalkerLight-v0', 'DMCWalkerHeavy-v0']
    >>> env = make_env("DMCWalkerDR-v0", num_envs=4, seed=0)   # a new context per episode
    >>> env.rollout(2)["next", "reward"].shape
    torch.Size([4, 2, 3])
"""

__all__ = ["DMCCheetahEnv", "DMCContextEnv", "DMCHopperEnv", "DMCWalkerEnv"]

_MODULES = {
    "DMCContextEnv": "base",
    "DMCCheetahEnv": "cheetah",
    "DMCHopperEnv": "hopper",
    "DMCWalkerEnv": "walker",
}


def __getattr__(name: str):
    module = _MODULES.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(f"morl_trl.envs.dmc.{module}"), name)


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
