"""The parity benchmark's verdicts, computed from the per-seed results, and its seed rule.

A case says something about learning only where the reference learns at its budget, so each
verdict first asks, per library, whether it learned (its final value above its frame-0 value),
then compares the two libraries' final values with an equivalence test, not CI overlap (two flat
runs "overlap"; five seeds rarely exclude a difference):

* **learns**: a one-sided paired t-test of ``final - frame 0`` over the seeds (the same seed's two
  evaluations), p < :data:`ALPHA` and a positive mean gain;
* **at parity**: Welch's two one-sided tests (TOST) on the difference of the final means, with the
  margin :data:`MARGIN_OF_GAIN` of the reference's mean gain (a tenth of what the reference
  learned), both p < :data:`ALPHA`;
* **better / worse**: Welch's two-sided t-test on the difference of the final means, p < :data:`ALPHA`;
* otherwise **inconclusive** (neither shown equal within the margin nor shown different).

Beside the verdict, each library's final values are read against the **floor of trivial policies** (the best of
the random policy and every constant action under the same evaluation, per seed): :func:`above_floor`, the same
paired test on ``final - floor``. Learning (above frame 0) is the issue's criterion for an informative case; the
floor says whether what was learned beats what a constant action or a random policy scores under this protocol
(on deep-sea-treasure "always down" reaches the first treasure, hypervolume 16.8; 16 random episodes reach ~180).

>>> verdict([0, 0, 0, 0, 0], [80, 84, 82, 81, 83], [0, 0, 0, 0, 0], [82, 80, 83, 81, 84])
'both learn, at parity'
>>> verdict([5, 5, 5], [5, 5.1, 4.9], [5, 5, 5], [5.1, 5, 4.9])
'neither learns at this budget'
"""

from __future__ import annotations

import math
from collections.abc import Sequence

ALPHA = 0.05
#: the equivalence margin, as a fraction of the reference's mean gain (final - frame 0)
MARGIN_OF_GAIN = 0.1
#: verdicts in which a case counts as evidence of learning (the others count for nothing)
INFORMATIVE = ("both learn, at parity", "both learn, ours better", "both learn, ours worse",
               "both learn, inconclusive", "only the reference learns", "only ours learns")

#: The seed rule, fixed before running and never used for tuning: round ``r`` of the benchmark runs
#: seeds ``100 * (r - 1)`` to ``100 * (r - 1) + 4``. Round 1 (issue 29) ran 0-4, round 2 (issue 48)
#: runs 100-104 (and 100-109 where a case asks for ten); results of every round are reported.
SEEDS_PER_ROUND = 5


def round_seeds(round_number: int, count: int = SEEDS_PER_ROUND) -> list[int]:
    """The seeds of a round of the benchmark.

    >>> round_seeds(1), round_seeds(2), round_seeds(2, 10)
    ([0, 1, 2, 3, 4], [100, 101, 102, 103, 104], [100, 101, 102, 103, 104, 105, 106, 107, 108, 109])
    """
    if round_number < 1 or count < 1 or count > 100:
        raise ValueError(f"round {round_number} with {count} seeds: rounds count from 1, with 1 to 100 seeds")
    return list(range(100 * (round_number - 1), 100 * (round_number - 1) + count))


def _mean_var(x: Sequence[float]) -> tuple[float, float, int]:
    n = len(x)
    m = sum(x) / n
    return m, (sum((v - m) ** 2 for v in x) / (n - 1) if n > 1 else 0.0), n


def gain_test(frame0: Sequence[float], final: Sequence[float]) -> tuple[float, float]:
    """``(mean gain, p)``: the mean of ``final - frame0`` over the seeds (each seed's two evaluations paired)
    and the one-sided paired t-test's p-value for a positive gain (0 or 1 where every seed gained the same).

    >>> gain_test([0.0, 0.0, 0.0], [0.5, 0.6, 0.55])[0], gain_test([1.0, 1.0], [1.0, 1.0])
    (0.55, (0.0, 1.0))
    """
    from scipy import stats

    if len(frame0) != len(final) or len(final) < 2:
        raise ValueError(f"learns() pairs each seed's frame-0 and final values: got {len(frame0)} and {len(final)} "
                         "(at least 2 seeds, as many of each)")
    gains = [b - a for a, b in zip(frame0, final)]
    mean, var, _ = _mean_var(gains)
    if var == 0.0:  # (every seed gained the same)
        return mean, 0.0 if mean > 0 else 1.0
    return mean, float(stats.ttest_1samp(gains, 0.0, alternative="greater").pvalue)


def learns(frame0: Sequence[float], final: Sequence[float]) -> bool:
    """Whether the runs learned: one-sided paired t-test of ``final - frame0`` (same seeds), p < ALPHA
    (:func:`gain_test`).

    >>> learns([0.0, 0.0, 0.0], [0.5, 0.6, 0.55]), learns([0.1, 0.2, 0.1], [0.1, 0.2, 0.1])
    (True, False)
    """
    mean, p = gain_test(frame0, final)
    return bool(mean > 0 and p < ALPHA)


def above_floor(final: Sequence[float], floor: Sequence[float]) -> tuple[bool, float, float]:
    """``(above, mean gain, p)``: whether the final values beat the trivial policies' floor at their seeds (one value
    per seed, same order): the one-sided paired t-test of ``final - floor`` (:func:`gain_test`), p < ALPHA.

    >>> above_floor([16.8] * 5, [16.8] * 5), above_floor([300.0, 310.0, 320.0], [178.0, 180.0, 177.0])[0]
    ((False, 0.0, 1.0), True)
    """
    mean, p = gain_test(floor, final)
    return bool(mean > 0 and p < ALPHA), mean, p


def floor_words(final: Sequence[float], floor: Sequence[float] | None) -> str:
    """:func:`above_floor` in words for the tables: ``"above the floor (+G, p P)"``, ``"not above the floor
    (G, p P)"``, or ``""`` without a floor (or fewer than 2 seeds).

    >>> floor_words([16.8] * 5, [178.5] * 5), floor_words([1.0], [0.0])
    ('not above the floor (-162, p 1)', '')
    """
    if floor is None or len(final) < 2:
        return ""
    above, mean, p = above_floor(final, floor)
    return f"{'above' if above else 'not above'} the floor ({mean:+.3g}, p {p:.2g})"


def learning(frame0: Sequence[float] | None, final: Sequence[float], higher_is_better: bool = True) -> str:
    """One library's learning on its own, in words: ``"learns (gain G, p P)"``, ``"does not learn (gain G, p P)"``,
    ``"no frame-0 evaluation"`` or ``"fewer than 2 seeds"``; the gain is final - frame 0, in the metric's
    direction. What the per-method table says of the reference: a case is informative only where it learns.

    >>> learning([0.0, 0.0, 0.0], [0.5, 0.6, 0.55]), learning(None, [1.0, 2.0])
    ('learns (gain 0.55, p 0.0014)', 'no frame-0 evaluation')
    """
    if frame0 is None:
        return "no frame-0 evaluation"
    if len(final) < 2:
        return "fewer than 2 seeds"
    sign = 1.0 if higher_is_better else -1.0
    mean, p = gain_test([sign * v for v in frame0], [sign * v for v in final])
    said = "learns" if mean > 0 and p < ALPHA else "does not learn"
    return f"{said} (gain {mean:.3g}, p {p:.2g})"


def welch(ours: Sequence[float], ref: Sequence[float]) -> tuple[float, float, float]:
    """``(difference of means ours - ref, its standard error, Welch-Satterthwaite degrees of freedom)``."""
    mo, vo, no = _mean_var(ours)
    mr, vr, nr = _mean_var(ref)
    se2 = vo / no + vr / nr
    if se2 == 0.0:
        return mo - mr, 0.0, math.inf
    df = se2 ** 2 / ((vo / no) ** 2 / max(no - 1, 1) + (vr / nr) ** 2 / max(nr - 1, 1))
    return mo - mr, math.sqrt(se2), df


def equivalent(ours: Sequence[float], ref: Sequence[float], margin: float) -> bool:
    """Welch's TOST: the difference of the means lies within ``(-margin, margin)``, both one-sided p < ALPHA.

    >>> equivalent([1.0, 1.1, 0.9], [1.0, 1.05, 0.95], margin=0.5), equivalent([1.0, 1.1, 0.9], [3.0, 3.1, 2.9], 0.5)
    (True, False)
    """
    from scipy import stats

    if margin <= 0:
        return False
    diff, se, df = welch(ours, ref)
    if se == 0.0:
        return bool(abs(diff) < margin)
    p_low = stats.t.sf((diff + margin) / se, df)  # H0: diff <= -margin
    p_high = stats.t.cdf((diff - margin) / se, df)  # H0: diff >= margin
    return bool(max(p_low, p_high) < ALPHA)


def different(ours: Sequence[float], ref: Sequence[float]) -> int:
    """Welch's two-sided t-test: ``1`` ours higher, ``-1`` lower (p < ALPHA), ``0`` no difference shown."""
    from scipy import stats

    diff, se, df = welch(ours, ref)
    if se == 0.0:
        return (diff > 0) - (diff < 0)
    p = 2 * stats.t.sf(abs(diff) / se, df)
    return ((diff > 0) - (diff < 0)) if p < ALPHA else 0


def verdict(ours_frame0: Sequence[float] | None, ours_final: Sequence[float], ref_frame0: Sequence[float] | None,
            ref_final: Sequence[float], higher_is_better: bool = True) -> str:
    """One case's verdict from each library's per-seed frame-0 and final values (see the module docstring).

    ``None`` for a library's frame-0 values: that library has no frame-0 evaluation, and whether it
    learned cannot be said. ``higher_is_better=False`` for a metric to minimise (IGD).
    """
    if ours_frame0 is None or ref_frame0 is None:
        return "no frame-0 evaluation"
    if min(len(ours_final), len(ref_final)) < 2:
        return "fewer than 2 seeds"
    sign = 1.0 if higher_is_better else -1.0
    o0, o1 = [sign * v for v in ours_frame0], [sign * v for v in ours_final]
    r0, r1 = [sign * v for v in ref_frame0], [sign * v for v in ref_final]
    ours_learns, ref_learns = learns(o0, o1), learns(r0, r1)
    if not ours_learns and not ref_learns:
        return "neither learns at this budget"
    if not ref_learns:
        return "only ours learns"
    if not ours_learns:
        return "only the reference learns"
    margin = MARGIN_OF_GAIN * (_mean_var(r1)[0] - _mean_var(r0)[0])
    if equivalent(o1, r1, margin):
        return "both learn, at parity"
    side = different(o1, r1)
    if side:
        return "both learn, ours better" if side > 0 else "both learn, ours worse"
    return "both learn, inconclusive"
