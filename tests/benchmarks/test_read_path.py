"""``benchmarks/read_path.py``: what a reader reads from ``morl-trl train`` to the loss (issue 46's bounds)."""

from __future__ import annotations

import ast
import inspect

import pytest

from tests.benchmarks._helpers import load_benchmark


def test_the_command_line_hands_the_opened_run_to_the_registrys_loop():
    """``train_main`` opens the run and calls the algorithm's loop itself (no wrapper in between)."""
    from morl_trl import cli

    source = inspect.getsource(cli.train_main)
    assert "with open_run(" in source and "algorithm(run.cfg.algo).train(run)" in source
    calls = {n.func.id for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
    assert "run_training" not in calls


def test_function_spans_count_a_decorated_function_from_its_decorator(tmp_path):
    read_path = load_benchmark("read_path")
    path = tmp_path / "m.py"
    path.write_text("import contextlib\n\n@contextlib.contextmanager\ndef f():\n    yield\n\ndef g():\n    pass\n")
    spans = read_path._function_spans(path)
    assert spans[3] == spans[4] == (3, 5) and spans[7] == (7, 8)


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["envelope", "capql"])
def test_reading_an_algorithm_from_the_cli_to_its_loss_stays_within_issue_46s_bounds(algo):
    """<= 4 calls from ``main`` to ``update``, <= 6 package files and <= 700 lines (the rule in read_path.py)."""
    read_path = load_benchmark("read_path")
    env_id, overrides = read_path.CASES[algo]
    result = read_path.read_path(algo, env_id, overrides)
    assert result["chain"][0] == "main" and result["chain"][-1] == "update"
    assert result["calls"] <= 4 and len(result["files"]) <= 6 and result["lines"] <= 700, result
