"""Whether two checkouts train exactly alike: every algorithm's full run, compared tensor by tensor.

A restructuring that must not change what is computed (issue 46: one loop and one update per
algorithm) is checked here end to end: for each case below, each checkout runs its own
``morl_trl.recipes.train`` (what ``morl-trl train`` runs: env, agent, replay, collector, the
recipe's loop, evaluations and the final checkpoint) in a fresh process with ``PYTHONPATH`` and
the working directory at the checkout, on the same machine, one thread. Then every tensor of the
final checkpoint's agent state (networks, targets, optimizer moments, counters, archives) and
every row of the evaluation log are compared for exact equality.

Make the "before" checkout once (detached, outside this repository's tree)::

    git worktree add --detach /tmp/base <commit>
    python benchmarks/compare_trajectories.py --before /tmp/base --after .
    python benchmarks/compare_trajectories.py --before /tmp/base --after . --algos envelope,capql

Prints one line per case (``identical`` or what differs, first differing entries named); exits 1
if any case differs or fails.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

# small, fast settings (the same for both checkouts); evaluation on two contexts, 3 weights
_COMMON = dict(num_envs=2, frames_per_batch=32, hidden=(16, 16), progress=False, logger="csv", seed=5,
               eval_weights=3, eval_random_baseline=False)
_OFF = dict(init_random_frames=32, updates_per_batch=2, batch_size=16, buffer_size=512)
_LAVA = dict(eval_contexts=("MOLavaGridRoom-v0", "MOLavaGridSnake-v0"))
_ONE = dict(_OFF, num_envs=1, frames_per_batch=1, eval_contexts=None, eval_episodes=1)
_HOP = dict(eval_contexts=("MOHopperDefault-v5",), eval_episodes=1)

#: case -> (algorithm, env id, overrides)
CASES = {
    "envelope": ("envelope", "MOLavaGridDR-v0", dict(**_OFF, **_LAVA, frames=256, eval_interval=128)),
    "capql": ("capql", "MOHopperDR-v5", dict(**_OFF, **_HOP, frames=160, eval_interval=160)),
    "capql_joint": ("capql", "MOHopperDR-v5", dict(**_OFF, **_HOP, frames=128, eval_interval=128, joint_update=True)),
    "mosac": ("mosac", "MOHopperDR-v5", dict(**_OFF, **_HOP, frames=160, eval_interval=160)),
    "mosac_discrete": ("mosac_discrete", "MOLavaGridDR-v0", dict(**_OFF, **_LAVA, frames=256, eval_interval=128)),
    "sac": ("sac", "MOHopperDR-v5", dict(**_OFF, **_HOP, frames=160, eval_interval=160)),
    "sac_discrete": ("sac", "MOLavaGridDR-v0", dict(**_OFF, **_LAVA, frames=256, eval_interval=256,
                                                    update_frequency=1)),
    "gpi_ls": ("gpi_ls", "MOLavaGridDR-v0", dict(**_OFF, **_LAVA, frames=256, eval_interval=128,
                                                 gpi_iteration_frames=64)),
    "gpi_pd": ("gpi_pd", "MOLavaGridDR-v0", dict(**_OFF, **_LAVA, frames=256, eval_interval=128,
                                                 gpi_iteration_frames=64, gpi_dynamics_rollout_starts=64,
                                                 gpi_dynamics_train_freq=64)),
    "gpi_pd_continuous": ("gpi_pd", "MOHopperDR-v5", dict(**_OFF, **_HOP, frames=128, eval_interval=128,
                                                          gpi_iteration_frames=64, gpi_dynamics_rollout_starts=64,
                                                          gpi_dynamics_train_freq=64)),
    "pcn": ("pcn", "MOLavaGridDR-v0", dict(**_LAVA, frames=1024, frames_per_batch=256, num_envs=2, eval_interval=512,
                                           pcn_er_episodes=2, pcn_step_episodes=1, pcn_model_updates=3,
                                           batch_size=16)),
    "pgmorl": ("pgmorl", "MOHopperDR-v5", dict(**_HOP, frames=256, frames_per_batch=64, eval_interval=128,
                                               pgmorl_pop=2, pgmorl_envs_per_member=1, pgmorl_warmup=1,
                                               pgmorl_evo_iterations=1, pgmorl_minibatches=2, pgmorl_epochs=1,
                                               hidden=(8,), num_envs=2)),
    # one env, one frame a batch, a MO-Gymnasium id (the one-env path of issue 47: the lean env step)
    "envelope_one_env": ("envelope", "deep-sea-treasure-v0", dict(**_ONE, frames=400, eval_interval=400)),
    "gpi_ls_one_env": ("gpi_ls", "deep-sea-treasure-v0", dict(**_ONE, frames=400, eval_interval=400,
                                                           gpi_iteration_frames=200)),
    "capql_one_env": ("capql", "mo-mountaincarcontinuous-v0", dict(**_ONE, frames=300, eval_interval=300)),
    # PCN on one MO-Gymnasium env (its own loop: a command per episode; the lean env step with the command transform)
    "pcn_one_env": ("pcn", "fruit-tree-v0", dict(num_envs=1, eval_contexts=None, eval_episodes=1, eval_weights=6,
                                                 frames=600, eval_interval=600, pcn_er_episodes=5, pcn_step_episodes=2,
                                                 pcn_model_updates=3, batch_size=16, pcn_scaling_factor=[0.1] * 7)),
    # round robin: 3 members, turns of 64 frames (2 catch-up passes at each exchange)
    "morld": ("morld", "MOHopperDR-v5", dict(**{**_OFF, "updates_per_batch": 0}, **_HOP, num_envs=1, pop_size=3,
                                             exchange_every=64, frames=224, eval_interval=96)),
    "morld_psa": ("morld_psa", "MOLavaGridDR-v0", dict(**{**_OFF, "updates_per_batch": 0}, **_LAVA, num_envs=1,
                                                       pop_size=3, exchange_every=64, frames=256, eval_interval=128)),
    "morld_concurrent": ("morld", "MOHopperDR-v5", dict(**_OFF, **_HOP, morld_schedule="concurrent", pop_size=3,
                                                        num_envs=3, frames_per_batch=27, frames=162, eval_interval=81)),
}

_TIMING = re.compile(r"per_second|fps|seconds|time", re.I)

_CHILD = r"""
import json, sys, torch
torch.set_num_threads(1)
from morl_trl.recipes import resolve_config, train
from morl_trl.runs.checkpoint import find_checkpoint, load_checkpoint
algo, env_id, overrides, run_dir, out = json.loads(sys.argv[1])
overrides = {k: (tuple(v) if isinstance(v, list) else v) for k, v in overrides.items() if v is not None}
cfg = resolve_config(algo, env_id, run_dir=run_dir, **overrides)
train(cfg)
ckpt, _ = find_checkpoint(run_dir, only=("state.pt",))
state = load_checkpoint(ckpt, map_location="cpu", keys={"agent": dict})
flat = {}
def walk(prefix, value):
    if isinstance(value, torch.Tensor):
        flat[prefix] = value
    elif isinstance(value, dict):
        for k, v in value.items():
            walk(f"{prefix}/{k}", v)
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            walk(f"{prefix}/{i}", v)
    elif isinstance(value, (int, float, bool, str)) or value is None:
        flat[prefix] = value
walk("agent", state["agent"])
walk("frames", state.get("frames"))
torch.save({"flat": flat, "checkpoint": ckpt.name}, out)
"""


def _run(checkout: Path, case: str, workdir: Path) -> dict:
    algo, env_id, overrides = CASES[case]
    overrides = {**_COMMON, **overrides}
    run_dir = workdir / f"{case}_{checkout.name}"
    out = workdir / f"{case}_{checkout.name}.pt"
    env = dict(os.environ, PYTHONPATH=str(checkout), OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    env.pop("MORL_TRL_REFERENCE", None)
    arg = json.dumps([algo, env_id, overrides, str(run_dir), str(out)])
    proc = subprocess.run([sys.executable, "-c", _CHILD, arg], cwd=checkout, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else f"rc {proc.returncode}")
    import torch

    result = torch.load(out, weights_only=False)
    # (wall-clock figures differ from run to run: left out)
    metrics = sorted(p for p in run_dir.glob("logs/**/*.csv") if not _TIMING.search(p.name))
    result["logs"] = {str(p.relative_to(run_dir)): p.read_text() for p in metrics}
    return result


def compare(before: dict, after: dict) -> list[str]:
    """The entries that differ (empty: identical)."""
    import torch

    diffs = []
    a, b = before["flat"], after["flat"]
    for key in sorted(set(a) | set(b)):
        if key not in a or key not in b:
            diffs.append(f"{key}: only in {'before' if key in a else 'after'}")
            continue
        x, y = a[key], b[key]
        if isinstance(x, torch.Tensor) and isinstance(y, torch.Tensor):
            if x.shape != y.shape or x.dtype != y.dtype or not torch.equal(x, y):
                diffs.append(f"{key}: tensors differ")
        elif x != y:
            diffs.append(f"{key}: {x!r} != {y!r}")
    logs = set(before["logs"]) | set(after["logs"])
    for name in sorted(logs):
        if before["logs"].get(name) != after["logs"].get(name):
            diffs.append(f"log {name} differs")
    return diffs


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, required=True)
    parser.add_argument("--after", type=Path, required=True)
    parser.add_argument("--algos", default=None, help="comma-separated case or algorithm names (default: all cases)")
    args = parser.parse_args(argv)
    wanted = None if args.algos is None else set(args.algos.split(","))
    cases = [c for c in CASES if wanted is None or c in wanted or CASES[c][0] in wanted]
    failed = 0
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for case in cases:
            try:
                before = _run(args.before.resolve(), case, work / "before")
                after = _run(args.after.resolve(), case, work / "after")
            except RuntimeError as err:
                print(f"{case:20s} FAILED: {err}", flush=True)
                failed += 1
                continue
            diffs = compare(before, after)
            n = len(before["flat"])
            if diffs:
                failed += 1
                print(f"{case:20s} DIFFERS in {len(diffs)} of {n} entries: {'; '.join(diffs[:4])}", flush=True)
            else:
                print(f"{case:20s} identical ({n} entries, {len(before['logs'])} logs, "
                      f"checkpoint {before['checkpoint']})", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
