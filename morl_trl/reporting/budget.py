"""Which budget a NHGR was measured at, written beside it: a run's report never puts an 8-weight,
60k-frame run beside the paper's 100-weight, 3M-frame values without saying so.

:func:`budget_label` names a column by its budget, :func:`same_budget` says whether a run's numbers may share a
table and a chart with the paper's (the same evaluation weights and at least the paper's frames).

Example:
    >>> count_label(60_032), count_label(3_000_000), count_label(2_000)
    ('60,032', '3M', '2k')
    >>> budget_label("Envelope", "paper", frames=3_000_000, weights=100)
    'Envelope (paper, 100 weights, 3M frames)'
    >>> same_budget("MOLunarLanderDR-v0", frames=60_032, weights=8)
    False
"""

from __future__ import annotations

from morl_trl.reporting.paper import paper_budget

__all__ = ["budget_label", "count_label", "same_budget"]


def count_label(n: int) -> str:
    """A frame count as people write it: ``3M``, ``60k`` when round, else with thousands commas."""
    n = int(n)
    if n >= 1_000_000 and n % 100_000 == 0:
        return f"{n / 1_000_000:g}M"
    if n >= 1_000 and n % 1_000 == 0:
        return f"{n // 1_000}k"
    return f"{n:,}"


def budget_label(name: str, who: str, *, frames: int | None = None, weights: int | None = None) -> str:
    """``"<name> (<who>, <weights> weights, <frames> frames)"``, leaving out what is ``None``."""
    parts = [who]
    if weights is not None:
        parts.append(f"{weights} weights")
    if frames is not None:
        parts.append(f"{count_label(frames)} frames")
    return f"{name} ({', '.join(parts)})"


def same_budget(domain: str, *, frames: int, weights: int) -> bool:
    """Whether a run of ``frames`` frames evaluated at ``weights`` weights on ``domain`` was
    measured at the paper's budget (its number of weights, and at least 99 % of its frames)."""
    budget = paper_budget(domain)
    return budget is not None and weights == budget[1] and frames >= 0.99 * budget[0]
