"""Which domain modules a loaded config may import: only those its caller trusts.

A run's ``config.json`` (and the config inside a policy export) may *name* the Python modules
that register its domains (``domain_modules``). Importing a module runs its code, and a run
folder someone shares can hold that code (``evil.py`` beside it, on ``sys.path`` when Python is
started in the folder that holds the run) or name any installed module. So loading a run or an
export (``load_policy``, ``export``, ``evaluate``, a resume) imports a module its config names
only when

* the caller opts in: ``trust_code=True`` (every module the config names) or
  ``trust_code=["pkg.module", ...]`` in Python, ``--trust-code pkg.module`` on the command line;
* or the module registers domains through an installed package's ``morl_trl.domains`` entry
  point (installing a package is already trusting it);
* or it is already imported in this process (importing it again runs nothing: e.g. morl_trl's
  own domains, or a module the user imported or gave with ``--domain-module``).

Anything else is refused, before any import, with :class:`UntrustedCodeError` naming the
module and the flag.

Example:
    >>> check_trusted(["morl_trl.envs"], False, source="config.json")  # imported already: importing runs nothing
    >>> try:
    ...     check_trusted(["shared_run.evil"], False, source="run/config.json")
    ... except UntrustedCodeError as err:
    ...     print(str(err)[:71])
    run/config.json names the domain module 'shared_run.evil': importing it
"""

from __future__ import annotations

import sys
from collections.abc import Iterable

__all__ = ["UntrustedCodeError", "check_trusted", "entry_point_modules"]


class UntrustedCodeError(ValueError):
    """A loaded config names a module the caller did not trust (nothing was imported)."""


def entry_point_modules() -> set[str]:
    """The modules installed packages register domains from (the ``morl_trl.domains`` entry points)."""
    from importlib.metadata import entry_points

    from morl_trl.envs.registry import ENTRY_POINT_GROUP

    return {ep.module for ep in entry_points(group=ENTRY_POINT_GROUP)}


def check_trusted(modules: Iterable[str] | None, trust_code: bool | Iterable[str] = False, *, source: str) -> None:
    """:class:`UntrustedCodeError` unless every module in ``modules`` (named by ``source``, e.g.
    ``"'runs/a/config.json'"``) may be imported: see the module docstring. Imports nothing."""
    if trust_code is True:
        return
    allowed = set() if not trust_code else {trust_code} if isinstance(trust_code, str) else set(trust_code)
    names = [modules] if isinstance(modules, str) else list(modules or ())
    refused = [m for m in names if m not in allowed and m not in sys.modules]
    if refused:
        refused = [m for m in refused if m not in entry_point_modules()]
    if refused:
        flags = " ".join(f"--trust-code {m}" for m in refused)
        raise UntrustedCodeError(
            f"{source} names the domain module {refused[0]!r}"
            + (f" (and {refused[1:]})" if len(refused) > 1 else "")
            + ": importing it would run its code, so it was not imported. If you trust where this run comes from, "
            f"pass {flags} (trust_code=True in Python), or install the package that registers its domains "
            f"(entry point 'morl_trl.domains')")
