"""Sub-env steps per second of the batched MuJoCo domains against a single Gymnasium env.

For each domain, in one run: ``make_env("MO<Domain>DR-v5", num_envs=N)`` stepped through
TorchRL's ``step_and_maybe_reset`` (what collectors call: partial resets included) for N in
1, 16, 64, and the raw Gymnasium env doing the same physics (``gym.make("<Domain>-v5")``
with its default wrappers, reset when an episode ends), both with uniform random actions
drawn beforehand. Each figure is the best of a few alternating repeats, which keeps the
ratio meaningful on a shared machine. Our envs are measured with their default thread
count (``auto``: ``min(N, usable CPUs)`` C++ threads step the sub-envs) and with one thread.
Target: ratio >= 1.0 at N=16 for every domain.

    python benchmarks/bench_mujoco.py            # ~1 minute
    python benchmarks/bench_mujoco.py --quick    # ~15 s, noisier
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from importlib import resources

import gymnasium as gym
import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from morl_trl.envs import make_env  # noqa: E402

DOMAINS = {
    # domain: (our DR id, Gymnasium id, Gymnasium kwargs giving the same physics and (but for the
    # healthy term on terminal steps) the same scalar reward as ours)
    "Hopper": ("MOHopperDR-v5", "Hopper-v5", {"xml_file": str(resources.files("morl_trl.envs.mujoco") / "assets" / "hopper.xml")}),
    "HalfCheetah": ("MOHalfCheetahDR-v5", "HalfCheetah-v5", {}),
    "Humanoid": ("MOHumanoidDR-v5", "Humanoid-v5", {"healthy_reward": 2.0, "contact_cost_weight": 0.0, "ctrl_cost_weight": 1e-3}),
}


def gym_steps_per_second(env_id: str, kwargs: dict, seconds: float, seed: int = 0) -> float:
    env = gym.make(env_id, **kwargs)
    env.reset(seed=seed)
    space = env.action_space
    actions = np.random.default_rng(seed).uniform(space.low, space.high, size=(4096, *space.shape)).astype(np.float32)
    steps, start = 0, time.perf_counter()
    while True:
        for a in actions[steps % len(actions):][:256]:
            _, _, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                env.reset()
        steps += 256
        if time.perf_counter() - start >= seconds:
            break
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate


def ours_steps_per_second(env_id: str, num_envs: int, seconds: float, seed: int = 0, threads=None) -> float:
    env = make_env(env_id, num_envs=num_envs, seed=seed, num_threads=threads)
    td = env.reset()
    spec = env.action_spec
    low, high = spec.space.low, spec.space.high
    gen = torch.Generator().manual_seed(seed)
    actions = low + (high - low) * torch.rand((64, *spec.shape), generator=gen)
    for t in range(5):  # warm-up
        td["action"] = actions[t]
        _, td = env.step_and_maybe_reset(td)
    calls, start = 0, time.perf_counter()
    while True:
        for a in actions:
            td["action"] = a
            _, td = env.step_and_maybe_reset(td)
        calls += len(actions)
        if time.perf_counter() - start >= seconds:
            break
    rate = calls * num_envs / (time.perf_counter() - start)
    env.close()
    return rate


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs, fewer repeats")
    parser.add_argument("--domains", nargs="*", default=list(DOMAINS), choices=list(DOMAINS))
    parser.add_argument("--num-envs", nargs="*", type=int, default=[1, 16, 64])
    parser.add_argument(
        "--threads", nargs="*", type=int, default=[0, 1],
        help="num_threads of our envs to measure; 0 is the default, min(N, CPUs)",
    )
    parser.add_argument("--context", choices=("dr", "default"), default="dr",
                        help="dr: the domain-randomized ids; default: MO<Domain>Default-v5, the peer's physics")
    args = parser.parse_args(argv)
    seconds, repeats = (0.4, 2) if args.quick else (1.5, 3)
    torch.set_num_threads(1)

    print(f"sub-env steps/s, best of {repeats} alternating repeats of {seconds}s each "
          f"(torch {torch.__version__}, gymnasium {gym.__version__}, {os.cpu_count()} CPUs)")
    head = " ".join(f"{f'N={n}':>9} {'ratio':>6}" for n in args.num_envs)
    print(f"{'domain':<12} {'Gymnasium (1 env)':>17} {'threads':>8} {head}")
    for domain in args.domains:
        ours_id, gym_id, gym_kwargs = DOMAINS[domain]
        if args.context == "default":
            ours_id = ours_id.replace("DR-", "Default-")
        configs = [(t, n) for t in args.threads for n in args.num_envs if not (t == 1 and n == 1 and 0 in args.threads)]
        peer, ours = 0.0, dict.fromkeys(configs, 0.0)
        for _ in range(repeats):
            peer = max(peer, gym_steps_per_second(gym_id, gym_kwargs, seconds))
            for t, n in configs:
                ours[t, n] = max(ours[t, n], ours_steps_per_second(ours_id, n, seconds, threads=t or None))
        for row, t in enumerate(args.threads):
            cells = " ".join(
                f"{ours[t, n]:>9.0f} {ours[t, n] / peer:>6.2f}" if (t, n) in ours else f"{'':>9} {'':>6}"
                for n in args.num_envs
            )
            name, peer_cell = (domain, f"{peer:>17.0f}") if row == 0 else ("", f"{'':>17}")
            print(f"{name:<12} {peer_cell} {t or 'auto':>8} {cells}", flush=True)


if __name__ == "__main__":
    main()
