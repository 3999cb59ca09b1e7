"""Where one frame goes, end to end on one env: ours beside MORL-Baselines' for the same parity case.

Runs ``bench_train --one-env``'s case (``benchmarks/parity/common.py``: the same env, settings and
networks for both libraries) once in each library with a timer around each phase of a frame
(process CPU time, one torch thread), and prints milliseconds per frame:

==================  ====================================================  ==========================================
phase               ours                                                  MORL-Baselines 1.3.0
==================  ====================================================  ==========================================
act                 the collector's policy call                           ``act`` / ``_act`` / the policy's
                                                                          ``get_action``
env step            the collector env's ``step_and_maybe_reset``          the env's ``step``
store               ``Agent.store`` / a buffer's ``extend`` / PCN's        the replay buffer's ``add`` / ``push`` /
                    ``store_episodes``                                    ``_add_episode``
sample              a replay buffer's / PCN's episode replay's ``sample``  the replay buffer's ``sample``
loss                a loss module's call (TorchRL ``LossModule``) or its   the rest of ``update`` (loss, target
                    parts' (``qvalue_loss``, ``actor_loss``, ...,         update, schedules)
                    PCN's ``losses_of``)
backward+optimizer  ``optimizer_step`` / ``backward`` / ``Optimizer.step``  ``backward``, ``clip_grad_norm_``,
                                                                          ``Optimizer.step`` / ``zero_grad``
priority write      the buffer's ``update_priority``                      ``update_priorities``
update other        the rest of the recipe's ``update`` (target update,   -
                    moving the batch)
bookkeeping         the rest of the loop (collector, run log, schedules)  the rest of ``train()``
==================  ====================================================  ==========================================

Each phase counts its own time only (a phase inside another is taken out of the outer one);
evaluations are left out (as ``bench_train --one-env``). The timers add ~1-2 us per call.

    python benchmarks/profile_frame.py envelope-dst
    python benchmarks/profile_frame.py gpi_ls-dst pcn-fruit-tree --frames 1000
    python benchmarks/profile_frame.py capql-mountaincar --peer none
"""

from __future__ import annotations

import argparse
import functools
import inspect
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PARITY = ROOT / "benchmarks" / "parity"
PHASES = ("act", "env step", "store", "sample", "loss", "backward+optimizer", "priority write", "update other",
          "bookkeeping")
CLOCK = time.process_time


class Phases:
    """Exclusive CPU time per phase: a phase entered inside another pauses the outer one."""

    def __init__(self):
        self.seconds: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self._stack: list[list] = []  # [name, start, nested seconds]
        self.on = False

    def wrap(self, name: str, fn):
        if getattr(fn, "_phase", None) is not None:
            return fn
        phases = self

        @functools.wraps(fn)
        def timed(*args, **kwargs):
            if not phases.on:
                return fn(*args, **kwargs)
            entry = [name, CLOCK(), 0.0]
            phases._stack.append(entry)
            try:
                return fn(*args, **kwargs)
            finally:
                phases._stack.pop()
                spent = CLOCK() - entry[1]
                phases.seconds[name] = phases.seconds.get(name, 0.0) + spent - entry[2]
                phases.calls[name] = phases.calls.get(name, 0) + 1
                if phases._stack:
                    phases._stack[-1][2] += spent

        timed._phase = name
        return timed

    def patch(self, owner, attr: str, name: str) -> None:
        fn = getattr(owner, attr, None)
        if fn is not None:
            setattr(owner, attr, self.wrap(name, fn))

    def reset(self):
        self.seconds.clear(), self.calls.clear()


_PHASES: list = []


def _phases() -> Phases:
    if not _PHASES:
        _PHASES.append(Phases())
    return _PHASES[0]


def _patch_torch(ph: Phases) -> None:
    import torch

    ph.patch(torch.Tensor, "backward", "backward+optimizer")
    ph.patch(torch.autograd, "backward", "backward+optimizer")
    ph.patch(torch.nn.utils, "clip_grad_norm_", "backward+optimizer")
    for cls in (torch.optim.Adam, torch.optim.AdamW, torch.optim.SGD):
        ph.patch(cls, "step", "backward+optimizer")
    ph.patch(torch.optim.Optimizer, "zero_grad", "backward+optimizer")


# ----------------------------------------------------------------------------------------------- ours
def ours(case: str, frames: int) -> dict:
    """Ours on ``case`` (``bench_train.ours_one_env``) with every phase timed: ms per frame."""
    import torch
    from torchrl.collectors import Collector
    from torchrl.data import ReplayBuffer
    from torchrl.objectives import LossModule

    import morl_trl.training.optim as optim
    from morl_trl.algorithms.registry import REGISTRY  # noqa: F401  (the recipes imported)
    from morl_trl.training.agent import Agent

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_train

    torch.set_num_threads(1)
    bench_train.CLOCK = CLOCK
    ph = _phases()  # (one for the process: a function wrapped for an earlier case keeps reporting to it)
    ph.reset()
    _patch_torch(ph)
    ph.patch(Agent, "store", "store")
    from morl_trl.algorithms.pcn.recipe import PCNAgent
    from morl_trl.data.episode_replay import EpisodeReplay
    from morl_trl.objectives import PCNLoss

    ph.patch(PCNAgent, "store_episodes", "store")  # (PCN: episodes into its episode replay)
    ph.patch(EpisodeReplay, "sample", "sample")
    ph.patch(PCNLoss, "losses_of", "loss")
    import morl_trl.data.lean  # noqa: F401  (its buffer class among the subclasses)
    import morl_trl.objectives  # noqa: F401  (their losses among the subclasses)

    for cls in subclasses(ReplayBuffer):
        ph.patch(cls, "sample", "sample")
        ph.patch(cls, "update_priority", "priority write")
        ph.patch(cls, "update_tensordict_priority", "priority write")
        ph.patch(cls, "extend", "store")
    ph.patch(LossModule, "__call__", "loss")
    for cls in subclasses(LossModule):  # (the actor-critics call their losses' parts: qvalue_loss, actor_loss, ...)
        for name, fn in list(vars(cls).items()):
            if name.endswith(("_loss", "_dist")) and not name.startswith("_") and inspect.isfunction(fn):
                ph.patch(cls, name, "loss")
    step = optim.optimizer_step
    timed_step = ph.wrap("backward+optimizer", step)
    for mod in [m for k, m in sys.modules.items() if k.startswith("morl_trl") and m is not None]:
        if getattr(mod, "optimizer_step", None) is step:
            mod.optimizer_step = timed_step
        fn = getattr(mod, "update", None)
        if callable(fn) and k_is_recipe(mod):
            mod.update = ph.wrap("update other", fn)
    iterator = Collector.iterator

    def started_iterator(self):  # the phases count from the first collected batch, as bench_train's clock
        # (on the instance: a subclass's rollout, e.g. the recipes' one-step one, calls the same two)
        self._wrapped_policy = ph.wrap("act", self._wrapped_policy)
        self.env.step_and_maybe_reset = ph.wrap("env step", self.env.step_and_maybe_reset)
        ph.reset()
        ph.on = True
        yield from iterator(self)

    Collector.iterator = started_iterator
    from morl_trl.evaluation import MultiContextEvaluator

    evaluate = MultiContextEvaluator.evaluate

    def no_phases_evaluate(self, *args, **kwargs):
        on, ph.on = ph.on, False
        try:
            return evaluate(self, *args, **kwargs)
        finally:
            ph.on = on

    MultiContextEvaluator.evaluate = no_phases_evaluate
    from morl_trl.runs.run import Run

    finish = Run.finish

    def stop_finish(self, *args, **kwargs):
        ph.on = False
        return finish(self, *args, **kwargs)

    Run.finish = stop_finish
    try:
        r = bench_train.ours_one_env(case, frames)
    finally:
        Collector.iterator = iterator
        MultiContextEvaluator.evaluate, Run.finish = evaluate, finish
    total_ms = 1e3 / r["fps"]
    return _per_frame(ph, r["frames"], total_ms)


def subclasses(cls) -> set:
    """``cls`` and every class below it."""
    return {cls}.union(*(subclasses(c) for c in cls.__subclasses__()))


def k_is_recipe(mod) -> bool:
    return mod.__name__.startswith("morl_trl.algorithms.") and mod.__name__.endswith(".recipe")


def _per_frame(ph: Phases, frames: int, total_ms: float) -> dict:
    out = {name: ph.seconds.get(name, 0.0) * 1e3 / frames for name in PHASES if name != "bookkeeping"}
    out["bookkeeping"] = total_ms - sum(out.values())
    out["total"] = total_ms
    return out


# ------------------------------------------------------------------------------------------------ MB
_MB_CHILD = r"""
import json, sys, time
sys.path.insert(0, {parity!r}); sys.path.insert(0, {bench!r})
import profile_frame as pf
print(json.dumps(pf.mb_child({case!r}, {frames})))
"""


def mb_child(case_name: str, frames: int) -> dict:
    """In MB's python: its ``train()`` on ``case_name`` with every phase timed (``mb_runner.run``)."""
    import importlib

    import common
    import mo_gymnasium as mo_gym
    import torch

    _ = torch
    common.CASES[case_name].update(frames=frames, eval_every=frames)
    ph = Phases()
    _patch_torch(ph)
    mods = {"envelope": ("morl_baselines.multi_policy.envelope.envelope", "Envelope"),
            "gpi_ls": ("morl_baselines.multi_policy.gpi_pd.gpi_pd", "GPILS"),
            "gpi_pd": ("morl_baselines.multi_policy.gpi_pd.gpi_pd", "GPIPD"),
            "pcn": ("morl_baselines.multi_policy.pcn.pcn", "PCN"),
            "capql": ("morl_baselines.multi_policy.capql.capql", "CAPQL")}
    algo = common.CASES[case_name]["algo"]
    from morl_baselines.common import buffer, prioritized_buffer

    for cls in (buffer.ReplayBuffer, prioritized_buffer.PrioritizedReplayBuffer):
        ph.patch(cls, "add", "store")
        ph.patch(cls, "sample", "sample")
        ph.patch(cls, "update_priorities", "priority write")
    capql = importlib.import_module("morl_baselines.multi_policy.capql.capql")
    ph.patch(capql.ReplayMemory, "push", "store")
    ph.patch(capql.ReplayMemory, "sample", "sample")
    ph.patch(capql.Policy, "get_action", "act")
    gpi = importlib.import_module("morl_baselines.multi_policy.gpi_pd.gpi_pd")
    for cls in (gpi.GPILS, gpi.GPIPD):
        ph.patch(cls, "_act", "act")
        ph.patch(cls, "update", "loss")
    if algo in mods:
        cls = getattr(importlib.import_module(mods[algo][0]), mods[algo][1])
        for attr in ("act", "_act"):
            ph.patch(cls, attr, "act")
        ph.patch(cls, "_add_episode", "store")
        ph.patch(cls, "update", "loss")
    make = mo_gym.make

    def timed_make(*args, **kwargs):
        env = make(*args, **kwargs)
        env.step = ph.wrap("env step", env.step)
        return env

    mo_gym.make = timed_make
    import mb_runner

    marks = {}
    evaluate = mb_runner.evaluate_policy

    def no_phases_evaluate(*args, **kwargs):
        on, ph.on = ph.on, False
        t = CLOCK()
        try:
            return evaluate(*args, **kwargs)
        finally:
            marks["eval"] = marks.get("eval", 0.0) + CLOCK() - t
            ph.on = on

    mb_runner.evaluate_policy = no_phases_evaluate
    call = mb_runner._call

    def timed_call(fn, **kwargs):  # (the train() call)
        ph.reset()
        marks["eval"] = 0.0
        ph.on = True
        t = CLOCK()
        try:
            return call(fn, **kwargs)
        finally:
            ph.on = False
            marks["train"] = CLOCK() - t - marks["eval"]

    mb_runner._call = timed_call
    with tempfile.TemporaryDirectory() as tmp:
        cwd = os.getcwd()
        os.chdir(tmp)
        try:
            mb_runner.run(case_name, 0, Path(tmp) / "mb.json")
            result = json.loads((Path(tmp) / "mb.json").read_text())
        finally:
            os.chdir(cwd)
    frames_done = result["frames"]
    return _per_frame(ph, frames_done, marks["train"] * 1e3 / frames_done)


def mb(case: str, frames: int, python: Path) -> dict:
    code = _MB_CHILD.format(parity=str(PARITY), bench=str(ROOT / "benchmarks"), case=case, frames=frames)
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    done = subprocess.run([str(python), "-c", code], env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(done.stderr.strip().splitlines()[-1] if done.stderr.strip() else str(done.returncode))
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_train import mb_python

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("cases", nargs="+", help="parity cases (bench_train --one-env's: envelope-dst, gpi_ls-dst, ...)")
    p.add_argument("--frames", type=int, default=2_000)
    p.add_argument("--peer", choices=["auto", "none"], default="auto")
    p.add_argument("--mb-python", default=None)
    args = p.parse_args(argv)
    python = None if args.peer == "none" else mb_python(args.mb_python)
    for case in args.cases:
        o = ours(case, args.frames)
        m = mb(case, args.frames, python) if python is not None else None
        print(f"{case}: ms per frame ({args.frames} frames, process CPU time, 1 thread)")
        print(f"  {'phase':<20} {'ours':>8} {'MB':>8}")
        for name in (*PHASES, "total"):
            print(f"  {name:<20} {o[name]:>8.3f} {m[name] if m else float('nan'):>8.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
