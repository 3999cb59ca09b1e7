"""Aggregates of scores across runs and tasks, with rliable's definitions (Agarwal et al. 2021).

Scores come as a ``[runs, tasks]`` matrix (e.g. seeds × evaluation contexts of NHGR). The
point estimates pool every entry; the stratified bootstrap resamples runs independently
within each task, as ``rliable.library.get_interval_estimates`` does.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from morl_trl.metrics._arrays import to_numpy

__all__ = ["interquartile_mean", "iqm", "optimality_gap", "mean", "median", "stratified_bootstrap_ci"]


def _scores(scores) -> np.ndarray:
    arr = to_numpy(scores)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise ValueError(f"scores must be a [runs, tasks] matrix (or a [runs] vector), got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"scores are empty (shape {arr.shape})")
    if not np.isfinite(arr).all():
        raise ValueError("scores contain NaN or inf")
    return arr


def _trim_mean(flat: np.ndarray, proportion: float = 0.25) -> np.ndarray:
    """``scipy.stats.trim_mean`` along the last axis: drop ``int(p * n)`` from each end."""
    n = flat.shape[-1]
    cut = int(proportion * n)
    s = np.sort(flat, axis=-1)
    return s[..., cut : n - cut].mean(axis=-1)


def interquartile_mean(scores) -> float:
    """Interquartile mean of all entries: the mean of the middle 50% (25% trimmed from each end).

    Example:
        >>> interquartile_mean([[0.0, 1.0, 2.0, 3.0], [4.0, 5.0, 6.0, 100.0]])
        3.5
    """
    return float(_trim_mean(_scores(scores).ravel()))


iqm = interquartile_mean


def optimality_gap(scores, target: float = 1.0) -> float:
    """How far the scores fall short of ``target``: ``target - mean(min(scores, target))``.

    Example:
        >>> round(optimality_gap([[0.5, 1.2], [0.8, 0.9]]), 6)
        0.2
    """
    arr = _scores(scores)
    return float(target - np.minimum(arr, target).mean())


def mean(scores) -> float:
    """Mean of all entries."""
    return float(_scores(scores).mean())


def median(scores) -> float:
    """Median of all entries."""
    return float(np.median(_scores(scores)))


def _vectorized(name: str) -> Callable[[np.ndarray], np.ndarray]:
    # statistic over the last two axes of [..., runs, tasks]
    if name in ("iqm", "interquartile_mean"):
        return lambda a: _trim_mean(a.reshape(*a.shape[:-2], -1))
    if name == "optimality_gap":
        return lambda a: 1.0 - np.minimum(a, 1.0).reshape(*a.shape[:-2], -1).mean(-1)
    if name == "mean":
        return lambda a: a.reshape(*a.shape[:-2], -1).mean(-1)
    if name == "median":
        return lambda a: np.median(a.reshape(*a.shape[:-2], -1), axis=-1)
    raise ValueError(f"unknown statistic {name!r}; valid: 'iqm', 'optimality_gap', 'mean', 'median' or a callable")


def stratified_bootstrap_ci(scores, statistic: str | Callable[[np.ndarray], float] = "iqm", *, reps: int = 50_000,
                            confidence: float = 0.95, seed: int | None = 0) -> tuple[float, float, float]:
    """Point estimate and percentile confidence interval from a stratified bootstrap.

    Each bootstrap replicate resamples, for every task (column) independently, as many runs
    (rows) with replacement; the statistic is computed on each replicate and the interval is
    the ``[(1-c)/2, (1+c)/2]`` percentiles, as rliable's default ``percentile`` method.

    Args:
        scores: ``[runs, tasks]``.
        statistic: ``"iqm"``, ``"optimality_gap"``, ``"mean"``, ``"median"`` (vectorized), or
            any callable ``[runs, tasks] -> float``.
        reps: bootstrap replicates (the paper: 50,000).
        confidence: interval mass.
        seed: seed of the resampling.

    Returns:
        ``(estimate, low, high)``.

    Example:
        >>> est, lo, hi = stratified_bootstrap_ci([[0.2, 0.4], [0.6, 0.8], [0.5, 0.9]], "mean", reps=1000)
        >>> round(est, 3), lo <= est <= hi
        (0.567, True)
    """
    arr = _scores(scores)
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    if not isinstance(reps, int) or reps < 1:
        raise ValueError(f"reps must be a positive int, got {reps!r}")
    runs, tasks = arr.shape
    rng = np.random.default_rng(seed)
    if callable(statistic):
        estimate = float(statistic(arr))
        stats = []
        for _ in range(reps):
            idx = rng.integers(0, runs, size=(runs, tasks))
            stats.append(float(statistic(np.take_along_axis(arr, idx, axis=0))))
        stats = np.asarray(stats)
    else:
        fn = _vectorized(statistic)
        estimate = float(fn(arr[None])[0])
        stats = []
        chunk = max(1, 2_000_000 // arr.size)  # bound memory
        for start in range(0, reps, chunk):
            m = min(chunk, reps - start)
            idx = rng.integers(0, runs, size=(m, runs, tasks))
            stats.append(fn(np.take_along_axis(np.broadcast_to(arr, (m, runs, tasks)), idx, axis=1)))
        stats = np.concatenate(stats)
    alpha = (1 - confidence) / 2 * 100
    low, high = np.percentile(stats, [alpha, 100 - alpha])
    return estimate, float(low), float(high)
