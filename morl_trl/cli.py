"""The ``morl-trl`` command line.

Subcommands are small functions registered in ``COMMANDS``; each parses its own arguments so
that a subcommand's module is only imported when it runs.
"""

from __future__ import annotations

import argparse
import importlib
import sys

# name -> ("module:function", help). The function takes the remaining argv list.
COMMANDS: dict[str, tuple[str, str]] = {
    "train": ("morl_trl.trainers.cli:train_main", "train a generalist across contexts, evaluate it, report"),
    "evaluate": ("morl_trl.trainers.cli:evaluate_main", "re-evaluate a run's checkpoint on its evaluation suite"),
    "demo": ("morl_trl.demo:main", "build every domain, step it under random contexts, print vector returns"),
    "envs": ("morl_trl.demo:list_main", "list domains, their contexts and evaluation suites"),
    "reference-table": ("morl_trl.metrics.table:main", "reproduce the paper's NHGR table from the published fronts"),
}


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(prog="morl-trl", description=__doc__.splitlines()[0])
    parser.add_argument("command", choices=sorted(COMMANDS), help="; ".join(f"{k}: {v[1]}" for k, v in COMMANDS.items()))
    if not argv or argv[0] in ("-h", "--help"):
        parser.print_help()
        return 0
    if argv[0] not in COMMANDS:
        parser.error(f"unknown command {argv[0]!r}; valid: {sorted(COMMANDS)}")
    module, _, func = COMMANDS[argv[0]][0].partition(":")
    try:
        return int(getattr(importlib.import_module(module), func)(argv[1:]) or 0)
    except ValueError as err:  # bad input: say what is wrong and what is valid, no traceback
        print(f"morl-trl {argv[0]}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
