"""Batched networks: ``E`` members (a population, an ensemble, a set of critics) as ONE module.

The one home of the batched layers every population and ensemble uses (MORL/D's and PGMORL's populations, the GPI Q
ensembles and critics, GPI-PD's dynamics ensemble): no Python loop over members, one batched matmul per layer.

* :class:`BatchedLinear`: ``E`` independent ``Linear(in, out)``; ``weight [E, in, out]``,
  ``bias [E, 1, out]`` (member ``e`` is ``nn.Linear`` with ``weight[e].T`` and ``bias[e, 0]``).
* :class:`BatchedLayerNorm`: LayerNorm over the last dim with one affine per member.
* :func:`batched_dropout`: inverted dropout (``F.dropout``'s distribution); on the CPU its mask comes
  from geometric gaps between the drops (:func:`dropped_positions`).
* :func:`linear_dropout_norm_relu`: the ``Linear -> Dropout -> LayerNorm -> ReLU`` block of the
  GPI networks, with as few temporaries as exactness allows (in place where autograd permits).
* :class:`BatchedMLP`: ``E`` MLPs of :class:`BatchedLinear` layers (``mlp`` holds them at the
  indices of :class:`~morl_trl.objectives.networks.PreferenceConditionedMLP`'s ``mlp``).

Inputs are member-major: ``[E, *B, in]``, or ``[E * N, in]`` (rows ``e * N .. (e + 1) * N - 1`` belong to member
``e``, as a ``[P * N]`` training env's sub-envs); the output keeps the input's leading shape.

Initialisations (``init``): ``"orthogonal"`` (each member's ``[out, in]`` weight orthogonal with
``gain``, zero bias: the authors' ``layer_init``) or ``"torch"`` (each member as ``nn.Linear``:
``kaiming_uniform(a=sqrt 5)`` weights, then every member's bias ``U(-1/sqrt(in), 1/sqrt(in))``).
Both draw each member's weight as an ``[out, in]`` matrix, as a per-member ``nn.Linear`` would.

Example:
    >>> layer = BatchedLinear(3, 4, 5)
    >>> x = torch.randn(3, 7, 4)
    >>> layer(x).shape
    torch.Size([3, 7, 5])
    >>> torch.allclose(layer(x)[1], layer.member_linear(1)(x[1]), atol=1e-6)
    True
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import Tensor, nn
from torch.nn import functional as F

__all__ = ["BatchedLinear", "BatchedLayerNorm", "BatchedMLP", "batched_dropout", "batched_linear", "dropped_positions",
           "hidden_block", "linear_dropout_norm_relu", "INITS"]

#: the initialisations of :class:`BatchedLinear`
INITS = ("orthogonal", "torch")


def _members(t: Tensor, members: slice | None) -> Tensor:
    return t if members is None else t[members]


def batched_linear(x: Tensor, weight: Tensor, bias: Tensor) -> Tensor:
    """:class:`BatchedLinear` on given tensors: ``x`` ``[E, *B, in]`` (or ``[E * N, in]``), ``weight``
    ``[E, in, out]``, ``bias`` ``[E, 1, out]`` -> ``[E, *B, out]`` (one ``baddbmm``)."""
    if x.dim() == 3 and x.shape[0] == weight.shape[0]:  # already [E, N, in]: the product's own tensor, not a
        return torch.baddbmm(bias, x, weight)  # view of it (in-place steps on a view: autograd copies the gradient)
    flat = x.reshape(weight.shape[0], -1, x.shape[-1])
    return torch.baddbmm(bias, flat, weight).reshape(*x.shape[:-1], weight.shape[-1])


class BatchedLinear(nn.Module):
    """``E`` independent ``Linear(in, out)`` layers: ``[E, *B, in] -> [E, *B, out]`` (one ``baddbmm``).

    Args:
        members: ``E``.
        in_features, out_features: as ``nn.Linear``'s.
        init: ``"orthogonal"`` (default; ``gain``, zero bias) or ``"torch"`` (``nn.Linear``'s); see the module.
        gain: the orthogonal init's gain.

    ``forward(x, members=None)``: ``members`` (a slice) runs only those members (``x`` then has their count first).

    Example:
        >>> lin = BatchedLinear(2, 3, 4, init="torch")
        >>> x = torch.randn(2, 5, 3)
        >>> ref = [lin.member_linear(e)(x[e]) for e in range(2)]
        >>> torch.allclose(lin(x), torch.stack(ref), atol=1e-6), lin(x.reshape(10, 3)).shape
        (True, torch.Size([10, 4]))
    """

    def __init__(self, members: int, in_features: int, out_features: int, *, init: str = "orthogonal",
                 gain: float = 1.0) -> None:
        super().__init__()
        if isinstance(members, bool) or not isinstance(members, int) or members < 1 or in_features < 1 \
                or out_features < 1:
            raise ValueError(f"members, in_features, out_features must be ints >= 1, got "
                             f"{(members, in_features, out_features)}")
        self.members, self.in_features, self.out_features = members, int(in_features), int(out_features)
        self.weight = nn.Parameter(torch.empty(members, self.in_features, self.out_features))
        self.bias = nn.Parameter(torch.empty(members, 1, self.out_features))
        self.reset_parameters(init, gain)

    @torch.no_grad()
    def reset_parameters(self, init: str = "orthogonal", gain: float = 1.0) -> None:
        """Re-draw every member's parameters (``init``, ``gain``: see the class)."""
        if init not in INITS:
            raise ValueError(f"init={init!r}; valid: {INITS}")
        if init == "orthogonal":
            for e in range(self.members):
                self.weight[e].copy_(nn.init.orthogonal_(torch.empty(self.out_features, self.in_features), gain).T)
            self.bias.zero_()
        else:  # as nn.Linear: kaiming_uniform(a=sqrt(5)) weights, then U(-bound, bound) biases
            for e in range(self.members):
                w = torch.empty(self.out_features, self.in_features)
                nn.init.kaiming_uniform_(w, a=math.sqrt(5))
                self.weight[e].copy_(w.T)
            bound = 1 / math.sqrt(self.in_features)
            nn.init.uniform_(self.bias, -bound, bound)

    def forward(self, x: Tensor, members: slice | None = None) -> Tensor:
        return batched_linear(x, _members(self.weight, members), _members(self.bias, members))

    def member_linear(self, e: int) -> nn.Linear:
        """Member ``e`` as a (detached copy) ``nn.Linear``."""
        lin = nn.Linear(self.in_features, self.out_features, device=self.weight.device, dtype=self.weight.dtype)
        with torch.no_grad():
            lin.weight.copy_(self.weight[e].T)
            lin.bias.copy_(self.bias[e, 0])
        return lin

    def extra_repr(self) -> str:
        return f"members={self.members}, in_features={self.in_features}, out_features={self.out_features}"


class BatchedLayerNorm(nn.Module):
    """LayerNorm over the last dim with one affine per member: ``[E, *B, d] -> [E, *B, d]``
    (member ``e`` is ``nn.LayerNorm(d)`` with ``weight[e, 0]``, ``bias[e, 0]``).

    Example:
        >>> norm = BatchedLayerNorm(2, 4)
        >>> x = torch.randn(2, 3, 4)
        >>> torch.allclose(norm(x)[1], nn.LayerNorm(4)(x[1]), atol=1e-6)
        True
    """

    def __init__(self, members: int, dim: int, eps: float = 1e-5) -> None:
        super().__init__()
        self.weight = nn.Parameter(torch.ones(members, 1, dim))
        self.bias = nn.Parameter(torch.zeros(members, 1, dim))
        self.eps = eps

    def forward(self, x: Tensor, members: slice | None = None) -> Tensor:
        w, b = _members(self.weight, members), _members(self.bias, members)
        flat = x.reshape(w.shape[0], -1, x.shape[-1])
        return _affine(F.layer_norm(flat, flat.shape[-1:], eps=self.eps), w, b).reshape(x.shape)


def _grad_free(*tensors: Tensor) -> bool:
    return not torch.is_grad_enabled() or not any(t.requires_grad for t in tensors)


def _affine(normed: Tensor, w: Tensor, b: Tensor) -> Tensor:
    """``normed * w + b`` with one temporary (the sum is added in place: ``AddBackward`` keeps nothing)."""
    if _grad_free(normed, w, b):
        return normed.mul_(w).add_(b)
    return (normed * w).add_(b)


def _dropout_mask(like: Tensor, p: float, of_rows: int | None = None) -> Tensor:
    """The inverted-dropout mask ``keep / (1 - p)`` of ``like``'s shape: iid ``keep ~ Bernoulli(1 - p)``.

    CUDA: ``U[0, 1) >= p`` from one ``uniform_`` of ``like``'s size (the values of ``(torch.rand_like(like) >=
    p).to(dtype) / (1 - p)``). CPU: the dropped positions from geometric gaps (:func:`dropped_positions`): the same
    distribution from ``~n p`` draws instead of ``n`` (torch's CPU generator draws one number at a time: at the GPI
    networks' ``p = 0.01`` the uniform draws were ~15% of an update).

    ``of_rows``: ``like`` ``[E, N, d]`` holds the first ``N`` rows of each member of an ``[E, of_rows, d]``
    activation: the mask is drawn for that whole activation (the same draws) and its first ``N`` rows are returned,
    so rows computed alone get the values they get computed with the rest.
    """
    if of_rows is not None and of_rows != like.shape[-2]:
        e, n, d = like.shape
        if like.device.type != "cpu":
            return torch.rand(e, of_rows, d, dtype=like.dtype, device=like.device)[:, :n].ge_(p).mul_(1.0 / (1.0 - p))
        pos = dropped_positions(e * of_rows * d, p)
        member, within = pos.div(of_rows * d, rounding_mode="floor"), pos.remainder(of_rows * d)
        pos = torch.where(within < n * d, member * (n * d) + within, e * n * d)  # (the rest: to the spare slot)
        mask = torch.full((e * n * d + 1,), 1.0 / (1.0 - p), dtype=like.dtype)
        return mask.index_fill_(0, pos, 0.0)[: e * n * d].view(like.shape)
    if like.device.type != "cpu":
        return torch.rand_like(like).ge_(p).mul_(1.0 / (1.0 - p))
    n = like.numel()
    mask = torch.full((n + 1,), 1.0 / (1.0 - p), dtype=like.dtype)  # slot n: where positions past the end land
    mask.index_fill_(0, dropped_positions(n, p), 0.0)
    return mask[:n].view(like.shape)


def dropped_positions(n: int, p: float, *, chunk: int | None = None) -> Tensor:
    """The positions in ``range(n)`` that dropout at rate ``p`` zeroes, from geometric gaps (CPU).

    Gaps ``G_i ~ Geometric(p)`` on ``{1, 2, ...}`` (``Tensor.geometric_``) put a drop at ``G_1 + ... + G_j - 1``:
    every position is dropped independently with probability ``p`` (a Bernoulli process). Gaps are drawn ``chunk``
    at a time (default ``n p + 6 sqrt(n p) + 16``) until they pass ``n``, one generator stream whatever the chunk;
    positions ``>= n`` are returned as ``n`` (callers keep a spare slot there). ``0 < p < 1``.

    Example:
        >>> _ = torch.manual_seed(0)
        >>> pos = dropped_positions(100_000, 0.01)
        >>> keep = torch.ones(100_001).index_fill_(0, pos, 0.0)[:100_000]
        >>> 900 < int((keep == 0).sum()) < 1100
        True
    """
    chunk = chunk or int(n * p + 6.0 * math.sqrt(n * p) + 16)
    ends = torch.empty(chunk, dtype=torch.float64).geometric_(p).cumsum_(0)
    parts = [ends]
    while ends[-1] < n:  # (rare: more drops than n p + 6 sigma)
        ends = torch.empty(chunk, dtype=torch.float64).geometric_(p).cumsum_(0).add_(ends[-1])
        parts.append(ends)
    ends = parts[0] if len(parts) == 1 else torch.cat(parts)
    return ends.sub_(1.0).clamp_(max=n).long()


def batched_dropout(x: Tensor, p: float, training: bool) -> Tensor:
    """Inverted dropout (``F.dropout``'s distribution), its mask drawn as :func:`dropped_positions`
    says on the CPU (a few draws per drop instead of one per element) and uniformly on CUDA.

    Example:
        >>> _ = torch.manual_seed(0)
        >>> y = batched_dropout(torch.ones(1000), 0.5, training=True)
        >>> sorted(set(y.tolist())), batched_dropout(torch.ones(3), 0.5, training=False).tolist()
        ([0.0, 2.0], [1.0, 1.0, 1.0])
    """
    if not training or p == 0.0:
        return x
    mask = _dropout_mask(x, p)
    return mask.mul_(x) if _grad_free(x) else x * mask


def linear_dropout_norm_relu(x: Tensor, linear: BatchedLinear, norm: BatchedLayerNorm | None, p: float,
                             training: bool, members: slice | None = None) -> Tensor:
    """``relu(norm(dropout(linear(x))))``: the GPI networks' hidden block, as these four modules compute it
    (the same draws and values), with in-place steps where autograd allows: the dropout mask is applied
    to the fresh matmul output in place, the affine's sum and the ReLU too; without gradients, all of it.

    Example:
        >>> lin, norm = BatchedLinear(2, 3, 4), BatchedLayerNorm(2, 4)
        >>> x = torch.randn(2, 5, 3)
        >>> _ = torch.manual_seed(1)
        >>> fast = linear_dropout_norm_relu(x, lin, norm, 0.1, True)
        >>> _ = torch.manual_seed(1)
        >>> torch.equal(fast, torch.relu(norm(batched_dropout(lin(x), 0.1, True))))
        True
    """
    norm_params = None if norm is None else (_members(norm.weight, members), _members(norm.bias, members), norm.eps)
    return hidden_block(x, _members(linear.weight, members), _members(linear.bias, members), norm_params, p, training)


def hidden_block(x: Tensor, weight: Tensor, bias: Tensor, norm: tuple[Tensor, Tensor, float] | None, p: float,
                 training: bool, of_rows: int | None = None) -> Tensor:
    """:func:`linear_dropout_norm_relu` on given tensors (``norm``: ``(weight, bias, eps)`` or ``None``);
    ``of_rows``: ``x`` ``[E, N, in]`` holds the first ``N`` rows of an ``of_rows``-row batch, whose
    dropout masks are drawn (see :func:`_dropout_mask`): each row's output is what it is in the whole."""
    h = batched_linear(x, weight, bias)
    if training and p > 0.0:
        h.mul_(_dropout_mask(h, p, of_rows))  # h is the matmul's fresh output: BaddbmmBackward does not keep it
    if norm is not None:
        nw, nb, eps = norm
        if h.dim() == 3 and h.shape[0] == nw.shape[0]:  # (no views: see batched_linear)
            h = _affine(F.layer_norm(h, h.shape[-1:], eps=eps), nw, nb)
        else:
            flat = h.reshape(nw.shape[0], -1, h.shape[-1])
            h = _affine(F.layer_norm(flat, flat.shape[-1:], eps=eps), nw, nb).reshape(h.shape)
    return h.relu_()


class BatchedMLP(nn.Module):
    """``E`` MLPs as one: ``cat(inputs, -1)`` ``[E, *B, in]`` -> ``[E, *B, *out_shape]``.

    Args:
        members: ``E``.
        in_features: the width of the concatenated inputs.
        out_shape: trailing output shape, e.g. ``(num_actions, k)``.
        num_cells: hidden widths.
        activation: the hidden activation class (e.g. ``nn.ReLU``, ``nn.Tanh``).
        init: ``"torch"`` (default, ``nn.Linear``'s) or ``"orthogonal"``; see the module.
        gain: the orthogonal gain of the hidden layers; ``out_gain``: the output layer's (default: ``gain``).

    ``member_state(e)`` / ``load_member_state(e, state)`` copy one member's parameters out and in.

    Example:
        >>> net = BatchedMLP(4, 6, (3, 2), num_cells=(8, 8))
        >>> net(torch.randn(4, 5, 6)).shape, net(torch.randn(4 * 5, 6)).shape
        (torch.Size([4, 5, 3, 2]), torch.Size([20, 3, 2]))
        >>> ppo = BatchedMLP(2, 4, 1, num_cells=(8,), activation=nn.Tanh, init="orthogonal", gain=2 ** 0.5,
        ...                  out_gain=0.01)
        >>> ppo.member_state(1)["mlp.0.weight"].shape
        torch.Size([4, 8])
    """

    def __init__(self, members: int, in_features: int, out_shape: int | Sequence[int], *,
                 num_cells: Sequence[int] = (256, 256), activation: type[nn.Module] = nn.ReLU, init: str = "torch",
                 gain: float = 1.0, out_gain: float | None = None) -> None:
        super().__init__()
        if isinstance(members, bool) or not isinstance(members, int) or members < 1:
            raise ValueError(f"members must be a positive int, got {members!r}")
        self.members = members
        self.out_shape = (int(out_shape),) if isinstance(out_shape, int) else tuple(int(s) for s in out_shape)
        layers: list[nn.Module] = []
        width = int(in_features)
        for cells in num_cells:
            layers += [BatchedLinear(members, width, cells, init=init, gain=gain), activation()]
            width = cells
        layers.append(BatchedLinear(members, width, math.prod(self.out_shape), init=init,
                                    gain=gain if out_gain is None else out_gain))
        self.mlp = nn.Sequential(*layers)

    @property
    def population(self) -> int:
        """``E`` (the name the population losses use)."""
        return self.members

    def forward(self, first: Tensor, *rest: Tensor) -> Tensor:
        x = torch.cat([first, *rest], dim=-1) if rest else first
        x = self.mlp(x.to(self.mlp[0].weight.dtype))
        return x.reshape(*x.shape[:-1], *self.out_shape)

    def member_state(self, e: int) -> dict[str, Tensor]:
        """A copy of member ``e``'s parameters (name -> tensor without the member dim)."""
        return {name: t[e].detach().clone() for name, t in self.named_parameters()}

    def load_member_state(self, e: int, state: dict[str, Tensor]) -> None:
        """Overwrite member ``e``'s parameters with ``state`` (from :meth:`member_state`)."""
        with torch.no_grad():
            for name, t in self.named_parameters():
                t[e].copy_(state[name])
