"""Drawing preference vectors on the simplex: Dirichlet(alpha) and MORL-Baselines' "gaussian"."""

from __future__ import annotations

from collections.abc import Sequence

import torch

__all__ = ["PREFERENCE_DISTRIBUTIONS", "sample_preferences"]

#: ``"dirichlet"``: Dirichlet(``alpha``), uniform on the simplex for ``alpha=1``.
#: ``"gaussian"``: ``|N(0, I)|`` normalised to sum one, MORL-Baselines'
#: ``random_weights(dist="gaussian")``, which the paper's Envelope runs used.
PREFERENCE_DISTRIBUTIONS = ("dirichlet", "gaussian")


def _standard_gamma(alpha: torch.Tensor, generator: torch.Generator | None) -> torch.Tensor:
    """Gamma(alpha, 1) draws (Marsaglia & Tsang, 2000; boosted for alpha < 1)."""
    boost = alpha < 1
    a = torch.where(boost, alpha + 1, alpha)
    d = a - 1.0 / 3.0
    c = 1.0 / torch.sqrt(9.0 * d)
    out = torch.empty_like(a)
    todo = torch.ones_like(a, dtype=torch.bool)
    while todo.any():
        x = torch.randn(a.shape, generator=generator, dtype=a.dtype, device=a.device)
        u = torch.rand(a.shape, generator=generator, dtype=a.dtype, device=a.device)
        v = (1 + c * x) ** 3
        ok = (v > 0) & (torch.log(u) < 0.5 * x * x + d - d * v + d * torch.log(v.clamp(min=1e-30)))
        accept = todo & ok
        out = torch.where(accept, d * v, out)
        todo &= ~ok
    if boost.any():
        u = torch.rand(a.shape, generator=generator, dtype=a.dtype, device=a.device)
        out = torch.where(boost, out * u.pow(1.0 / alpha), out)
    return out


def _alpha(alpha, k: int) -> torch.Tensor:
    a = torch.as_tensor(alpha, dtype=torch.float64)
    if a.ndim > 1 or not torch.isfinite(a).all() or (a <= 0).any():
        raise ValueError(f"alpha must be a positive float or [k] vector, got {a.tolist()}")
    if a.ndim == 1 and a.numel() != k:
        raise ValueError(f"alpha has {a.numel()} entries; expected {k} (one per objective)")
    return a.expand(k)


def sample_preferences(
    shape: Sequence[int] | int,
    num_objectives: int,
    *,
    distribution: str = "dirichlet",
    alpha: float | torch.Tensor = 1.0,
    generator: torch.Generator | None = None,
    device: torch.device | str | None = None,
    dtype: torch.dtype = torch.float32,
) -> torch.Tensor:
    """Draw ``[*shape, num_objectives]`` preference vectors on the probability simplex.

    Draws come from ``generator`` (on ``device``) or torch's global RNG, so a seed makes them
    reproducible. The Dirichlet draws normalise Exp(1) variates (``exponential_`` in
    float64) for ``alpha = 1`` and Marsaglia–Tsang Gamma(alpha) variates otherwise; they are
    what :class:`~morl_trl.transforms.PreferenceConditioning` gives its sub-envs.

    Args:
        shape: leading (batch) shape.
        num_objectives: ``k``.
        distribution: one of :data:`PREFERENCE_DISTRIBUTIONS`.
        alpha: Dirichlet concentration, a float or ``[k]`` (``"dirichlet"`` only).
        generator: a :class:`torch.Generator` on ``device``; the global RNG when ``None``.
        device: where the draws are made.
        dtype: of the output.

    Example:
        >>> g = torch.Generator().manual_seed(0)
        >>> sample_preferences(2, 3, generator=g)
        tensor([[0.6553, 0.2298, 0.1149],
                [0.4935, 0.2016, 0.3049]])
        >>> w = sample_preferences((4,), 3, distribution="gaussian", generator=g)
        >>> bool((w >= 0).all()), bool(torch.allclose(w.sum(-1), torch.ones(4)))
        (True, True)
    """
    if isinstance(shape, int):
        shape = (shape,)
    shape = tuple(int(s) for s in shape)
    if isinstance(num_objectives, bool) or not isinstance(num_objectives, int) or num_objectives < 1:
        raise ValueError(f"num_objectives must be a positive int, got {num_objectives!r}")
    if distribution not in PREFERENCE_DISTRIBUTIONS:
        raise ValueError(f"distribution={distribution!r}; valid values are {PREFERENCE_DISTRIBUTIONS}")
    k = num_objectives
    if generator is not None and device is None:
        device = generator.device
    size = (*shape, k)
    if distribution == "gaussian":
        if not bool((torch.as_tensor(alpha) == 1).all()):
            raise ValueError(f"alpha={alpha!r} applies to distribution='dirichlet' only")
        x = torch.randn(size, generator=generator, device=device, dtype=torch.float64).abs()
        x = x.clamp_min(torch.finfo(x.dtype).tiny)  # an all-zero row (probability 0) stays defined
    else:
        a = _alpha(alpha, k)
        if bool((a == 1).all()):
            x = torch.empty(size, dtype=torch.float64, device=device).exponential_(generator=generator)
        else:
            x = _standard_gamma(a.to(device=device).expand(size).clone(), generator)
    return (x / x.sum(-1, keepdim=True)).to(dtype)
