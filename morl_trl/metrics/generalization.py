"""Generalization ratios against an optimal (specialist) front: NHGR and EUGR (paper §4, App. D)."""

from __future__ import annotations

from morl_trl.metrics._arrays import as_points
from morl_trl.metrics.hypervolume import normalized_hypervolume
from morl_trl.metrics.utility import eum

__all__ = ["nhgr", "eugr"]


def nhgr(front, optimal_front, lower, upper) -> float:
    """Normalized Hypervolume Generalization Ratio of ``front`` in one context.

    ``min(HV_norm(front) / HV_norm(optimal_front), 1)``, both normalized with the same frozen bounds (clipping,
    origin reference). The cap handles a front that beats the (approximate) optimal one.

    Raises ``ValueError`` if the optimal front has zero normalized hypervolume (the ratio is
    undefined), besides the usual checks on the inputs.

    Example:
        >>> nhgr([[0.5, 0.5]], [[1.0, 0.5], [0.5, 1.0]], lower=[0, 0], upper=[1, 1])
        0.3333333333333333
    """
    f = as_points(front, "front")
    opt = as_points(optimal_front, "optimal_front", dim=f.shape[1])
    denom = normalized_hypervolume(opt, lower, upper)
    if denom <= 0:
        raise ValueError(
            "the optimal front has zero normalized hypervolume within the bounds "
            f"[{list(lower)}, {list(upper)}]; NHGR is undefined"
        )
    return min(normalized_hypervolume(f, lower, upper) / denom, 1.0)


def eugr(front, optimal_front, weights) -> float:
    """Expected Utility Generalization Ratio: ``clip(EUM(front) / EUM(optimal_front), 0, 1)``.

    Computed on unnormalized fronts, as in the paper. The ratio only means something when the
    optimal front's EUM is positive; otherwise this raises ``ValueError`` (normalize both
    fronts first, e.g. with :func:`~morl_trl.metrics.normalize`, to get a ratio anyway).

    Example:
        >>> eugr([[1.0, 0.0]], [[1.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [0.0, 1.0]])
        0.5
    """
    f = as_points(front, "front")
    opt = as_points(optimal_front, "optimal_front", dim=f.shape[1])
    denom = eum(opt, weights)
    if denom <= 0:
        raise ValueError(
            f"the optimal front's EUM is {denom} <= 0, so the EUGR ratio is meaningless; "
            "normalize both fronts to positive bounds first"
        )
    return min(max(eum(f, weights) / denom, 0.0), 1.0)
