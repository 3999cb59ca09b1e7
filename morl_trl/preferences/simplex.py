"""The one check that weight vectors lie on the probability simplex."""

from __future__ import annotations

import numpy as np
import torch

__all__ = ["SIMPLEX_ATOL", "check_simplex", "format_values"]

#: How far a row's sum may be from 1 (and an entry below 0). float32 rounding of a
#: normalised k-vector is ~k * 6e-8, so 1e-4 leaves three orders of margin for any k a
#: front can have, while weights rounded by hand to 3 digits (0.333, 0.333, 0.333) are
#: refused instead of silently biasing every utility by 0.1%.
SIMPLEX_ATOL = 1e-4

_VALID = f"weights must lie on the simplex: finite, >= 0 and summing to 1 (within {SIMPLEX_ATOL:g})"


def format_values(values) -> str:
    """Values as a short list for error messages (float32 noise removed)."""
    values = torch.as_tensor(np.asarray(values) if not isinstance(values, torch.Tensor) else values)
    if values.is_floating_point():
        return str([float(f"{x:.6g}") for x in values.reshape(-1).tolist()])
    return str(values.reshape(-1).tolist())


def check_simplex(w, num_objectives: int | None = None, *, name: str = "preference"):
    """Check that every row of ``w`` ``[..., k]`` lies on the simplex; return ``w``.

    A row passes when its entries are finite and ``>= -SIMPLEX_ATOL`` and it sums to 1 within
    :data:`SIMPLEX_ATOL`. ``w`` may be a torch tensor (returned as is, integer tensors as
    float32) or a numpy array / nested list (returned as a float64 numpy array). Otherwise a
    ``ValueError`` names the first offending row, its index, the problem and what is valid.

    Args:
        w: the weights, ``[k]`` or ``[..., k]``.
        num_objectives: ``k``; the last dimension must equal it (any width when ``None``).
        name: what ``w`` is, for the message.

    Example:
        >>> check_simplex([[0.5, 0.5], [1.0, 0.0]], 2).tolist()
        [[0.5, 0.5], [1.0, 0.0]]
        >>> check_simplex(torch.tensor([[0.5, 0.5], [0.5, 0.6]]))
        Traceback (most recent call last):
        ...
        ValueError: preference row 1 = [0.5, 0.6] sums to 1.1; weights must lie on the simplex: finite, >= 0 and summing to 1 (within 0.0001)
    """
    is_torch = isinstance(w, torch.Tensor)
    if is_torch:
        t = w if w.is_floating_point() else w.to(torch.float32)
    else:
        try:
            arr = np.asarray(w, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be numbers [..., k] on the simplex, got {w!r}") from None
        t = torch.from_numpy(arr)
    k = num_objectives if num_objectives is not None else (t.shape[-1] if t.ndim else 0)
    if t.ndim == 0 or t.shape[-1] != k or k < 1:
        raise ValueError(
            f"{name} has shape {tuple(t.shape)}; expected [..., {k}] (one weight per objective): {format_values(t)}"
        )
    if t.numel() == 0:
        return t if is_torch else arr
    lead = t.shape[:-1]
    flat = t.reshape(-1, k)
    finite = torch.isfinite(flat).all(-1)
    neg = (flat < -SIMPLEX_ATOL).any(-1)
    sums = flat.sum(-1)
    off = (sums - 1).abs() > SIMPLEX_ATOL
    bad = ~finite | neg | off
    if bool(bad.any()):
        i = int(bad.nonzero()[0, 0])
        row = flat[i]
        where = f" row {_index(i, lead)}" if len(lead) else ""
        if not bool(finite[i]):
            problem = "is not finite"
        elif bool(neg[i]):
            problem = f"has a negative weight {float(row.min()):.6g}"
        else:
            problem = f"sums to {float(sums[i]):.6g}"
        n_bad = int(bad.sum())
        more = f" ({n_bad} of {flat.shape[0]} rows are off the simplex)" if n_bad > 1 else ""
        raise ValueError(f"{name}{where} = {format_values(row)} {problem}; {_VALID}{more}")
    return t if is_torch else arr


def _index(i: int, lead: torch.Size) -> str:
    if len(lead) == 1:
        return str(i)
    return str([int(j) for j in np.unravel_index(i, tuple(lead))])
