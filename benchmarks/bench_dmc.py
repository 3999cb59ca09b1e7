"""Sub-env steps per second of the batched DMC domains against TorchRL's ``DMControlEnv``.

For each domain, in one run: ``make_env("DMC<Domain>Default-v0", num_envs=N)`` (the suite's
physics, bit for bit: ``tests/envs/test_dmc.py``) stepped through ``step_and_maybe_reset``
(what collectors call; auto-resets included) for N in 1, 16, 64; TorchRL's
``DMControlEnv(domain, task)`` (one env) and a ``ParallelEnv`` of W of them (one process
each), stepped the same way. Actions are uniform random, drawn beforehand. Each figure is the
best of a few alternating repeats; ratios are ours / peer (sub-env steps per second).

    python benchmarks/bench_dmc.py                 # ~2 minutes
    python benchmarks/bench_dmc.py --quick         # ~30 s, noisier
    python benchmarks/bench_dmc.py --workers 8     # the ParallelEnv's size
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from morl_trl.envs import make_env  # noqa: E402

DOMAINS = {  # domain: (our default-context id, dm_control suite domain, task)
    "Walker": ("DMCWalkerDefault-v0", "walker", "walk"),
    "Cheetah": ("DMCCheetahDefault-v0", "cheetah", "run"),
    "Hopper": ("DMCHopperDefault-v0", "hopper", "hop"),
}


def _rate(env, num_envs: int, seconds: float, seed: int = 0) -> float:
    td = env.reset()
    spec = env.action_spec
    low, high = spec.space.low, spec.space.high
    gen = torch.Generator().manual_seed(seed)
    actions = low + (high - low) * torch.rand((64, *spec.shape), generator=gen)
    actions = actions.to(spec.dtype)
    for t in range(3):  # warm-up
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
    return calls * num_envs / (time.perf_counter() - start)


def _make_dmcontrol(domain: str, task: str):
    from torchrl.envs import DMControlEnv

    return DMControlEnv(domain, task)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs, fewer repeats")
    parser.add_argument("--domains", nargs="*", default=list(DOMAINS), choices=list(DOMAINS))
    parser.add_argument("--num-envs", nargs="*", type=int, default=[1, 16, 64])
    parser.add_argument("--workers", type=int, default=min(8, os.cpu_count() or 1),
                        help="processes of the ParallelEnv peer")
    args = parser.parse_args(argv)
    seconds, repeats = (0.5, 1) if args.quick else (1.5, 3)
    torch.set_num_threads(1)
    from functools import partial

    from torchrl.envs import ParallelEnv

    print(f"sub-env steps/s, best of {repeats} alternating repeats of {seconds}s each "
          f"(torch {torch.__version__}, {os.cpu_count()} CPUs; ours with min(N, CPUs) threads)")
    head = " ".join(f"{f'N={n}':>9} {'/1env':>6} {'/par':>6}" for n in args.num_envs)
    print(f"{'domain':<8} {'DMControlEnv':>12} {f'ParallelEnv({args.workers})':>15} {head}")
    for domain in args.domains:
        ours_id, suite_domain, task = DOMAINS[domain]
        single = _make_dmcontrol(suite_domain, task)
        parallel = ParallelEnv(args.workers, partial(_make_dmcontrol, suite_domain, task))
        peer1 = peer_par = 0.0
        ours = dict.fromkeys(args.num_envs, 0.0)
        for _ in range(repeats):
            peer1 = max(peer1, _rate(single, 1, seconds))
            peer_par = max(peer_par, _rate(parallel, args.workers, seconds))
            for n in args.num_envs:
                env = make_env(ours_id, num_envs=n, seed=0)
                ours[n] = max(ours[n], _rate(env, n, seconds))
                env.close()
        parallel.close()
        cells = " ".join(f"{ours[n]:>9.0f} {ours[n] / peer1:>6.1f} {ours[n] / peer_par:>6.1f}" for n in args.num_envs)
        print(f"{domain:<8} {peer1:>12.0f} {peer_par:>15.0f} {cells}", flush=True)


if __name__ == "__main__":
    main()
