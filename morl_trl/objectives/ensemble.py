"""Ensembles as one batched module: ``E`` linear layers applied with one batched matmul.

Used by GPI-LS/GPI-PD's Q-network ensemble and by the probabilistic dynamics ensemble
(:mod:`morl_trl.objectives.dynamics`): no Python loop over members.

Example:
    >>> layer = EnsembleLinear(3, 4, 5)
    >>> layer(torch.zeros(3, 7, 4)).shape
    torch.Size([3, 7, 5])
"""

from __future__ import annotations

import math

import torch
from torch import nn
from torch.nn import functional as F

__all__ = ["EnsembleLinear", "EnsembleLayerNorm", "dropout"]


def dropout(x: torch.Tensor, p: float, training: bool) -> torch.Tensor:
    """Inverted dropout (``F.dropout``'s distribution) from a uniform mask: ~30% faster than
    ``F.dropout``'s Bernoulli sampling on CPU for the small rates of the GPI networks."""
    if not training or p == 0.0:
        return x
    return x * ((torch.rand_like(x) >= p).to(x.dtype) * (1.0 / (1.0 - p)))


class EnsembleLinear(nn.Module):
    """``E`` independent ``Linear(in, out)`` layers: ``[E, N, in] -> [E, N, out]``.

    ``init``: ``"orthogonal"`` (each member's weight orthogonal with ``gain``, zero bias; the
    authors' ``layer_init`` and ``EnsembleLayer``) or ``"default"`` (PyTorch's ``Linear`` init).
    """

    def __init__(self, ensemble_size: int, in_features: int, out_features: int, *, init: str = "orthogonal",
                 gain: float = 1.0) -> None:
        super().__init__()
        if ensemble_size < 1 or in_features < 1 or out_features < 1:
            raise ValueError(f"ensemble_size, in_features, out_features must be >= 1, got "
                             f"{(ensemble_size, in_features, out_features)}")
        self.weight = nn.Parameter(torch.empty(ensemble_size, in_features, out_features))
        self.bias = nn.Parameter(torch.zeros(ensemble_size, 1, out_features))
        if init == "orthogonal":
            for e in range(ensemble_size):
                self.weight.data[e] = nn.init.orthogonal_(torch.empty(out_features, in_features), gain=gain).T
        elif init == "default":
            bound = 1 / math.sqrt(in_features)
            nn.init.uniform_(self.weight, -bound, bound)
            nn.init.uniform_(self.bias, -bound, bound)
        else:
            raise ValueError(f"init={init!r}; valid: 'orthogonal', 'default'")

    @property
    def ensemble_size(self) -> int:
        return self.weight.shape[0]

    def forward(self, x: torch.Tensor, members: slice | None = None) -> torch.Tensor:
        w, b = (self.weight, self.bias) if members is None else (self.weight[members], self.bias[members])
        return torch.baddbmm(b, x, w)


class EnsembleLayerNorm(nn.Module):
    """LayerNorm over the last dim with one affine per member: ``[E, N, d]``."""

    def __init__(self, ensemble_size: int, dim: int, eps: float = 1e-5) -> None:
        super().__init__()
        self.weight = nn.Parameter(torch.ones(ensemble_size, 1, dim))
        self.bias = nn.Parameter(torch.zeros(ensemble_size, 1, dim))
        self.eps = eps

    def forward(self, x: torch.Tensor, members: slice | None = None) -> torch.Tensor:
        w, b = (self.weight, self.bias) if members is None else (self.weight[members], self.bias[members])
        return F.layer_norm(x, x.shape[-1:], eps=self.eps) * w + b
