"""Throughput of the batched MO-LavaGrid against a MiniGrid env of the same size.

Measures, in one run, sub-env steps per second of

* the peer: ``gymnasium.make("MiniGrid-LavaGapS7-v0", size=13)`` from the ``minigrid`` package
  (a 13x13 MiniGrid lava world, the base the authors built MO-LavaGrid on), one env stepped
  through its Gymnasium API with pre-drawn random actions, reset when an episode ends;
* ours, ``morl_trl.envs.make_env(...)`` for N in 1, 1024, 16384 on ``--device``: random
  actions, ``env.step_and_maybe_reset`` (``step`` + ``step_mdp`` + a partial reset of the
  finished sub-envs), on

  - ``MOLavaGridRoom-v0`` (a fixed evaluation map),
  - ``MOLavaGridDR-v0`` (a new random map per sub-env at each of its resets, drawn by the
    env's ``ContextSampler`` on the CPU),
  - ``MOLavaGridRoom-v0, randomize=True`` (the same randomization drawn inside the env, on
    ``--device``);

and prints each rate with its ratio to the MiniGrid env (goal: >= 100x at the best N).

    python benchmarks/bench_lava_grid.py                   # ~1-2 min on 2 CPU cores
    python benchmarks/bench_lava_grid.py --quick           # ~20 s
    python benchmarks/bench_lava_grid.py --device cuda     # ours on a GPU, the peer on the CPU
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing


def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def _minigrid_rate(steps: int, seed: int = 0) -> float:
    import gymnasium as gym
    import minigrid  # noqa: F401  (registers the MiniGrid ids)

    env = gym.make("MiniGrid-LavaGapS7-v0", size=13)
    actions = np.random.default_rng(seed).integers(0, 3, size=steps).tolist()  # left, right, forward
    env.reset(seed=seed)
    for a in actions[:100]:  # warm-up
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    start = time.perf_counter()
    for a in actions:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    return steps / (time.perf_counter() - start)


def _ours_rate(env_id: str, num_envs: int, steps: int, device: torch.device, seed: int = 0, **kwargs) -> float:
    from morl_trl.envs import make_env

    env = make_env(env_id, num_envs=num_envs, device=device, seed=seed, **kwargs)
    gen = torch.Generator(device=device).manual_seed(seed)
    actions = torch.randint(0, 3, (steps + 10, num_envs), generator=gen, device=device)
    td = env.reset()
    for t in range(10):  # warm-up
        td["action"] = actions[t]
        _, td = env.step_and_maybe_reset(td)
    _sync(device)
    start = time.perf_counter()
    for t in range(10, steps + 10):
        td["action"] = actions[t]
        _, td = env.step_and_maybe_reset(td)
    _sync(device)
    return num_envs * steps / (time.perf_counter() - start)


def _kernel_rate(num_envs: int, steps: int, device: torch.device, seed: int = 0) -> float:
    """The env's own batched step alone (no TorchRL TensorDict plumbing, no resets)."""
    from morl_trl.envs import make_env

    env = make_env("MOLavaGridRoom-v0", num_envs=num_envs, device=device, seed=seed)
    gen = torch.Generator(device=device).manual_seed(seed)
    actions = torch.randint(0, 3, (steps, num_envs), generator=gen, device=device)
    env._step_subenvs(actions[0])
    _sync(device)
    start = time.perf_counter()
    for t in range(steps):
        env._step_subenvs(actions[t])
    _sync(device)
    return num_envs * steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps (a rough figure in ~20 s)")
    parser.add_argument("--device", default="cpu", help="device of our env (the MiniGrid peer runs on the CPU)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 1024, 16384])
    parser.add_argument("--threads", type=int, default=1,
                        help="torch CPU threads (1 by default: on a shared 2-core machine more threads contend)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    warnings.filterwarnings("ignore")
    device = torch.device(args.device)
    peer_steps = 5_000 if args.quick else 30_000
    # steps per call of env.step, per N: enough sub-env steps to dominate the timer resolution
    calls = {n: max(20, min(2_000, (100_000 if args.quick else 1_000_000) // n)) for n in args.sizes}

    peer = _minigrid_rate(peer_steps)
    print(f"device {device}, torch threads {torch.get_num_threads()}, torch {torch.__version__}")
    print(f"{'environment':<52} {'N':>6} {'steps/s':>12} {'x MiniGrid':>11}")
    print(f"{'minigrid MiniGrid-LavaGapS7-v0 size=13 (1 env, cpu)':<52} {1:>6} {peer:>12,.0f} {1.0:>11.1f}")
    best = 0.0
    variants = [
        ("MOLavaGridRoom-v0", {}, "MOLavaGridRoom-v0"),
        ("MOLavaGridDR-v0", {}, "MOLavaGridDR-v0 (DR transform)"),
        ("MOLavaGridRoom-v0", {"randomize": True}, "MOLavaGrid randomize=True (DR in the env)"),
    ]
    for env_id, kwargs, label in variants:
        for n in args.sizes:
            rate = _ours_rate(env_id, n, calls[n], device, **kwargs)
            best = max(best, rate)
            print(f"{label:<52} {n:>6} {rate:>12,.0f} {rate / peer:>11.1f}")
    for n in args.sizes:
        rate = _kernel_rate(n, calls[n], device)
        print(f"{'  env step kernel alone (no TensorDict, no resets)':<52} {n:>6} {rate:>12,.0f} {rate / peer:>11.1f}")
    print(f"best through TorchRL: {best:,.0f} steps/s = {best / peer:.0f}x MiniGrid (goal >= 100x)")


if __name__ == "__main__":
    main()
