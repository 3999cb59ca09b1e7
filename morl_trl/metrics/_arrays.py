"""Input checking shared by the metrics: torch or numpy in, float64 numpy inside."""

from __future__ import annotations

import numpy as np
import torch

__all__ = ["as_points", "as_vector", "to_numpy"]


def to_numpy(x) -> np.ndarray:
    if isinstance(x, torch.Tensor):
        return x.detach().to("cpu", torch.float64).numpy()
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"expected a numeric array, got {type(x).__name__}: {e}") from None


def as_points(x, name: str = "points", *, dim: int | None = None, allow_empty: bool = False) -> np.ndarray:
    """A ``[n, k]`` float64 array of finite points (a single ``[k]`` point becomes ``[1, k]``).

    Raises ``ValueError`` for an empty set (unless ``allow_empty``), NaN/inf entries, a wrong
    number of dimensions, or ``k != dim`` when ``dim`` is given.
    """
    arr = to_numpy(x)
    if arr.ndim == 1 and arr.size and dim is not None and arr.shape[0] == dim:
        arr = arr[None]
    if arr.ndim != 2:
        raise ValueError(f"{name} must be a [n, k] array of n points with k objectives, got shape {arr.shape}")
    if arr.shape[0] == 0 and not allow_empty:
        raise ValueError(f"{name} is empty: at least one point is needed")
    if arr.shape[1] == 0:
        raise ValueError(f"{name} has 0 objectives (shape {arr.shape})")
    if dim is not None and arr.shape[1] != dim:
        raise ValueError(f"{name} has {arr.shape[1]} objectives, expected {dim} (shape {arr.shape})")
    bad = ~np.isfinite(arr)
    if bad.any():
        row, col = (int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"{name}[{row}, {col}] is {arr[row, col]}; every entry must be a finite number")
    return arr


def as_vector(x, name: str, dim: int) -> np.ndarray:
    """A finite ``[dim]`` float64 vector (a scalar is broadcast to ``[dim]``)."""
    arr = to_numpy(x)
    if arr.ndim == 0:
        arr = np.full(dim, float(arr))
    if arr.shape != (dim,):
        raise ValueError(f"{name} must have shape ({dim},) to match {dim} objectives, got {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        i = int(np.argwhere(bad)[0, 0])
        raise ValueError(f"{name}[{i}] is {arr[i]}; every entry must be a finite number")
    return arr
