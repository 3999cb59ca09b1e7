"""Argument types and checks of the ``morl-trl`` command line, in pure Python.

Everything here runs before torch, torchrl or any env is imported, so that ``--help`` and an
argument error answer at once (``benchmarks/bench_cli.py`` measures it).
"""

from __future__ import annotations

import argparse
import math
import re

__all__ = ["frame_count", "join_negative_values", "split_positionals", "check_algorithm"]

_SUFFIXES = {"k": 10**3, "m": 10**6, "g": 10**9}


def frame_count(text: str) -> int:
    """A number of frames as typed: ``100000``, ``100_000``, ``1e5``, ``100k``, ``3M``, ``1.5k``.

    Example:
        >>> [frame_count(t) for t in ("3000", "1e5", "100k", "3M", "1.5k", "2_000")]
        [3000, 100000, 100000, 3000000, 1500, 2000]
        >>> frame_count("-5")
        Traceback (most recent call last):
        ...
        argparse.ArgumentTypeError: '-5' is not a frame count: give a whole number >= 1, e.g. 3000, 1e5, 100k or 3M
    """
    raw = text.strip().replace("_", "").replace(",", "")
    scale = 1
    if raw[-1:].lower() in _SUFFIXES:
        raw, scale = raw[:-1], _SUFFIXES[raw[-1].lower()]
    try:
        value = float(raw) * scale
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value < 1 or not value.is_integer():
        raise argparse.ArgumentTypeError(f"{text!r} is not a frame count: give a whole number >= 1, e.g. 3000, 1e5, "
                                         f"100k or 3M")
    return int(value)


_NEGATIVE = re.compile(r"^-\.?\d")  # ("-1,-1", "-.5,2", "-1,x": the last refused by the option's own check)


def join_negative_values(argv: list[str], options: tuple[str, ...]) -> list[str]:
    """``["--ref-point", "-1,-1,-1"]`` -> ``["--ref-point=-1,-1,-1"]``: argparse takes a value
    that starts with ``-`` and is not one plain number for an option, so a negative list typed
    after its flag would be refused ("expected one argument").

    Example:
        >>> join_negative_values(["train", "--ref-point", "-1,-1,-1", "--frames", "10"], ("--ref-point",))
        ['train', '--ref-point=-1,-1,-1', '--frames', '10']
        >>> join_negative_values(["--ref-point", "--frames"], ("--ref-point",))
        ['--ref-point', '--frames']
    """
    out: list[str] = []
    i = 0
    while i < len(argv):
        arg = argv[i]
        if arg in options and i + 1 < len(argv) and _NEGATIVE.match(argv[i + 1]):
            out.append(f"{arg}={argv[i + 1]}")
            i += 2
            continue
        out.append(arg)
        i += 1
    return out


def split_positionals(values: list[str | None]) -> tuple[list[str], list[str]]:
    """The positional words of ``morl-trl train`` as (names, overrides): ``KEY=VALUE`` words are
    overrides wherever they stand (``morl-trl train --resume RUN frames=...`` has no algorithm
    or env id before them).

    Example:
        >>> split_positionals(["lr=1e-3", None, "hidden=[64]"])
        ([], ['lr=1e-3', 'hidden=[64]'])
        >>> split_positionals(["pcn", "fruit-tree-v0"])
        (['pcn', 'fruit-tree-v0'], [])
    """
    names = [v for v in values if v is not None and "=" not in v]
    overrides = [v for v in values if v is not None and "=" in v]
    return names, overrides


def check_algorithm(algo: str, valid: tuple[str, ...]) -> None:
    """``ValueError`` naming the algorithms (and the one most likely meant) when ``algo`` is none of them."""
    if algo not in valid:
        from morl_trl._suggest import did_you_mean

        raise ValueError(f"unknown algorithm {algo!r}{did_you_mean(algo, valid, cutoff=0.6)}; valid: "
                         f"{', '.join(valid)}")

