"""Throughput of the batched MO-SuperMarioBros against the raw gym-super-mario-bros loop.

Measures, in one run, agent steps per second (one agent step = 4 emulated frames) on stage
1-1 with the same pre-drawn random SIMPLE_MOVEMENT actions on every side, resetting an
emulator when its episode ends:

* **raw**: N upstream ``gym_super_mario_bros.SuperMarioBrosEnv(rom_mode="pixel",
  target=(1, 1))`` environments (fixed for NumPy 2 by ``morl_trl.envs.mario._compat``),
  stepped one after the other in a Python loop, 4 ``env.step`` calls per agent step; no
  frame processing, no vector reward, no TorchRL;
* **ours, 1 thread**: ``make_env("MOSuperMarioBros-1-1-v2", num_envs=N, num_threads=1)``
  with ``env.step_and_maybe_reset`` (max-pool, grayscale, 84x84, stack, vector reward,
  TensorDicts, partial resets);
* **ours, 2 threads**: the same with the emulators stepped by 2 threads (nes-py's core
  releases the GIL);
* **ours, 2 processes** (skipped with ``--quick``): ``torchrl.envs.ParallelEnv`` of 2
  workers, each holding N/2 emulators in one thread;

for N = 1, 2, 4, and prints each rate with its ratio to the raw loop. It first prints what a
stage costs: starting an emulator on it, resetting it (restoring its snapshot), one frame.

    python benchmarks/bench_mario.py            # ~2 min
    python benchmarks/bench_mario.py --quick    # ~30 s
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

STAGE = (1, 1)


def _actions(steps: int, n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 7, size=(steps, n))


def raw_rate(n: int, steps: int, warmup: int) -> float:
    from morl_trl.envs.mario._compat import upstream_stage_env
    from morl_trl.envs.mario.game import SIMPLE_MOVEMENT_BUTTONS

    envs = [upstream_stage_env(*STAGE) for _ in range(n)]
    for env in envs:
        env.reset()
    actions = _actions(warmup + steps, n)

    def run(rows):
        for row in rows:
            for env, a in zip(envs, row):
                buttons = SIMPLE_MOVEMENT_BUTTONS[a]
                for _ in range(4):
                    _, _, done, _ = env.step(buttons)
                    if done:
                        break
                if done:
                    env.reset()

    run(actions[:warmup])
    start = time.perf_counter()
    run(actions[warmup:])
    elapsed = time.perf_counter() - start
    for env in envs:
        env.close()
    return n * steps / elapsed


def _run_ours(env, actions: np.ndarray, warmup: int) -> float:
    td = env.reset()
    shape = env.action_spec.shape
    acts = torch.as_tensor(actions).reshape(len(actions), *shape)
    for t in range(warmup):
        td["action"] = acts[t]
        _, td = env.step_and_maybe_reset(td)
    start = time.perf_counter()
    for t in range(warmup, len(acts)):
        td["action"] = acts[t]
        _, td = env.step_and_maybe_reset(td)
    return (len(acts) - warmup) * acts[0].numel() / (time.perf_counter() - start)


def ours_rate(n: int, steps: int, warmup: int, threads: int) -> float:
    from morl_trl.envs import make_env

    env = make_env(f"MOSuperMarioBros-{STAGE[0]}-{STAGE[1]}-v2", num_envs=n, num_threads=threads)
    rate = _run_ours(env, _actions(warmup + steps, n), warmup)
    env.close()
    return rate


def _make_half(n):
    from morl_trl.envs import make_env

    return make_env(f"MOSuperMarioBros-{STAGE[0]}-{STAGE[1]}-v2", num_envs=n, num_threads=1)


def processes_rate(n: int, steps: int, warmup: int) -> float:
    import functools

    from torchrl.envs import ParallelEnv

    env = ParallelEnv(2, functools.partial(_make_half, n // 2), mp_start_method="fork")
    try:
        return _run_ours(env, _actions(warmup + steps, n), warmup)
    finally:
        env.close()


def stage_costs(reps: int = 1000) -> tuple[float, float, float]:
    """Seconds to start a stage emulator (title screen -> stage), to reset one (restore its
    snapshot), and to emulate one frame."""
    from morl_trl.envs.mario.game import MarioStage

    start = time.perf_counter()
    games = [MarioStage(w, l) for w, l in ((1, 1), (3, 3), (8, 4))]
    started = (time.perf_counter() - start) / len(games)
    game = games[0]
    start = time.perf_counter()
    for _ in range(reps):
        game.reset()
    reset = (time.perf_counter() - start) / reps
    start = time.perf_counter()
    for _ in range(reps // 4):
        game.nes.step(0x80)
    frame = (time.perf_counter() - start) / (reps // 4)
    for g in games:
        g.close()
    return started, reset, frame


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer steps, no worker processes")
    parser.add_argument("--steps", type=int, default=None, help="timed agent steps per emulator")
    args = parser.parse_args()
    steps = args.steps or (100 if args.quick else 400)
    warmup = 10
    torch.set_num_threads(1)  # the frame pipeline is small; keep the cores for the emulators

    started, reset, frame = stage_costs()
    print(
        f"stage start {started * 1e3:.0f} ms (kept in a pool), reset by restore {reset * 1e6:.0f} us, "
        f"one emulated frame {frame * 1e3:.2f} ms"
    )
    print(f"MO-SuperMarioBros stage {STAGE[0]}-{STAGE[1]}, {steps} timed agent steps (x4 frames) per emulator")
    header = f"{'N':>3} {'raw loop':>10} {'ours 1 thr':>16} {'ours 2 thr':>16}"
    if not args.quick:
        header += f" {'ours 2 procs':>18}"
    print(header + "   (agent steps/s, ratio to the raw loop)")
    for n in (1, 2, 4):
        raw = raw_rate(n, steps, warmup)
        one = ours_rate(n, steps, warmup, threads=1)
        two = ours_rate(n, steps, warmup, threads=2)
        line = f"{n:>3} {raw:>10.0f} {one:>9.0f} ({one / raw:4.2f}x) {two:>9.0f} ({two / raw:4.2f}x)"
        if not args.quick:
            if n >= 2:
                proc = processes_rate(n, steps, warmup)
                line += f" {proc:>11.0f} ({proc / raw:4.2f}x)"
            else:
                line += f" {'-':>18}"
        print(line, flush=True)


if __name__ == "__main__":
    main()
