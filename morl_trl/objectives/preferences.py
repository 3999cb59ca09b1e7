"""Sampling preference vectors (weights on the simplex) inside the losses."""

from __future__ import annotations

from collections.abc import Sequence

import torch

__all__ = ["PREFERENCE_DISTRIBUTIONS", "sample_preferences"]

#: ``"dirichlet"``: uniform on the simplex (Dirichlet(1, ..., 1)).
#: ``"gaussian"``: ``|N(0, I)|`` normalised to sum one, MORL-Baselines'
#: ``random_weights(dist="gaussian")``, which the paper's Envelope runs used.
PREFERENCE_DISTRIBUTIONS = ("dirichlet", "gaussian")


def sample_preferences(
    shape: Sequence[int] | int,
    num_objectives: int,
    *,
    distribution: str = "dirichlet",
    device: torch.device | str | None = None,
    generator: torch.Generator | None = None,
) -> torch.Tensor:
    """Draws ``[*shape, num_objectives]`` preference vectors on the probability simplex.

    Both distributions are sampled from the global torch RNG (or ``generator``), so
    ``torch.manual_seed`` makes them reproducible.

    Args:
        shape: leading (batch) shape of the output.
        num_objectives: ``k``, the number of objectives.
        distribution: one of :data:`PREFERENCE_DISTRIBUTIONS`.
        device: device of the output.
        generator: optional torch generator on ``device``.

    Examples:
        >>> _ = torch.manual_seed(0)
        >>> w = sample_preferences((4,), 3)
        >>> w.shape, bool(torch.allclose(w.sum(-1), torch.ones(4)))
        (torch.Size([4, 3]), True)
    """
    if isinstance(shape, int):
        shape = (shape,)
    if num_objectives < 1:
        raise ValueError(f"num_objectives must be >= 1, got {num_objectives}.")
    if distribution not in PREFERENCE_DISTRIBUTIONS:
        raise ValueError(f"distribution={distribution!r}; valid values are {PREFERENCE_DISTRIBUTIONS}.")
    size = (*shape, num_objectives)
    if distribution == "dirichlet":
        # -log(U) is Exp(1); normalised Exp(1) draws are Dirichlet(1, ..., 1).
        u = torch.rand(size, device=device, generator=generator)
        x = -torch.log(u.clamp_min(torch.finfo(u.dtype).tiny))
    else:
        x = torch.randn(size, device=device, generator=generator).abs()
    return x / x.sum(-1, keepdim=True).clamp_min(torch.finfo(x.dtype).tiny)
