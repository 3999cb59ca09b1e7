"""``morl-trl demo`` and ``morl-trl envs``: every domain built, stepped and listed."""

from __future__ import annotations

import argparse
import time

import torch

from morl_trl.envs import list_domains, make_env


def _available(spec) -> bool:
    try:
        spec.env_cls()
    except ImportError:
        return False
    return True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="morl-trl demo", description=__doc__)
    parser.add_argument("--num-envs", type=int, default=4)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    torch.manual_seed(args.seed)
    for spec in list_domains():
        if not _available(spec):
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


def list_main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(prog="morl-trl envs", description="List domains and evaluation suites.").parse_args(argv)
    for spec in list_domains():
        print(f"{spec.name}  train: {spec.train_id}  objectives: {list(spec.objective_names)}")
        print(f"    context ({spec.context_space.dim}): {', '.join(spec.context_space.names)}")
        print(f"    evaluation suite: {', '.join(spec.evaluation_ids)}")
        extra = [i for i in spec.contexts if i not in spec.evaluation_ids]
        if extra:
            print(f"    other fixed contexts: {', '.join(extra)}")
    return 0
