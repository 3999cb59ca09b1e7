"""benchmarks/profile_update.py: the per-operation breakdown of one update runs and names the products."""

from __future__ import annotations

import re

from tests.benchmarks._helpers import load_benchmark


def _module():
    return load_benchmark("profile_update")


def test_breakdown_of_a_capql_update(capsys):
    assert _module().main(["capql", "--updates", "1", "--filled", "512", "--top", "40"]) == 0
    out = capsys.readouterr().out
    head = re.match(r"capql: ([\d.]+) ms per update .*; (\d+) tensor operations per update; matrix products "
                    r"([\d.]+) ms = (\d+)% of the update", out)
    assert head, out
    assert float(head.group(1)) > 0 and int(head.group(2)) > 100 and 0 < int(head.group(4)) <= 100
    # one addmm per layer of every forward (5 layers: actor on s', two target critics, two critics, actor on s,
    # two critics at its actions = 8 networks) and 37 backward products: the 77 of bench_losses' FLOP count
    assert re.search(r"\s40\.0 x  aten\.addmm\.default", out), out
    assert re.search(r"\s37\.0 x  aten\.mm\.default", out), out
