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
    "reference-table": ("morl_trl.cli:reference_table_main", "reproduce the paper's NHGR table from the published fronts"),
}


def reference_table_main(argv: list[str] | None = None) -> int:
    """``morl-trl reference-table DATA_DIR``: the paper's NHGR table from the published fronts
    (:func:`morl_trl.reporting.table.reference_table`)."""
    import csv
    from pathlib import Path

    from morl_trl.reporting.table import format_table, reference_table

    parser = argparse.ArgumentParser(
        prog="morl-trl reference-table",
        description="Recompute the paper's NHGR table (mean ± pooled std, IQM, optimality gap) from published fronts.",
    )
    parser.add_argument("data_dir", help="reference folder with minmax_values/, specialist_fronts/, generalist_fronts/")
    parser.add_argument("--domain", action="append", help="restrict to this domain id (repeatable)")
    parser.add_argument("--ci", action="store_true", help="add stratified-bootstrap 95%% CIs of IQM and optimality gap")
    parser.add_argument("--reps", type=int, default=50_000, help="bootstrap replicates for --ci (default 50000)")
    parser.add_argument("--seed", type=int, default=0, help="bootstrap seed")
    parser.add_argument("--no-eugr", action="store_true", help="skip EUGR")
    parser.add_argument("--csv", type=Path, help="also write the rows to this CSV file")
    args = parser.parse_args(argv)
    try:
        rows = reference_table(
            args.data_dir, args.domain, eugr=not args.no_eugr, ci_reps=args.reps if args.ci else 0, seed=args.seed
        )
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    try:
        print(format_table(rows), flush=True)
    except BrokenPipeError:  # e.g. piped into `head`
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    if args.csv:
        dicts = [r.as_dict() for r in rows]
        keys = list(dict.fromkeys(k for d in dicts for k in d))
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        with args.csv.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=keys)
            w.writeheader()
            w.writerows(dicts)
    return 0


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
