"""The ``morl-trl`` command line: every entry point of the package, in one place.

Each subcommand is a small function that parses its own arguments and imports what it needs
only when it runs (``morl-trl envs`` loads no simulator, no training code).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

__all__ = ["main", "COMMANDS"]


def _default_reference() -> str | None:
    """``$MORL_TRL_REFERENCE`` or ``../shared/reference`` when it holds the published data."""
    for cand in (os.environ.get("MORL_TRL_REFERENCE"), "../shared/reference"):
        if cand and (Path(cand) / "minmax_values").is_dir():
            return cand
    return None


# ---------------------------------------------------------------------- train / evaluate
def train_main(argv: list[str]) -> int:
    from morl_trl.recipes.config import ALGORITHMS

    p = argparse.ArgumentParser(
        prog="morl-trl train",
        description="Train a generalist under domain randomization, evaluate it on the evaluation suite, report.",
    )
    p.add_argument("algo", choices=ALGORITHMS, help="algorithm")
    p.add_argument("env_id", help="training env id, e.g. MOLunarLanderDR-v0 (morl-trl envs lists them)")
    p.add_argument("--frames", type=int, help="environment frames to train for")
    p.add_argument("--seed", type=int, help="one seed for contexts, preferences, networks and evaluation")
    p.add_argument("--device", help="cpu, cuda, ...")
    p.add_argument("--config", help="a .toml/.json file of config overrides")
    p.add_argument("--quick", action="store_true", help="a preset that finishes in a few CPU minutes")
    p.add_argument("--run-dir", help="where to write the run (default runs/<algo>_<env>_s<seed>_<time>)")
    p.add_argument("--reference", help="the published data (bounds, specialist fronts) for NHGR; "
                   "default $MORL_TRL_REFERENCE or ../shared/reference if present")
    p.add_argument("--logger", choices=("csv", "tensorboard", "wandb", "none"))
    p.add_argument("--resume", metavar="RUN_DIR",
                   help="continue a run from its newest intact checkpoint (damaged ones are skipped with a "
                   "warning); logs are first cut back to that checkpoint. algo, env id, --seed, --config and "
                   "--quick values must match the run's config.json (a difference is an error); --frames "
                   "(total frames: extend the run), --device, --logger and --no-progress may change. A run that "
                   "already reached its frames is left as it is")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the contents of a non-empty --run-dir (without it, a non-empty run dir is an error)")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--print-config", action="store_true", help="print the complete resolved config (grouped TOML) and exit")
    args = p.parse_args(argv)
    from morl_trl.recipes import resolve_config, train

    if args.resume:
        cfg = _resume_config(args)
        if args.print_config:
            print(cfg.to_toml())
            return 0
        return _run_training(lambda: train(cfg, resume=args.resume))
    reference = args.reference or _default_reference()
    cfg = resolve_config(
        args.algo, args.env_id, quick=args.quick, config_file=args.config, frames=args.frames, seed=args.seed,
        device=args.device, run_dir=args.run_dir, reference_dir=reference, logger=args.logger,
        progress=False if args.no_progress else None,
    )
    if args.print_config:
        print(cfg.to_toml())
        return 0
    return _run_training(lambda: train(cfg, overwrite=args.overwrite))


def _resume_config(args):
    """The run's config.json, checked against what the command line gives (see ``--resume``)."""
    from morl_trl.recipes.config import TrainConfig, load_config_file, quick_preset, resume_config

    run_dir = Path(args.resume)
    if args.overwrite:
        raise ValueError("--resume continues a run and --overwrite replaces it: choose one")
    if args.run_dir and Path(args.run_dir).resolve() != run_dir.resolve():
        raise ValueError(f"--run-dir {args.run_dir!r} and --resume {args.resume!r} name different directories")
    if not (run_dir / "config.json").is_file():
        raise ValueError(f"cannot resume: {str(run_dir)!r} has no config.json (not a run directory)")
    cfg = TrainConfig.load(run_dir / "config.json")
    from_file = load_config_file(args.config) if args.config else {}
    cfg = resume_config(cfg, {"algo": args.algo, "env_id": from_file.get("env_id", args.env_id)}, "the command line")
    if args.quick:
        cfg = resume_config(cfg, {k: v for k, v in quick_preset().items() if k != "frames"}, "the --quick preset")
    if from_file:
        cfg = resume_config(cfg, from_file, f"config file {args.config!r}")
    flags = dict(frames=args.frames, seed=args.seed, device=args.device, logger=args.logger,
                 reference_dir=args.reference, progress=False if args.no_progress else None)
    return resume_config(cfg, {k: v for k, v in flags.items() if v is not None}, "the command line")


def _run_training(run) -> int:
    from morl_trl.recipes import NonFiniteLossError
    from morl_trl.recipes.off_policy import EXIT_NON_FINITE_LOSS

    try:
        run()
    except NonFiniteLossError as err:  # the run stopped cleanly: its last good state is checkpointed
        print(f"morl-trl train: stopped: {err}", file=sys.stderr)
        return EXIT_NON_FINITE_LOSS
    return 0


def evaluate_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="morl-trl evaluate",
                                description="Re-evaluate a run's latest checkpoint on its evaluation suite.")
    p.add_argument("run_dir")
    p.add_argument("--reference", help="the published data for NHGR/EUGR (default as in train)")
    p.add_argument("--weights", type=int, help="number of evaluation weights (default: the run's)")
    args = p.parse_args(argv)
    from morl_trl.recipes import evaluate_run

    evaluate_run(args.run_dir, reference_dir=args.reference or _default_reference(), weights=args.weights)
    return 0


# ---------------------------------------------------------------------- envs / demo
def envs_main(argv: list[str]) -> int:
    argparse.ArgumentParser(prog="morl-trl envs", description="List domains and evaluation suites.").parse_args(argv)
    from morl_trl.envs import list_domains

    for spec in list_domains():
        print(f"{spec.name}  train: {spec.train_id}  objectives: {list(spec.objective_names)}")
        print(f"    context ({spec.context_space.dim}): {', '.join(spec.context_space.names)}")
        print(f"    evaluation suite: {', '.join(spec.evaluation_ids)}")
        extra = [i for i in spec.contexts if i not in spec.evaluation_ids]
        if extra:
            print(f"    other fixed contexts: {', '.join(extra)}")
    return 0


def demo_main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(
        prog="morl-trl demo", description="Build every domain, step it under random contexts, print vector returns.")
    parser.add_argument("--num-envs", type=int, default=4)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    import torch

    from morl_trl.envs import list_domains, make_env

    torch.manual_seed(args.seed)
    for spec in list_domains():
        try:
            spec.env_cls()
        except ImportError:
            print(f"{spec.train_id:34s} (skipped: its extra is not installed)")
            continue
        env = make_env(spec.train_id, num_envs=args.num_envs, seed=args.seed)
        t0 = time.perf_counter()
        td = env.rollout(args.steps, break_when_any_done=False)  # random policy
        dt = time.perf_counter() - t0
        ret = td["next", "reward"].sum(-2)  # undiscounted return of each sub-env's trajectory
        names = ", ".join(spec.objective_names)
        print(f"{spec.train_id:34s} {args.num_envs}x{args.steps} steps in {dt:5.2f}s  objectives [{names}]")
        for i in range(min(args.num_envs, 2)):
            ctx = ", ".join(f"{v:.2f}" for v in td["context"][i, 0].tolist()[:4])
            vals = ", ".join(f"{v:9.2f}" for v in ret[i].tolist())
            print(f"    sub-env {i}: context [{ctx}{', ...' if td['context'].shape[-1] > 4 else ''}]  return [{vals}]")
    return 0


# ---------------------------------------------------------------------- the paper's table
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


def floors_main(argv: list[str] | None = None) -> int:
    """``morl-trl floors --reference DIR [--write]``: the trivial policies' NHGR per domain and context
    (:mod:`morl_trl.reporting.floors`)."""
    from morl_trl.reporting.floors import floors_main as run

    return run(argv)


# name -> (function, help)
COMMANDS = {
    "train": (train_main, "train a generalist across contexts, evaluate it, report"),
    "evaluate": (evaluate_main, "re-evaluate a run's checkpoint on its evaluation suite"),
    "demo": (demo_main, "build every domain, step it under random contexts, print vector returns"),
    "envs": (envs_main, "list domains, their contexts and evaluation suites"),
    "reference-table": (reference_table_main, "reproduce the paper's NHGR table from the published fronts"),
    "floors": (floors_main, "NHGR of trivial policies (random, constant actions) per domain: the honest floors"),
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
    try:
        return int(COMMANDS[argv[0]][0](argv[1:]) or 0)
    except ValueError as err:  # bad input: say what is wrong and what is valid, no traceback
        print(f"morl-trl {argv[0]}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
