"""Layers point down only (DESIGN.md): no module imports a package above its own.

Every ``import`` of ``morl_trl.<package>`` in the source, at module level or inside a
function, is checked against the packages that package may use.
"""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "morl_trl"

# package -> the morl_trl packages it may import (besides itself)
ALLOWED = {
    "preferences": set(),
    "metrics": {"preferences"},
    "data": {"metrics", "preferences"},  # (metrics: the Pareto mathematics, e.g. PCN's non-dominated episodes)
    "envs": set(),
    "transforms": {"envs", "preferences"},
    "gym": {"envs"},
    "objectives": {"preferences", "data"},
    "evaluation": {"envs", "transforms", "metrics", "preferences"},
    "reporting": {"envs", "metrics", "preferences", "evaluation"},
    "runs": {"envs", "metrics", "preferences", "evaluation", "reporting"},
    "recipes": {"envs", "transforms", "objectives", "data", "metrics", "preferences", "evaluation", "reporting",
                "runs"},
    "grid": {"envs", "transforms", "objectives", "data", "metrics", "preferences", "evaluation", "reporting", "runs",
             "recipes"},
}


def _imports(path: Path) -> set[str]:
    """The morl_trl sub-packages ``path`` imports."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names if node.module == "morl_trl"]
        for name in names:
            parts = name.split(".")
            if parts[0] == "morl_trl" and len(parts) > 1:
                found.add(parts[1])
    return found


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        if len(rel.parts) > 1:
            yield rel.parts[0], path


def test_every_package_is_placed_in_a_layer():
    packages = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert packages == set(ALLOWED), f"place {sorted(packages ^ set(ALLOWED))} in ALLOWED"


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_no_package_imports_a_higher_layer(package):
    bad = {}
    for pkg, path in _modules():
        if pkg != package:
            continue
        up = _imports(path) - ALLOWED[package] - {package}
        if up:
            bad[str(path.relative_to(PACKAGE.parent))] = sorted(up)
    assert not bad, f"{package} may import only {sorted(ALLOWED[package])}; found {bad}"
