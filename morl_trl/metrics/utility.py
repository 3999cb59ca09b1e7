"""Expected utility (SER, linear utility) of a front over a set of preference weights."""

from __future__ import annotations

from morl_trl.metrics._arrays import as_points
from morl_trl.preferences import check_simplex

__all__ = ["eum"]


def eum(front, weights) -> float:
    """Expected utility metric: ``mean_w max_{v in front} w·v`` (Zintgraf et al. 2015; paper App. D).

    Args:
        front: ``[n, k]`` value vectors (dominated points do not change the result).
        weights: ``[m, k]`` preference weights on the simplex (:func:`morl_trl.preferences.check_simplex`), e.g.
            :func:`~morl_trl.preferences.energy_weights`.

    Example:
        >>> eum([[1.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [0.5, 0.5]])
        0.75
    """
    f = as_points(front, "front")
    w = check_simplex(as_points(weights, "weights", dim=f.shape[1]), f.shape[1], name="weights")
    return float((f @ w.T).max(axis=0).mean())
