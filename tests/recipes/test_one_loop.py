"""Each algorithm's loop and update are written once (issue 46): the code a reader sees is the code the
CLI, the benchmarks, the GPU tests and a captured (compiled / CUDA-graphed) run execute."""

import ast
import inspect
from pathlib import Path

import pytest

from morl_trl.algorithms.registry import REGISTRY

PACKAGE = Path(__file__).resolve().parents[2] / "morl_trl"
#: methods that would be a second copy of an algorithm's learning, next to its recipe module's functions
LOOP_METHODS = {"learn", "update", "run_updates", "delayed_actor_step", "gradient_step", "on_batch", "before_batch",
                "after_step", "frames_of", "next_is_actor_turn"}


def _trees():
    for path in sorted(PACKAGE.rglob("*.py")):
        yield path, ast.parse(path.read_text(), filename=str(path))


def test_the_registry_has_every_configured_algorithm_once():
    from morl_trl.recipes.config import ALGORITHMS

    assert tuple(REGISTRY) == ALGORITHMS


def test_no_agent_class_carries_a_copy_of_the_loop_or_the_update():
    found = []
    for path, tree in _trees():
        for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
            bases = {getattr(b, "id", getattr(b, "attr", "")) for b in cls.bases}
            if cls.name == "Agent" or any(b.endswith("Agent") for b in bases):
                found += [f"{path.name}:{cls.name}.{f.name}" for f in cls.body
                          if isinstance(f, ast.FunctionDef) and f.name in LOOP_METHODS]
    assert found == []


@pytest.mark.parametrize("name", list(REGISTRY))
def test_the_loop_calls_its_modules_one_on_batch_which_calls_its_one_update(name):
    entry = REGISTRY[name]
    train = getattr(entry.train, "func", entry.train)  # (the actor-critics' loop is bound to a builder)
    module = inspect.getmodule(train)
    assert inspect.getmodule(entry.on_batch) is module  # the per-batch step lives with the loop
    tree = ast.parse(inspect.getsource(module))
    top = [n.name for n in tree.body if isinstance(n, ast.FunctionDef)]
    assert top.count("update") == 1 and top.count("on_batch") == 1, top
    nested = [n.name for f in tree.body if isinstance(f, ast.FunctionDef) for n in ast.walk(f)
              if isinstance(n, ast.FunctionDef) and n is not f]
    assert not {"update", "on_batch", "gradient_step"} & set(nested), nested  # (no inline copy in the loop)
    calls = {n.func.id for n in ast.walk(ast.parse(inspect.getsource(train)))
             if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
    assert "on_batch" in calls
    on_batch_calls = {n.func.id for n in ast.walk(ast.parse(inspect.getsource(entry.on_batch)))
                      if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
    # the updates: update itself, or (MORL/D) the schedule's helper that calls it
    assert on_batch_calls & {"update", "updates_at"}, on_batch_calls


def test_capture_wraps_the_recipes_own_gradient_step():
    """``compile`` / CUDA graphs capture the recipe's ``gradient_step`` (what the eager update calls), never a
    second copy: the capture module has no loss or optimizer call of its own."""
    from morl_trl.algorithms.actor_critic import recipe as actor_critic
    from morl_trl.training import capture
    from morl_trl.algorithms.envelope import recipe as envelope

    source = inspect.getsource(capture)
    assert "optimizer_step(" not in source and "qvalue_loss(" not in source and ".loss(" not in source
    for recipe in (envelope, actor_critic):
        update = inspect.getsource(recipe.update)
        assert "captured_update(agent, gradient_step)" in update and "gradient_step(agent, batch" in update


def test_a_non_finite_update_carries_the_updates_of_its_batch_applied_before_it():
    """The loops count a batch's updates with ``counted_update``: the error of the third says two were applied."""
    from morl_trl.training.agent import NonFiniteLossError, counted_update

    applied = []
    with pytest.raises(NonFiniteLossError) as info:
        for done in range(4):
            with counted_update(done):
                if done == 2:
                    raise NonFiniteLossError("non-finite loss")
                applied.append(done)
    assert info.value.updates_done == 2 and applied == [0, 1]
