"""Distances of a front to a true Pareto front: the inverted generational distance (IGD)."""

from __future__ import annotations

import numpy as np

from morl_trl.metrics._arrays import as_points

__all__ = ["igd"]


def igd(front, true_front) -> float:
    """Inverted generational distance: the mean, over the points of ``true_front`` ``[m, k]``, of the Euclidean
    distance to the nearest point of ``front`` ``[n, k]`` (lower is better; 0 when ``front`` holds every true
    point). The definition of pymoo's ``IGD``, which MORL-Baselines reports.

    Example:
        >>> igd([[1.0, 0.0]], [[1.0, 0.0], [0.0, 1.0]])   # (0 + sqrt(2)) / 2
        0.7071067811865476
    """
    true = as_points(true_front, "true_front")
    pts = as_points(front, "front", dim=true.shape[1])
    dist = np.linalg.norm(true[:, None, :] - pts[None, :, :], axis=-1)
    return float(dist.min(axis=1).mean())
