"""End-to-end time of the multi-context evaluation protocol.

The paper's protocol (SPEC §2): every evaluation context × 100 preference weights, one
episode each, discounted vector returns, a Pareto front and metrics per context. Measured in
one run, each with its peer:

* **MO-LunarLander** (if ``morl_trl.envs.lunar_lander`` is there): 8 contexts × 100 weights =
  800 episodes of at most 1,000 steps, random policy, through
  ``MultiContextEvaluator("random", "MOLunarLanderDR-v0")`` — the whole grid as ONE batched
  env of 800 sub-envs, metrics with the published reference data when it is found. Peer:
  MO-Gymnasium's ``mo-lunar-lander-v3`` run episode by episode (8 × 100 episodes with each
  context's gravity, wind and turbulence; random actions pre-drawn; discounted vector return
  accumulated in Python), a lower bound on the authors' evaluator, which steps an 8-env
  vector env in lockstep for each weight.
* **MO-LavaGrid** (if registered): 8 contexts × 100 weights, random policy; no peer of the
  same game exists, so only our time is printed.
* **Toy** (always): ``tests/mocks.py:ToyContextEnv``, 8 contexts × 100 weights × 4 episodes,
  to show the evaluator's own overhead per step.

Box2D steps one world per sub-env in Python, so MO-LunarLander is physics-bound: a
batched step costs the same per sub-env as Gymnasium's, and in lockstep the finished sub-envs
keep being stepped until the longest episode ends (a random lander that comes to rest on its
legs without sleeping runs the full 1,000 steps). The pool (``chunk_size``) run shows the
effect of streaming rows through fewer sub-envs.

    python benchmarks/bench_evaluator.py                 # a few minutes on 2 cores
    python benchmarks/bench_evaluator.py --weights 10    # quick
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from morl_trl.evaluation import MultiContextEvaluator  # noqa: E402


def _reference(path: Path, domain: str):
    if not (path / "minmax_values").is_dir():
        return None
    from morl_trl.reporting import load_domain_reference

    return load_domain_reference(path, domain)


def _ours(contexts, weights: int, reference=None, chunk_size=None, seed=0, **kw):
    ev = MultiContextEvaluator("random", contexts, weights=weights, reference=reference, chunk_size=chunk_size,
                               seed=seed, **kw)
    start = time.perf_counter()
    result = ev.evaluate()
    elapsed = time.perf_counter() - start
    ev.close()
    return elapsed, result


def _peer_lunar_lander(contexts, weights: int, gamma: float, seed: int = 0):
    import mo_gymnasium as mo_gym

    from morl_trl.envs import domain_of

    space = domain_of(contexts[0]).context_space
    rng = np.random.default_rng(seed)
    steps = 0
    start = time.perf_counter()
    for cid in contexts:
        ctx = space.as_dict(domain_of(cid).context_of(cid))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # wind 20 is at the edge of Gymnasium's advice
            env = mo_gym.make(
                "mo-lunar-lander-v3", enable_wind=True, wind_power=ctx["wind_power"],
                turbulence_power=ctx["turbulence_power"],
            )
        # Gymnasium asserts -12 < g < 0 at construction; reset builds its world from .gravity
        env.unwrapped.gravity = ctx["gravity"]
        for w in range(weights):
            env.reset(seed=seed + w)
            ret, disc, done = np.zeros(4), 1.0, False
            actions = rng.integers(0, 4, size=1000)
            t = 0
            while not done:
                _, r, term, trunc, _ = env.step(int(actions[t]))
                ret += disc * r
                disc *= gamma
                done = term or trunc
                t += 1
            steps += t
        env.close()
    return time.perf_counter() - start, steps


def _registered(env_id: str) -> bool:
    try:
        from morl_trl.envs import domain_of

        spec = domain_of(env_id)
        module = spec.env_class.partition(":")[0]
        return importlib.util.find_spec(module) is not None
    except (ValueError, ModuleNotFoundError):
        return False


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--weights", type=int, default=100)
    p.add_argument("--chunk-size", type=int, default=None)
    p.add_argument("--reference", type=Path, default=ROOT.parent / "shared" / "reference")
    p.add_argument("--no-peer", action="store_true")
    args = p.parse_args(argv)
    torch.set_num_threads(1)

    from tests.mocks import TOY_CONTEXT, ToyContextEnv

    toy = {f"toy{i}": TOY_CONTEXT.make(speed=0.5 + 0.2 * i, bias=0.1 * i - 0.4) for i in range(8)}
    t, r = _ours(toy, args.weights, gamma=0.9, episodes=4,
                 env_factory=lambda num_envs, seed: ToyContextEnv(num_envs=num_envs, seed=seed))
    steps = int(r.lengths.max())
    print(f"Toy: {len(toy)} contexts x {args.weights} weights x 4 episodes = {r.lengths.numel()} sub-envs, "
          f"{steps} steps: {t:.3f} s ({t / steps * 1e3:.1f} ms per batched step, metrics included)")

    if _registered("MOLunarLanderDR-v0"):
        from morl_trl.envs import evaluation_suite

        suite = evaluation_suite("MOLunarLanderDR-v0")
        ref = _reference(args.reference, "MOLunarLanderDR-v0")
        n_rows = len(suite) * args.weights
        print(f"MO-LunarLander: {len(suite)} contexts x {args.weights} weights = {n_rows} episodes "
              f"(max 1000 steps), random policy, metrics with{'out' if ref is None else ''} reference data")
        t_ours = None
        for pool in dict.fromkeys([None, args.chunk_size or max(1, n_rows // 8)]):
            t, r = _ours("MOLunarLanderDR-v0", args.weights, reference=ref, chunk_size=pool)
            t_ours = t if t_ours is None else min(t_ours, t)
            n_steps = int(r.lengths.sum())
            agg = ", ".join(f"{k} {v:.3g}" for k, v in r.aggregate.items() if k in ("nhgr", "hypervolume"))
            print(f"  ours, {'one sub-env per episode' if pool is None else f'a pool of {pool} sub-envs'}: "
                  f"{t:.2f} s end to end; {n_steps} episode steps, longest episode {int(r.lengths.max())}; {agg}")
        if not args.no_peer:
            tp, peer_steps = _peer_lunar_lander(suite, args.weights, 0.99)
            print(f"  peer MO-Gymnasium mo-lunar-lander-v3, episode by episode: {tp:.2f} s, {peer_steps} steps; "
                  f"time ratio peer/ours (best) {tp / t_ours:.2f}x")
    else:
        print("MO-LunarLander: morl_trl.envs.lunar_lander not available, skipped")

    if _registered("MOLavaGridDR-v0"):
        t, r = _ours("MOLavaGridDR-v0", args.weights)
        print(f"MO-LavaGrid: {len(r.context_names)} contexts x {args.weights} weights, random policy: "
              f"{t:.2f} s end to end, {int(r.lengths.max())} batched steps, {int(r.lengths.sum())} episode steps")
    return 0


if __name__ == "__main__":
    sys.exit(main())
