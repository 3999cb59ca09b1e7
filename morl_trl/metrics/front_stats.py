"""Shape statistics of a Pareto front: cardinality and PGMORL's sparsity."""

from __future__ import annotations

import numpy as np

from morl_trl.metrics.pareto import is_nondominated
from morl_trl.metrics._arrays import as_points

__all__ = ["cardinality", "sparsity"]


def cardinality(points) -> int:
    """Number of distinct non-dominated points.

    Example:
        >>> cardinality([[1.0, 0.0], [0.0, 1.0], [0.0, 1.0], [0.0, 0.5]])
        2
    """
    return int(is_nondominated(points).sum())


def sparsity(points) -> float:
    """PGMORL's sparsity of the Pareto front of ``points`` (Xu et al. 2020; SPEC §2).

    For each objective, sort the front's values and sum the squared gaps between neighbours;
    add over objectives and divide by ``|F| - 1``. Lower is denser. A one-point front has
    sparsity 0 (PGMORL's convention). Computed on the non-dominated, de-duplicated subset.

    Example:
        >>> sparsity([[0.0, 2.0], [1.0, 1.0], [2.0, 0.0]])
        2.0
    """
    pts = as_points(points)
    front = pts[is_nondominated(pts)]
    if len(front) < 2:
        return 0.0
    gaps = np.diff(np.sort(front, axis=0), axis=0)
    return float((gaps**2).sum() / (len(front) - 1))
