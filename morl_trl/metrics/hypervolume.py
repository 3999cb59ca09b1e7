"""Exact hypervolume (via ``moocore``), normalization to given bounds, normalized hypervolume."""

from __future__ import annotations

import moocore
import numpy as np

from morl_trl.metrics._arrays import as_points, as_vector

__all__ = ["hypervolume", "normalize", "normalized_hypervolume", "check_bounds"]


def hypervolume(points, ref_point, *, drop_unbounded: bool = False) -> float:
    """Exact hypervolume dominated by ``points`` ``[n, k]`` and bounded by ``ref_point`` ``[k]``.

    Maximization: the volume of the union of boxes ``[ref_point, p]``. Dominated and
    duplicate points add nothing. Exact in any number of objectives (``moocore``).

    Args:
        points: ``[n, k]`` (or a single ``[k]`` point); torch or numpy.
        ref_point: ``[k]`` (or a scalar for every objective).
        drop_unbounded: by default a point below ``ref_point`` in some objective is an error (the reference point
            must bound the set). With ``True`` such points are ignored, which is the convention of pymoo and of the
            paper's logged hypervolumes (an unreachable reference point then gives 0).

    Example:
        >>> hypervolume([[1.0, 2.0], [2.0, 1.0]], ref_point=[0.0, 0.0])
        3.0
    """
    pts = as_points(points)
    k = pts.shape[1]
    ref = as_vector(ref_point, "ref_point", k)
    below = pts < ref
    if below.any():
        if not drop_unbounded:
            row, col = (int(i) for i in np.argwhere(below)[0])
            raise ValueError(
                f"ref_point {ref.tolist()} does not bound the points: point {row} has objective {col} "
                f"= {pts[row, col]} < {ref[col]} (pass drop_unbounded=True to ignore such points)"
            )
        pts = pts[~below.any(axis=1)]
    # points on the boundary of the box add no volume; moocore wants them strictly inside
    pts = pts[(pts > ref).all(axis=1)]
    if len(pts) == 0:
        return 0.0
    return float(moocore.hypervolume(pts, ref=ref, maximise=True))


def check_bounds(lower, upper, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Validate per-objective bounds ``[k]``: finite and ``upper > lower`` everywhere."""
    lo = as_vector(lower, "lower", k)
    hi = as_vector(upper, "upper", k)
    bad = ~(hi > lo)
    if bad.any():
        i = int(np.argwhere(bad)[0, 0])
        raise ValueError(
            f"bounds of objective {i} are lower={lo[i]}, upper={hi[i]}; upper must be > lower"
        )
    return lo, hi


def normalize(points, lower, upper) -> np.ndarray:
    """Clip ``points`` ``[n, k]`` to ``[lower, upper]`` and scale each objective to ``[0, 1]``."""
    pts = as_points(points)
    lo, hi = check_bounds(lower, upper, pts.shape[1])
    return (np.clip(pts, lo, hi) - lo) / (hi - lo)


def normalized_hypervolume(points, lower, upper) -> float:
    """Hypervolume after clipping to ``[lower, upper]`` and scaling to the unit box, origin as reference.

    This is the paper's :math:`HV_{norm}` (§4): in ``[0, 1]`` for any input, and comparable across contexts whose
    returns live on different scales. Points at or below ``lower`` in some objective add nothing.

    Example:
        >>> normalized_hypervolume([[5.0, 10.0], [10.0, 5.0]], lower=[0.0, 0.0], upper=[10.0, 10.0])
        0.75
    """
    norm = normalize(points, lower, upper)
    return hypervolume(norm, np.zeros(norm.shape[1]))
