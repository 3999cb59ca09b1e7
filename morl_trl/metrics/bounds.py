"""Per-objective normalization bounds: the box fronts are clipped to and scaled from."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from morl_trl.metrics._arrays import as_points
from morl_trl.metrics.hypervolume import check_bounds

__all__ = ["Bounds"]


@dataclass(frozen=True)
class Bounds:
    """Per-objective normalization bounds ``lower < upper`` (each ``[k]``).

    Example:
        >>> b = Bounds.from_points([[0.0, 5.0], [2.0, 1.0]])
        >>> b.lower.tolist(), b.upper.tolist()
        ([0.0, 1.0], [2.0, 5.0])
    """

    lower: np.ndarray
    upper: np.ndarray

    def __post_init__(self) -> None:
        lo = np.asarray(self.lower, dtype=np.float64).reshape(-1)
        lo, hi = check_bounds(lo, self.upper, lo.shape[0])
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)

    @property
    def num_objectives(self) -> int:
        return int(self.lower.shape[0])

    @classmethod
    def from_points(cls, *point_sets) -> "Bounds":
        """Per-objective min and max over the union of point sets (the authors' construction)."""
        pts = np.concatenate([as_points(p) for p in point_sets], axis=0)
        return cls(pts.min(axis=0), pts.max(axis=0))

    @classmethod
    def from_json_entry(cls, entry: Mapping[str, Iterable[float]]) -> "Bounds":
        """From the published format ``{"0": [min, max], "1": [min, max], ...}``."""
        k = len(entry)
        try:
            pairs = [tuple(entry[str(i)]) for i in range(k)]
        except KeyError as e:
            raise ValueError(f"bounds entry {dict(entry)} lacks objective {e}; keys must be '0'..'{k - 1}'") from None
        return cls(np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs]))

    def to_json_entry(self) -> dict[str, list[float]]:
        return {str(i): [float(lo), float(hi)] for i, (lo, hi) in enumerate(zip(self.lower, self.upper))}
