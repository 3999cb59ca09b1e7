"""Collection rules that let ``python -m pytest`` pass on an install without the optional
simulator extras (``box2d``, ``mujoco``, ``mario``, ``dmc``).

``--doctest-modules`` imports every module of the package. A module that cannot be imported
because its simulator is missing is not collected (``pytest_ignore_collect``), and a doctest
elsewhere whose examples name such a domain (e.g. ``make_env("MOHopperDR-v5")``) is skipped
with the extra it needs. Test files skip themselves (``pytest.importorskip``).
"""

from __future__ import annotations

import importlib
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent

# extra -> (the modules it installs, the package folder whose modules may import them, the
# words that name its domains in a doctest example)
EXTRAS = {
    "box2d": (("Box2D",), "morl_trl/envs/lunar_lander", ("LunarLander",)),
    "mujoco": (("mujoco",), "morl_trl/envs/mujoco", ("Hopper", "HalfCheetah", "Humanoid")),
    "mario": (("nes_py", "gym_super_mario_bros"), "morl_trl/envs/mario", ("SuperMario",)),
    "dmc": (("dm_control", "mujoco"), "morl_trl/envs/dmc", ("DMC", "suite_model")),
}


def _installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


MISSING = {extra: spec for extra, spec in EXTRAS.items() if not all(_installed(m) for m in spec[0])}


def _needs_missing_simulator(path: Path, modules: tuple[str, ...]) -> bool:
    """Whether importing the package module at ``path`` fails for want of ``modules``."""
    name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
    if name.endswith(".__init__"):
        name = name[: -len(".__init__")]
    try:
        importlib.import_module(name)
    except ImportError as err:
        return (err.name or "").split(".")[0] in modules
    return False


def pytest_ignore_collect(collection_path: Path, config):
    if collection_path.suffix != ".py":
        return None
    path = Path(collection_path).resolve()
    for modules, folder, _ in MISSING.values():
        if ROOT / folder in path.parents and _needs_missing_simulator(path, modules):
            return True
    return None


def pytest_collection_modifyitems(config, items):
    if not MISSING:
        return
    for item in items:
        dtest = getattr(item, "dtest", None)  # a doctest
        if dtest is None:
            continue
        source = "".join(example.source for example in dtest.examples)
        for extra, (_, _, words) in MISSING.items():
            if any(word in source for word in words):  # (conservative: any example naming the domain)
                item.add_marker(pytest.mark.skip(reason=f"needs the {extra!r} extra (pip install 'morl-trl[{extra}]')"))
                break
