"""The examples in the objectives' docstrings run and print what they say."""

import doctest
import importlib

import pytest

MODULES = ["capql", "common", "envelope", "mosac", "networks", "value", "gpi", "ensemble", "dynamics"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(f"morl_trl.objectives.{name}")
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0
