"""benchmarks/bench_losses.py: the line that says which updates reach issue 31's 1.5x target."""

from __future__ import annotations

import itertools

from tests.benchmarks._helpers import load_benchmark


def _module():
    return load_benchmark("bench_losses", "bench_losses_under_test")


def test_target_line_splits_met_and_missed():
    line = _module().target_line({"Envelope": 3.15, "CAPQL": 1.07, "GPI-LS": 1.4999, "PCN": 1.5, "X": float("nan")})
    assert line == ("target 1.5x MORL-Baselines: met by Envelope 3.15x, PCN 1.50x; "
                    "not met: CAPQL 1.07x, GPI-LS 1.50x, X nanx")


def test_target_line_with_nothing_met_or_missed():
    m = _module()
    assert m.target_line({"A": 2.0}) == "target 1.5x MORL-Baselines: met by A 2.00x; not met: none"
    assert m.target_line({"A": 1.2}, target=2.0) == "target 2x MORL-Baselines: met by none; not met: A 1.20x"


def test_compare_records_the_eager_ratio_for_the_target_line(capsys):
    m = _module()
    m.FLOPS = False
    ticks = itertools.count()
    m.CLOCK = lambda: float(next(ticks))  # each clock read one second later: rate = n / 1 s
    ours = lambda: None  # noqa: E731
    peer = lambda: None  # noqa: E731
    m.compare("Fake", {"eager": ours}, peer, warmup=0, updates=3, rounds=1)
    assert m.RATIOS == {"Fake": 1.0}
    assert "Fake       eager              3.0        3.0     1.00x" in capsys.readouterr().out
    m.compare("NoPeer", {"eager": ours}, None, warmup=0, updates=3, rounds=1)
    assert "NoPeer" not in m.RATIOS


def test_matmul_rate_is_the_best_window():
    """The limit is the machine's best rate: a window slowed by a busy moment does not lower it."""
    m = _module()
    calls = [("mm", (2, 3), (3, 4), __import__("torch").float32)]  # 2 * 2 * 3 * 4 = 48 FLOP a pass
    # window 1: one pass in 4 s; window 2: one pass in 1 s; window 3: one pass in 2 s
    reads = iter([0.0, 4.0, 4.0, 4.0, 5.0, 5.0, 5.0, 7.0, 7.0])
    m.CLOCK = lambda: next(reads)
    assert m.matmul_rate(calls, "cpu", seconds=0.5, windows=3) == 48 / 1.0 / 1e9


def test_round_calls_stretch_a_fast_update_to_the_minimum_round():
    """A round runs at least MIN_ROUND_SECONDS, counted from the fastest step's last warm-up call, the same
    for ours and the peer; the warm-up itself is what is timed (no extra call)."""
    m = _module()
    reads = iter([0.0, 1.0, 1.0, 1.004, 2.0, 2.01])  # ours: two warm-up calls, the last 4 ms; the peer: 10 ms
    m.CLOCK = lambda: next(reads)
    calls = []
    seconds = [m.warm_up(lambda: calls.append("ours"), 2), m.warm_up(lambda: calls.append("peer"), 1)]
    assert calls == ["ours", "ours", "peer"]
    m.MIN_ROUND_SECONDS = 0.5
    assert m.round_calls(seconds, updates=20) == 125  # 0.5 s / 4 ms
    m.MIN_ROUND_SECONDS = 0.0
    assert m.round_calls(seconds, updates=20) == 20
    m.MIN_ROUND_SECONDS = 0.5
    assert m.round_calls([2.0], updates=20) == 20  # one call longer than the minimum round: --updates stands
    assert m.round_calls([m.warm_up(lambda: None, 0)], updates=20) == 20  # no warm-up, nothing timed
