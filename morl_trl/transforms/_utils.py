"""Helpers shared by the transforms: reset masks, seeding, value formatting."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.envs import EnvBase, TransformedEnv
from torchrl.envs.transforms import Transform

from morl_trl.preferences.simplex import format_values as fmt

__all__ = ["reset_mask", "SeededTransform", "fmt", "innermost_env"]

_UNSET = object()


def reset_mask(
    tensordict: TensorDictBase | None,
    batch_size: torch.Size,
    device: torch.device | str | None,
    reset_key: str = "_reset",
) -> torch.Tensor:
    """The sub-envs being reset, as a bool ``[*batch_size]`` mask (all of them without ``"_reset"``)."""
    reset = None if tensordict is None else tensordict.get(reset_key, None)
    if reset is None:
        return torch.ones(batch_size, dtype=torch.bool, device=device)
    reset = reset.to(device=device, dtype=torch.bool)
    nb = len(batch_size)
    if reset.ndim > nb:  # the done-shaped [*B, 1] signal
        reset = reset.flatten(nb).any(-1)
    return reset.expand(batch_size)


def innermost_env(env: EnvBase | None) -> EnvBase | None:
    """The env under every :class:`~torchrl.envs.TransformedEnv` layer."""
    while isinstance(env, TransformedEnv):
        env = env.base_env
    return env


def _env_seed(env: EnvBase | None) -> int | None:
    # read through __dict__: batched envs forward unknown attributes to their (maybe unstarted) workers
    base = innermost_env(env)
    seed = None if base is None else base.__dict__.get("_seed", None)
    return seed if isinstance(seed, int) else None


def _mix(seed: int, salt: int) -> int:
    """A 64-bit seed derived from ``seed`` and a per-transform ``salt`` (identity for salt 0)."""
    return (int(seed) + salt * 0x9E3779B97F4A7C15) % (1 << 64)


class SeededTransform(Transform):
    """A transform that draws from its own :class:`torch.Generator`.

    Seeding rules (the same for every subclass):

    * ``seed=`` at construction or :meth:`set_seed` seed the generator.
    * Otherwise, at the first reset the generator is seeded from the seed of the env underneath
      (``ContextualMOEnv`` keeps it), or from torch's global generator if that env has none.
    * Whenever the env underneath is re-seeded with a *different* seed (e.g. by
      ``ParallelEnv.set_seed``, which gives every worker its own seed), the generator follows.

    ``_salt`` keeps the streams of different transforms seeded with the same value apart.
    """

    _salt = 0

    def _init_seed(self, seed: int | None) -> None:
        self.generator = torch.Generator()
        self._seed = None
        self._env_seed_seen = _UNSET
        if seed is not None:
            self.set_seed(seed)

    @property
    def seed(self) -> int | None:
        """The last seed given to the generator (``None`` before the first one)."""
        return self._seed

    def set_seed(self, seed: int) -> None:
        """Re-seed the transform's generator."""
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise ValueError(f"seed must be an int, got {seed!r}")
        self._seed = int(seed)
        self.generator.manual_seed(_mix(seed, self._salt))

    def clone(self):
        other = super().clone()
        generator = torch.Generator()
        generator.set_state(self.generator.get_state())  # a copy continues the stream, it does not share it
        other.generator = generator
        return other

    def _sync_seed(self) -> None:
        env_seed = _env_seed(self.parent)
        if env_seed is not None and env_seed != self._env_seed_seen:
            first = self._env_seed_seen is _UNSET
            self._env_seed_seen = env_seed
            if not (first and self._seed is not None):
                self.set_seed(env_seed)
        if self._seed is None:
            self.set_seed(int(torch.randint(0, 2**62, (1,)).item()))
