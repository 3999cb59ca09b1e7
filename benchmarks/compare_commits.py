"""End-to-end training frames/s of two commits, measured in one run: "before" against "after".

Issue 26's check that a restructuring made nothing slower: for each (algorithm, domain) pair,
the same timing code (below, :func:`time_training`) runs the training loop's body of each
checkout -- that checkout's own ``resolve_config`` / ``build_training_env`` / ``build_agent`` /
replay buffer / TorchRL collector, as ``morl-trl train`` builds them -- in a fresh process with
``PYTHONPATH`` (and the working directory) pointing at the checkout: collect a batch ->
the algorithm's ``on_batch`` (store + its updates + schedules; ``agent.learn`` + ``agent.on_frames`` in a checkout
before issue 46) -> policy sync.
Evaluation and checkpoints are left out. Timing starts once learning has started (after
``init_random_frames`` and one batch of warm-up) and covers ``--frames`` environment frames
(whole batches). Rounds alternate the checkouts (before, after, after, before, ...) so that
machine load hits both alike; the median over rounds is reported.

Make the "before" checkout once (detached, outside this repository's tree)::

    git worktree add --detach /tmp/base 6842035
    nice -n 10 python benchmarks/compare_commits.py --before /tmp/base --after . --clock cpu

``--clock cpu`` (the worker's process CPU time, one torch thread) is the figure to use on a
shared machine. A pair that fails in a checkout (e.g. an algorithm it does not have) is
reported as such.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

# one paper domain per algorithm (the domains the paper ran each on: ../shared/reference/SPEC.md)
PAIRS = ("envelope:MOLunarLanderDR-v0", "capql:MOHopperDR-v5", "gpi_ls:MOLunarLanderDR-v0",
         "gpi_pd:MOLunarLanderDR-v0", "pcn:MOLunarLanderDR-v0", "morld:MOHopperDR-v5", "morld_psa:MOHopperDR-v5",
         "pgmorl:MOHopperDR-v5", "sac:MOHopperDR-v5")
# What differs from the paper's settings, only so that a round takes seconds, not minutes (the
# same for both checkouts): PGMORL collects 6 members x 4 envs x 2048 steps = 49,152 frames per
# iteration at the paper's settings (minutes per iteration on one core), timed here on 24 x 256-step
# iterations; PCN learns only once its 1000 random warm-up episodes are in (about 10^5 frames),
# timed here after 16 of them (``pcn_er_episodes``) and 2048 frames, over 4096 frames (a round
# of 50 updates every 10 finished episodes).
PAIR_SETTINGS = {
    "pgmorl": dict(overrides={"frames_per_batch": 24 * 256}),
    "pcn": dict(overrides={"pcn_er_episodes": 16}, warm=2048, frames=4096),
}
# ``--as-before``: the "after" checkout configured to do the work "before" did where issue 27 changed
# an algorithm's work to the authors' (not a speed change): PCN's network (the authors' net_arch
# [256] * 4 instead of MORL-Baselines' hidden_dim 64 with one hidden layer: ~15x the arithmetic
# per update), the delayed actor of SAC and MOSAC / MORL/D (policy_freq 2: a critic step per
# update and two actor steps every second one, each on a fresh forward of the whole loss), MORL/D's
# round robin (one member acts, one update of all P members' forward per frame: its concurrent schedule
# with the earlier layout instead).
# The actor-critics' one joint backward of the summed losses per update (``joint_update``) is what
# "before" did; the authors' order (critic step, then actor, then temperature) costs an extra actor
# forward per update (issue 27).
# SAC's and MORL/D's actor scale was softplus (issue 27: the authors' tanh log-std, a few more element-wise ops).
AS_BEFORE = {"pcn": {"hidden": [64, 64]}, "sac": {"policy_freq": 1, "joint_update": True, "actor_scale": "softplus"},
             "capql": {"joint_update": True},
             # PGMORL's episodes ran on across iterations (issue 27: a reset, and a re-seed, at every iteration)
             "pgmorl": {"pgmorl_reset_each_iteration": False, "pgmorl_reseed_each_iteration": False},
             "morld": {"policy_freq": 1, "joint_update": True, "actor_scale": "softplus",
                       "morld_schedule": "concurrent", "num_envs": 2, "frames_per_batch": 60}}


def time_training(algo: str, env_id: str, frames: int, clock: str, overrides: dict, warm: int = 0) -> dict:
    """Frames/s (environment frames, all sub-envs) of the checkout on ``sys.path``'s training loop."""
    import warnings

    import torch

    warnings.filterwarnings("ignore")
    from morl_trl.envs import domain_of
    from morl_trl.recipes import build_agent, build_training_env, resolve_config

    # (older layouts first: an editable install of a newer checkout would serve a module the older one lacks)
    try:  # issue 26 to issue 46
        from morl_trl.recipes.parts import make_collector, make_replay_buffer
        from morl_trl.recipes.parts import run_discount as discount
    except ImportError:
        try:  # after issue 46's layout
            from morl_trl.training.parts import make_collector, make_replay_buffer
            from morl_trl.training.parts import run_discount as discount
        except ImportError:  # before issue 26
            from morl_trl.recipes.off_policy import _gamma as discount
            from morl_trl.recipes.off_policy import make_collector, make_replay_buffer

    timer = time.process_time if clock == "cpu" else time.perf_counter
    torch.set_num_threads(1)  # the recipe's default
    dev = torch.device("cpu")
    cfg = resolve_config(algo, env_id, device="cpu", logger="none", progress=False, **overrides)
    spec = domain_of(env_id)
    torch.manual_seed(cfg.seed)
    env = build_training_env(cfg, dev)
    agent = build_agent(cfg, env, gamma=discount(cfg, spec), device=dev)
    buffer = make_replay_buffer(cfg, dev)
    if hasattr(agent, "learn"):  # before issue 46: the agent's learn, then its schedules
        def on_batch(agent, batch, buffer, frames):
            out = agent.learn(batch, buffer, frames)
            agent.on_frames(frames)
            return out
    else:  # the checkout's one per-batch step per algorithm
        from morl_trl.algorithms.registry import algorithm

        on_batch = algorithm(algo).on_batch
    if algo == "pgmorl" and on_batch.__module__.endswith("pgmorl.recipe"):  # PGMORL counts one member's frames
        from morl_trl.algorithms.pgmorl.recipe import counted_frames

        def frames_of(batch):
            return counted_frames(agent, batch)
    else:
        frames_of = getattr(agent, "frames_of", lambda batch: batch.numel())
    collector = make_collector(cfg, env, agent.explore_policy, dev)
    warm = max(warm, getattr(cfg, "init_random_frames", 0) + cfg.frames_per_batch)  # (PCN, PGMORL: no warm-up key)
    run_frames, collected, updates, timed, t0, learning = 0, 0, 0, 0, None, 0.0
    for batch in collector:
        collected += batch.numel()
        run_frames += frames_of(batch)
        t_learn = timer()
        _, n = on_batch(agent, batch, buffer, run_frames)
        t_learn = timer() - t_learn
        collector.update_policy_weights_()
        if t0 is not None:
            timed += batch.numel()
            updates += n
            learning += t_learn
            if timed >= frames:
                break
        elif collected >= warm:
            t0 = timer()
    seconds = timer() - t0
    collector.shutdown()
    return {"fps": timed / seconds, "ups": updates / seconds, "frames": timed, "seconds": seconds,
            "learn_share": learning / seconds}


def run_worker(checkout: Path, pair: str, frames: int, clock: str, overrides: dict, warm: int, timeout: float) -> dict:
    env = dict(os.environ, PYTHONPATH=str(checkout), OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", pair, "--frames", str(frames), "--clock", clock,
           "--overrides", json.dumps(overrides), "--warm", str(warm)]
    try:
        out = subprocess.run(cmd, cwd=checkout, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout:.0f} s"}
    for line in reversed(out.stdout.splitlines()):
        if line.startswith("{"):
            return json.loads(line)
    last = (out.stderr.strip().splitlines() or ["no output"])[-1]
    return {"error": last[:200]}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before", type=Path, default=Path("/tmp/base"), help="checkout of the 'before' commit")
    p.add_argument("--after", type=Path, default=Path(__file__).resolve().parents[1], help="checkout of 'after'")
    p.add_argument("--pairs", nargs="+", default=list(PAIRS), help="algo:env_id pairs")
    p.add_argument("--frames", type=int, default=512,
                   help="environment frames timed per pair and round (PCN: PAIR_SETTINGS)")
    p.add_argument("--rounds", type=int, default=3, help="rounds per pair (checkouts alternate)")
    p.add_argument("--clock", choices=["wall", "cpu"], default="wall",
                   help="wall time, or the worker's process CPU time (steadier on a shared machine)")
    p.add_argument("--timeout", type=float, default=1800, help="seconds per worker before it counts as failed")
    p.add_argument("--as-before", action="store_true",
                   help="configure 'after' to do the work 'before' did where issue 27 changed it (AS_BEFORE)")
    p.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    p.add_argument("--overrides", default="{}", help=argparse.SUPPRESS)
    p.add_argument("--warm", type=int, default=0, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.worker:
        algo, env_id = args.worker.split(":")
        print(json.dumps(time_training(algo, env_id, args.frames, args.clock, json.loads(args.overrides), args.warm)))
        return 0

    def describe(path: Path) -> str:
        rev = subprocess.run(["git", "-C", str(path), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
        dirty = subprocess.run(["git", "-C", str(path), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True).stdout.strip()
        return f"{path} ({rev.stdout.strip() or '?'}{' + changes' if dirty else ''})"

    checkouts = {"before": args.before.resolve(), "after": args.after.resolve()}
    print(f"before: {describe(checkouts['before'])}; after: {describe(checkouts['after'])}")
    print(f"{args.frames} frames timed per pair and round after learning starts, {args.rounds} rounds alternating, "
          f"1 torch thread, {args.clock} clock; median frames/s")
    print(f"{'algo':<9} {'domain':<20} {'before f/s':>11} {'after f/s':>10} {'after/before':>13} "
          f"{'learn% b':>8} {'a':>6}  note   (learn%: the share of the time in agent.learn; the rest is collection)")
    for pair in args.pairs:
        algo = pair.split(":")[0]
        setting = PAIR_SETTINGS.get(algo, {})
        overrides, warm, frames = setting.get("overrides", {}), setting.get("warm", 0), setting.get("frames", args.frames)
        rates, shares = {"before": [], "after": []}, {"before": [], "after": []}
        errors = {}
        for r in range(args.rounds):
            order = ("before", "after") if r % 2 == 0 else ("after", "before")
            for name in order:
                if name in errors:
                    continue
                mine = {**overrides, **AS_BEFORE.get(algo, {})} if args.as_before and name == "after" else overrides
                res = run_worker(checkouts[name], pair, frames, args.clock, mine, warm, args.timeout)
                if "error" in res:
                    errors[name] = res["error"]
                else:
                    rates[name].append(res["fps"])
                    shares[name].append(res["learn_share"])
        med = {k: statistics.median(v) if v else float("nan") for k, v in rates.items()}
        share = {k: statistics.median(v) if v else float("nan") for k, v in shares.items()}
        note = "; ".join(f"{k} failed: {v}" for k, v in errors.items())
        if setting:
            note = (note + "; " if note else "") + f"{frames} frames, {setting}"
        if args.as_before and algo in AS_BEFORE:
            note = (note + "; " if note else "") + f"after with {AS_BEFORE[algo]}"
        algo_, env_id = pair.split(":")
        print(f"{algo_:<9} {env_id:<20} {med['before']:>11.1f} {med['after']:>10.1f} "
              f"{med['after'] / med['before']:>12.2f}x {share['before']:>7.0%} {share['after']:>6.0%}  {note}",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
