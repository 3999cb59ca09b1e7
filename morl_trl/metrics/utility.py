"""Expected utility (SER, linear utility) of a front over a set of preference weights."""

from __future__ import annotations

import numpy as np

from morl_trl.metrics._arrays import as_points

__all__ = ["eum", "check_weights"]

SIMPLEX_TOL = 1e-4


def check_weights(weights, k: int) -> np.ndarray:
    """Validate preference weights ``[m, k]``: finite, non-negative, each row summing to 1."""
    w = as_points(weights, "weights", dim=k)
    neg = w < 0
    if neg.any():
        row, col = (int(i) for i in np.argwhere(neg)[0])
        raise ValueError(f"weights[{row}] = {w[row].tolist()} has a negative entry; weights must lie on the simplex")
    off = np.abs(w.sum(axis=1) - 1.0) > SIMPLEX_TOL
    if off.any():
        row = int(np.argwhere(off)[0, 0])
        raise ValueError(
            f"weights[{row}] = {w[row].tolist()} sums to {w[row].sum()}; weights must lie on the simplex (sum 1)"
        )
    return w


def eum(front, weights) -> float:
    """Expected utility metric: ``mean_w max_{v in front} w·v`` (Zintgraf et al. 2015; paper App. D).

    Args:
        front: ``[n, k]`` value vectors (dominated points do not change the result).
        weights: ``[m, k]`` preference weights on the simplex, e.g.
            :func:`~morl_trl.metrics.energy_weights`.

    Example:
        >>> eum([[1.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [0.5, 0.5]])
        0.75
    """
    f = as_points(front, "front")
    w = check_weights(weights, f.shape[1])
    return float((f @ w.T).max(axis=0).mean())
