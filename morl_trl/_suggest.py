""""Did you mean ...?" for a name that is not one of the valid ones (config keys, algorithms, env ids).

Close spellings come from :func:`difflib.get_close_matches`; names other libraries use for the same
thing (MORL-Baselines' ``learning_rate`` for our ``lr``) come from an alias table the caller gives.
Pure Python: the command line uses it before anything heavy is imported.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping

__all__ = ["close_names", "did_you_mean"]


def close_names(name: str, valid: Iterable[str], aliases: Mapping[str, str] | None = None, n: int = 3,
                cutoff: float = 0.75) -> list[str]:
    """The valid names ``name`` most likely meant: its alias (if valid) first, then close spellings.

    Example:
        >>> close_names("learning_rate", ["lr", "batch_size", "gamma"], {"learning_rate": "lr"})
        ['lr']
        >>> close_names("lerning_rat", ["lr", "batch_size", "gamma"], {"learning_rate": "lr"})
        ['lr']
        >>> close_names("envelop", ["envelope", "capql", "pcn"])
        ['envelope']
        >>> close_names("zzz", ["envelope", "capql"])
        []
    """
    valid = list(dict.fromkeys(valid))
    aliases = {a: t for a, t in (aliases or {}).items() if t in valid}  # (another name of a valid one)
    exact = aliases.get(name.lower().replace("-", "_"))
    if exact:  # another library's name for one of ours: that one only
        return [exact]
    out = []
    for match in difflib.get_close_matches(name, [*valid, *aliases], n=n, cutoff=cutoff):
        match = aliases.get(match, match)
        if match not in out:
            out.append(match)
    return out[:n]


def did_you_mean(name: str, valid: Iterable[str], aliases: Mapping[str, str] | None = None,
                 cutoff: float = 0.75) -> str:
    """``" (did you mean 'lr'?)"``, or ``""`` when nothing is close.

    Example:
        >>> did_you_mean("learning_rate", ["lr"], {"learning_rate": "lr"})
        " (did you mean 'lr'?)"
        >>> did_you_mean("gpi", ["gpi_ls", "gpi_pd"], cutoff=0.6)
        " (did you mean 'gpi_pd' or 'gpi_ls'?)"
    """
    close = close_names(name, valid, aliases, cutoff=cutoff)
    if not close:
        return ""
    return " (did you mean " + " or ".join(repr(c) for c in close) + "?)"
