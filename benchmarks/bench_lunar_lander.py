"""Throughput of the batched MO-LunarLander against the raw single Gymnasium env.

Measures, in one run, sub-env steps per second of

* ``gymnasium.make("LunarLander-v3", enable_wind=True)``: one env, random actions
  (pre-drawn, so the peer pays nothing for sampling), reset when an episode ends;
* ``mo_gymnasium.make("mo-lunar-lander-v3", enable_wind=True)``: the same, vector reward;
* ``morl_trl.envs.make_env("MOLunarLanderDR-v0", num_envs=N)`` for N in 1, 16, 64: random
  actions from the action spec, ``env.step_and_maybe_reset`` (``step`` + ``step_mdp`` + a
  partial reset of the finished sub-envs, each with a fresh random context drawn by
  ``DomainRandomization``);

and prints each rate with its ratio to the Gymnasium env. Same physics on both sides: wind
and turbulence on, Box2D ``Step`` with 180/60 iterations, no exhaust particles.

    python benchmarks/bench_lunar_lander.py            # ~1 min
    python benchmarks/bench_lunar_lander.py --quick    # ~10 s
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
import torch


def _peer_rate(make, steps: int, seed: int = 0) -> float:
    env = make()
    actions = np.random.default_rng(seed).integers(0, 4, size=steps).tolist()
    env.reset(seed=seed)
    for a in actions[:50]:  # warm-up
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    start = time.perf_counter()
    for a in actions:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    return steps / (time.perf_counter() - start)


def _ours_rate(num_envs: int, steps: int, seed: int = 0) -> float:
    from morl_trl.envs import make_env

    env = make_env("MOLunarLanderDR-v0", num_envs=num_envs, seed=seed)
    torch.manual_seed(seed)
    spec = env.action_spec
    td = env.reset()
    for _ in range(20):  # warm-up
        td["action"] = spec.rand()
        _, td = env.step_and_maybe_reset(td)
    start = time.perf_counter()
    for _ in range(steps):
        td["action"] = spec.rand()
        # env.step + step_mdp + a partial reset of the finished sub-envs (new DR contexts)
        _, td = env.step_and_maybe_reset(td)
    return num_envs * steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps (a rough figure in ~10 s)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 16, 64])
    args = parser.parse_args()
    torch.set_num_threads(1)
    warnings.filterwarnings("ignore")
    peer_steps = 3_000 if args.quick else 20_000
    ours_steps = 500 if args.quick else 2_000  # per sub-env

    import gymnasium as gym

    rows = [("gymnasium LunarLander-v3 (1 env)", 1, _peer_rate(lambda: gym.make("LunarLander-v3", enable_wind=True), peer_steps))]
    try:
        import mo_gymnasium as mo_gym

        rows.append(("mo-gymnasium mo-lunar-lander-v3 (1 env)", 1,
                     _peer_rate(lambda: mo_gym.make("mo-lunar-lander-v3", enable_wind=True), peer_steps)))
    except ImportError:
        pass
    base = rows[0][2]
    for n in args.sizes:
        steps = max(ours_steps // max(n // 4, 1), 100) if n > 4 else ours_steps
        rows.append((f"morl_trl MOLunarLanderDR-v0 num_envs={n}", n, _ours_rate(n, steps)))

    print(f"\n{'environment':<44}{'sub-env steps/s':>16}{'vs gymnasium':>14}")
    print("-" * 74)
    for name, _, rate in rows:
        print(f"{name:<44}{rate:>16,.0f}{rate / base:>13.2f}x")
    print("\n(ratio >= 1.0 at num_envs=16 is the target; timings are sensitive to machine load)")


if __name__ == "__main__":
    main()
