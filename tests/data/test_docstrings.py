"""The examples in the data modules' docstrings run and print what they say."""

import doctest
import importlib

import pytest


@pytest.mark.parametrize("name", ["prioritized", "segment_tree"])
def test_docstring_examples(name):
    module = importlib.import_module(f"morl_trl.data.{name}")
    assert doctest.testmod(module, optionflags=doctest.ELLIPSIS).failed == 0
