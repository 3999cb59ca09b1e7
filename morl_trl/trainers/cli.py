"""``morl-trl train`` and ``morl-trl evaluate``."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from morl_trl.trainers.config import ALGORITHMS, resolve_config


def _default_reference() -> str | None:
    """``$MORL_TRL_REFERENCE`` or ``../shared/reference`` when it holds the published data."""
    for cand in (os.environ.get("MORL_TRL_REFERENCE"), "../shared/reference"):
        if cand and (Path(cand) / "minmax_values").is_dir():
            return cand
    return None


def train_main(argv: list[str] | None = None) -> int:
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
    p.add_argument("--resume", metavar="RUN_DIR", help="continue a killed run from its last checkpoint")
    p.add_argument("--no-progress", action="store_true")
    args = p.parse_args(argv)
    from morl_trl.trainers.loop import train

    if args.resume:
        train(None, resume=args.resume)
        return 0
    reference = args.reference or _default_reference()
    cfg = resolve_config(
        args.algo, args.env_id, quick=args.quick, config_file=args.config, frames=args.frames, seed=args.seed,
        device=args.device, run_dir=args.run_dir, reference_dir=reference, logger=args.logger,
        progress=False if args.no_progress else None,
    )
    train(cfg)
    return 0


def evaluate_main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="morl-trl evaluate",
                                description="Re-evaluate a run's latest checkpoint on its evaluation suite.")
    p.add_argument("run_dir")
    p.add_argument("--reference", help="the published data for NHGR/EUGR (default as in train)")
    p.add_argument("--weights", type=int, help="number of evaluation weights (default: the run's)")
    args = p.parse_args(argv)
    from morl_trl.trainers.loop import evaluate_run

    evaluate_run(args.run_dir, reference_dir=args.reference or _default_reference(), weights=args.weights)
    return 0
