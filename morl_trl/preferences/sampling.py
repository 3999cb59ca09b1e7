"""Drawing preference vectors on the simplex: Dirichlet(alpha), MORL-Baselines' "gaussian" and the
angle-cone sampler of the authors' CAPQL runs ("cone")."""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

__all__ = ["PREFERENCE_DISTRIBUTIONS", "CONE_ANGLE_DEGREES", "sample_preferences", "sample_cone_preferences"]

#: ``"dirichlet"``: Dirichlet(``alpha``), uniform on the simplex for ``alpha=1``.
#: ``"gaussian"``: ``|N(0, I)|`` normalised to sum one, MORL-Baselines'
#: ``random_weights(dist="gaussian")``, which the paper's Envelope runs used.
#: ``"cone"``: a weight within :data:`CONE_ANGLE_DEGREES` of the equal-weight direction
#: (:func:`sample_cone_preferences`), the authors' CAPQL acting preferences.
PREFERENCE_DISTRIBUTIONS = ("dirichlet", "gaussian", "cone")

#: Half-angle of the authors' CAPQL preference cone, in degrees.
CONE_ANGLE_DEGREES = 22.5



def _leading_shape(shape, num_objectives) -> tuple[int, ...]:
    """``shape`` as a tuple of ints; ``ValueError`` unless ``num_objectives`` is a positive int."""
    if isinstance(num_objectives, bool) or not isinstance(num_objectives, int) or num_objectives < 1:
        raise ValueError(f"num_objectives must be a positive int, got {num_objectives!r}")
    return (int(shape),) if isinstance(shape, int) else tuple(int(s) for s in shape)

def sample_cone_preferences(
    shape: Sequence[int] | int,
    num_objectives: int,
    *,
    angle: float = CONE_ANGLE_DEGREES,
    generator: torch.Generator | None = None,
    device: torch.device | str | None = None,
    dtype: torch.dtype = torch.float32,
    return_centre: bool = False,
) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
    r"""Draw ``[*shape, k]`` preferences within ``angle`` degrees of the equal-weight direction.

    The authors' CAPQL acting preferences (a new one every env step; their ``capql.py:70-100``,
    SPEC §6). Per row:

    1. the fixed centre :math:`c = \mathbf{1} / \sqrt{k}` (the equal-weight direction);
    2. an angle :math:`\theta \sim U[0, \text{angle}]` and :math:`v` a uniformly random unit vector
       orthogonal to :math:`c` (a standard Gaussian with its component along ``c`` removed,
       normalised); :math:`u = \cos\theta\, c + \sin\theta\, v`;
    3. :math:`w = \max(u, 0) / \sum_i \max(u_i, 0)` (L1 normalisation; the clip at 0 only acts
       when the cone leaves the orthant: never for 22.5 degrees and ``k <= 6``).

    Every draw has :math:`\angle(w, c) \le` ``angle``, :math:`w \ge 0` and :math:`\sum_i w_i = 1`;
    for 22.5 degrees the components stay in [0.293, 0.707] (``k = 2``) and [0.138, 0.529]
    (``k = 3``). With ``k = 1`` every draw is ``[1]``.

    Args:
        shape: leading (batch) shape.
        num_objectives: ``k``.
        angle: half-angle of the cone in degrees, in ``[0, 90]``. Defaults to 22.5.
        generator: a :class:`torch.Generator` on ``device``; the global RNG when ``None``.
        device: where the draws are made.
        dtype: of the output.
        return_centre: also return the unit centre direction ``c`` (expanded to ``[*shape, k]``).

    Example:
        >>> g = torch.Generator().manual_seed(0)
        >>> w = sample_cone_preferences(5, 2, generator=g)
        >>> bool((w >= 0.29).all() and (w <= 0.71).all()), bool(torch.allclose(w.sum(-1), torch.ones(5)))
        (True, True)
    """
    shape = _leading_shape(shape, num_objectives)
    if not 0.0 <= float(angle) <= 90.0:
        raise ValueError(f"angle must lie in [0, 90] degrees, got {angle!r}")
    if generator is not None and device is None:
        device = generator.device
    size = (*shape, num_objectives)
    f64 = torch.float64
    c = torch.full(size, 1.0 / math.sqrt(num_objectives), device=device, dtype=f64)
    theta = torch.rand((*shape, 1), generator=generator, device=device, dtype=f64) * math.radians(float(angle))
    v = torch.randn(size, generator=generator, device=device, dtype=f64)
    v = v - (v * c).sum(-1, keepdim=True) * c
    norm = v.norm(dim=-1, keepdim=True)
    v = torch.where(norm > 1e-12, v / norm.clamp_min(1e-12), torch.zeros_like(v))  # k = 1: no room
    u = (theta.cos() * c + theta.sin() * v).clamp_min(0.0)
    w = (u / u.sum(-1, keepdim=True)).to(dtype)
    return (w, c.to(dtype)) if return_centre else w


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


def _is_one(alpha) -> bool:
    """Whether ``alpha`` (a number or a tensor) is 1 everywhere; a number is checked without a
    tensor, so a captured (compiled / CUDA-graphed) update drawing preferences reads no device value."""
    if isinstance(alpha, (int, float)) and not isinstance(alpha, bool):
        return alpha == 1
    return bool((torch.as_tensor(alpha) == 1).all())


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

    ``distribution="cone"`` is :func:`sample_cone_preferences` with its default 22.5 degrees.

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
    shape = _leading_shape(shape, num_objectives)
    if distribution not in PREFERENCE_DISTRIBUTIONS:
        raise ValueError(f"distribution={distribution!r}; valid values are {PREFERENCE_DISTRIBUTIONS}")
    k = num_objectives
    if generator is not None and device is None:
        device = generator.device
    size = (*shape, k)
    if distribution == "cone":
        if not _is_one(alpha):
            raise ValueError(f"alpha={alpha!r} applies to distribution='dirichlet' only")
        return sample_cone_preferences(shape, k, generator=generator, device=device, dtype=dtype)
    if distribution == "gaussian":
        if not _is_one(alpha):
            raise ValueError(f"alpha={alpha!r} applies to distribution='dirichlet' only")
        x = torch.randn(size, generator=generator, device=device, dtype=torch.float64).abs()
        x = x.clamp_min(torch.finfo(x.dtype).tiny)  # an all-zero row (probability 0) stays defined
    elif isinstance(alpha, (int, float)) and not isinstance(alpha, bool) and alpha == 1:  # no tensor check
        x = torch.empty(size, dtype=torch.float64, device=device).exponential_(generator=generator)
    else:
        a = _alpha(alpha, k)
        if bool((a == 1).all()):
            x = torch.empty(size, dtype=torch.float64, device=device).exponential_(generator=generator)
        else:
            x = _standard_gamma(a.to(device=device).expand(size).clone(), generator)
    return (x / x.sum(-1, keepdim=True)).to(dtype)
