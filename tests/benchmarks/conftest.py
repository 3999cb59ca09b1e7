"""Fixtures of the parity benchmark's tests: its scripts, loaded from ``benchmarks/parity`` (not a package) with
that folder on ``sys.path`` (they import ``common`` and ``verdict`` by name), and unloaded afterwards."""

import importlib.util
import sys
from pathlib import Path

import pytest

PARITY = Path(__file__).resolve().parents[2] / "benchmarks" / "parity"


def _load_parity_script(monkeypatch, name: str):
    monkeypatch.syspath_prepend(str(PARITY))
    spec = importlib.util.spec_from_file_location(name, PARITY / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def parity(monkeypatch):
    """``benchmarks/parity/run_parity.py`` as a module."""
    yield _load_parity_script(monkeypatch, "run_parity")
    sys.modules.pop("common", None)
    sys.modules.pop("mb_runner", None)


@pytest.fixture
def mb_runner(monkeypatch):
    """``benchmarks/parity/mb_runner.py`` as a module (its MB imports are lazy: no MORL-Baselines needed to load it)."""
    yield _load_parity_script(monkeypatch, "mb_runner")
    sys.modules.pop("common", None)
