"""What the benchmark scripts' tests share: loading a script of ``benchmarks/`` as a module."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def load_benchmark(name: str, module_name: str | None = None):
    """``benchmarks/<name>.py`` executed as a fresh module (the scripts are not a package)."""
    spec = importlib.util.spec_from_file_location(module_name or name, ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
