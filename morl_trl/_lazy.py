"""Module attributes imported on first use (PEP 562), so that importing a package stays light.

    >>> import types
    >>> m = types.ModuleType("demo")
    >>> m.__getattr__, m.__dir__ = lazy_attributes(m.__dict__, {"sqrt": "math", "tau": ("math", "tau")})
    >>> m.sqrt(4.0), round(m.tau, 3), "sqrt" in m.__dict__
    (2.0, 6.283, True)
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping


def lazy_attributes(namespace: dict, table: Mapping[str, str | tuple[str, str]]) -> tuple[Callable, Callable]:
    """``(__getattr__, __dir__)`` for a module whose ``namespace`` (its ``globals()``) gets each name of
    ``table`` on first use: ``name -> module`` (the attribute of that name) or ``name -> (module, attribute)``.
    A resolved name is stored in the namespace, so later reads are plain lookups."""
    owner = namespace.get("__name__", "module")

    def __getattr__(name: str):
        try:
            target = table[name]
        except KeyError:
            raise AttributeError(f"module {owner!r} has no attribute {name!r}") from None
        module, attr = (target, name) if isinstance(target, str) else target
        value = getattr(importlib.import_module(module), attr)
        namespace[name] = value
        return value

    def __dir__():
        return sorted([*namespace, *table])

    return __getattr__, __dir__
