"""Evaluation weight sets on the simplex: evenly spread ("energy"), uniformly random, the corners."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
import torch

from morl_trl.preferences.sampling import sample_preferences

__all__ = ["energy_weights", "uniform_weights", "extreme_weights", "pymoo_energy_weights"]


def _check(num_objectives: int, n: int) -> None:
    if not isinstance(num_objectives, int) or num_objectives < 1:
        raise ValueError(f"num_objectives must be a positive int, got {num_objectives!r}")
    if not isinstance(n, int) or n < 1:
        raise ValueError(f"the number of weights must be a positive int, got {n!r}")


_CACHE_FILE = Path(__file__).with_name("energy_weights.json")


@functools.lru_cache(maxsize=1)
def _precomputed() -> dict:
    # pymoo's energy optimization takes seconds; the paper's shapes are shipped precomputed
    # (tests check them against pymoo)
    with _CACHE_FILE.open() as fh:
        return json.load(fh)


@functools.lru_cache(maxsize=32)
def _energy(num_objectives: int, n: int, seed: int) -> np.ndarray:
    if num_objectives == 1:
        return np.ones((n, 1))
    cached = _precomputed().get(f"k{num_objectives}_n{n}_seed{seed}")
    if cached is not None:
        return np.asarray(cached, dtype=np.float64)
    return pymoo_energy_weights(num_objectives, n, seed)


def pymoo_energy_weights(num_objectives: int, n: int, seed: int) -> np.ndarray:
    """pymoo's ``get_reference_directions("energy", k, n, seed=seed)``, computed now (seconds)."""
    from pymoo.util.ref_dirs import get_reference_directions

    return np.asarray(get_reference_directions("energy", num_objectives, n, seed=seed), dtype=np.float64)


def energy_weights(num_objectives: int, n: int = 100, *, seed: int = 42, dtype=torch.float64) -> torch.Tensor:
    """``n`` evenly spread weights on the simplex, ``[n, k]``: the paper's evaluation weights.

    pymoo's Riesz s-energy reference directions with ``seed=42``, exactly what the authors'
    ``equally_spaced_weights(k, n)`` returns (SPEC §2: ``n = 100``, 32 for Mario). They
    include the simplex corners. The paper's shapes (k = 2..6 with n = 100, and k = 3 with
    n = 32) are read from a file computed with pymoo; others are computed once per
    ``(k, n, seed)`` and cached.

    Example:
        >>> w = energy_weights(2, 5)
        >>> w.shape, bool(torch.allclose(w.sum(-1), torch.ones(5, dtype=w.dtype)))
        (torch.Size([5, 2]), True)
    """
    _check(num_objectives, n)
    if n < num_objectives:
        raise ValueError(
            f"energy weights need n >= num_objectives (they include the {num_objectives} corners of the "
            f"simplex), got n={n}; use uniform_weights or extreme_weights for fewer"
        )
    return torch.as_tensor(_energy(num_objectives, n, int(seed)).copy(), dtype=dtype)


def uniform_weights(
    num_objectives: int,
    n: int,
    *,
    generator: torch.Generator | None = None,
    seed: int | None = None,
    dtype=torch.float64,
) -> torch.Tensor:
    """``n`` weights drawn uniformly on the simplex (flat Dirichlet, :func:`sample_preferences`), ``[n, k]``.

    Pass a ``generator`` or a ``seed`` for reproducibility.

    Example:
        >>> uniform_weights(3, 4, seed=0).shape
        torch.Size([4, 3])
    """
    _check(num_objectives, n)
    if generator is None:
        generator = torch.Generator()
        generator.manual_seed(int(seed) if seed is not None else int(torch.randint(0, 2**31 - 1, (1,))))
    return sample_preferences(n, num_objectives, generator=generator, dtype=dtype)


def extreme_weights(num_objectives: int, dtype=torch.float64) -> torch.Tensor:
    """The ``k`` corners of the simplex (one objective at a time), ``[k, k]``.

    Example:
        >>> extreme_weights(2)
        tensor([[1., 0.],
                [0., 1.]], dtype=torch.float64)
    """
    _check(num_objectives, 1)
    return torch.eye(num_objectives, dtype=dtype)
