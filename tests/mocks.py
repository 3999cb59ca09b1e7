"""Test doubles: the toy contextual domain lives in the package (morl_trl.envs.toy)."""

from morl_trl.envs.toy import TOY_CONTEXT, ToyContextEnv

__all__ = ["TOY_CONTEXT", "ToyContextEnv"]
