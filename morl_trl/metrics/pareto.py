"""Pareto filtering (maximization)."""

from __future__ import annotations

import moocore
import numpy as np
import torch

from morl_trl.metrics._arrays import as_points

__all__ = ["pareto_front", "is_nondominated"]


def is_nondominated(points) -> np.ndarray:
    """Boolean mask ``[n]``: True for the first copy of every non-dominated point (maximization)."""
    arr = as_points(points)
    return moocore.is_nondominated(arr, maximise=True, keep_weakly=False)


def pareto_front(points):
    """The non-dominated, de-duplicated subset of ``points`` ``[n, k]``, in input order.

    Returns the same kind of array it was given (a torch tensor keeps its dtype and device).

    Example:
        >>> import numpy as np
        >>> pareto_front(np.array([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5], [0.2, 0.2], [1.0, 0.0]]))
        array([[1. , 0. ],
               [0. , 1. ],
               [0.5, 0.5]])
    """
    mask = is_nondominated(points)
    if isinstance(points, torch.Tensor):
        return points[torch.as_tensor(mask, device=points.device)]
    return as_points(points)[mask]
