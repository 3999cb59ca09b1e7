"""Throughput of the batched MO-LunarLander against the raw single Gymnasium env.

Measures, in one run, sub-env steps per second of

* ``gymnasium.make("LunarLander-v3", enable_wind=True)``: one env, random actions
  (pre-drawn, so the peer pays nothing for sampling), reset when an episode ends;
* ``mo_gymnasium.make("mo-lunar-lander-v3", enable_wind=True)``: the same with the vector reward;
* ``morl_trl.envs.make_env("MOLunarLanderDR-v0", num_envs=N)`` for N in 1, 16, 64: random
  actions from the action spec (pre-drawn too), ``env.step_and_maybe_reset`` (``step`` + ``step_mdp`` + a
  partial reset of the finished sub-envs, each with a fresh random context drawn by
  ``DomainRandomization``);

and prints each rate with its ratio to the Gymnasium env. Same physics on both sides: wind
and turbulence on, Box2D ``Step`` with 180/60 iterations, no exhaust particles.

The configurations are measured in interleaved rounds and the best round of each is kept,
so that a burst of load from other processes hurts all of them alike. Besides wall-clock
rates the table shows rates per second of this process's CPU time, which a shared machine
disturbs less.

    python benchmarks/bench_lunar_lander.py            # ~1 min
    python benchmarks/bench_lunar_lander.py --quick    # ~15 s
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections.abc import Callable

import numpy as np
import torch


def _clock(run: Callable[[], int]) -> tuple[float, float]:
    """(steps per wall second, steps per CPU second) of one call of ``run``."""
    wall, cpu = time.perf_counter(), time.process_time()
    steps = run()
    return steps / (time.perf_counter() - wall), steps / max(time.process_time() - cpu, 1e-9)


def gymnasium_runner(make: Callable, steps: int, seed: int = 0) -> Callable[[], int]:
    env = make()
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)

    def run() -> int:
        for a in rng.integers(0, 4, size=steps).tolist():
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                env.reset()
        return steps

    run()  # warm-up
    return run


def morl_trl_runner(num_envs: int, steps: int, seed: int = 0) -> Callable[[], int]:
    from morl_trl.envs import make_env

    env = make_env(ENV_ID, num_envs=num_envs, seed=seed)
    torch.manual_seed(seed)
    spec = env.action_spec
    actions = torch.stack([spec.rand() for _ in range(steps)])  # pre-drawn, as for the peer
    state = {"td": env.reset()}

    def run() -> int:
        td = state["td"]
        for action in actions:
            td["action"] = action
            _, td = env.step_and_maybe_reset(td)
        state["td"] = td
        return steps * num_envs

    run()  # warm-up
    return run


def _cpu_us(fn: Callable[[], object], calls: int, setup: Callable[[], object] = lambda: None) -> float:
    """Best of 5 (each after ``setup``) of the mean CPU microseconds of ``calls`` calls."""
    best = float("inf")
    for _ in range(5):
        setup()
        start = time.process_time()
        for _ in range(calls):
            fn()
        best = min(best, (time.process_time() - start) / calls * 1e6)
    return best


def breakdown(num_envs: int) -> None:
    """CPU microseconds per call of the pieces of one batched step and one partial reset."""
    from torchrl.envs.utils import step_mdp

    from morl_trl.envs import make_env
    from morl_trl.envs.lunar_lander import physics

    env = make_env("MOLunarLanderDR-v0", num_envs=num_envs, seed=0)
    base = env.base_env
    noop = torch.zeros(num_envs, dtype=torch.long)
    td = env.reset().set("action", noop)
    calls = 30  # no-op steps from a fresh reset: every lander is still in the air

    box2d = _cpu_us(lambda: [w.world.Step(physics.TIME_STEP, 180, 60) for w in base._worlds], calls, env.reset)
    domain = _cpu_us(lambda: base._step_subenvs(noop), calls, env.reset)
    full = _cpu_us(lambda: env.step(td.clone()), calls, env.reset)
    one = torch.zeros(num_envs, 1, dtype=torch.bool)
    one[0] = True
    reset_td = step_mdp(env.step(td.clone())).set("_reset", one)
    reset = _cpu_us(lambda: env.reset(reset_td.clone()), calls)
    world = _cpu_us(lambda: base._reset_subenvs(torch.tensor([0]), base._context[:1]), calls)
    rows = [
        (f"Box2D world.Step x{num_envs}", box2d),
        ("domain step (_step_subenvs, incl. those Steps)", domain),
        ("env.step (TorchRL + base class + DR transform)", full),
        ("partial reset of 1 sub-env through env.reset", reset),
        ("  of which the domain's world rebuild", world),
    ]
    print(f"\nCPU us per call at num_envs={num_envs} (landers in the air):")
    for name, us in rows:
        print(f"  {name:<50}{us:8.0f}")


ENV_ID = "MOLunarLanderDR-v0"  # --context default: MOLunarLanderDefault-v0, the peer's exact physics


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps and rounds (~15 s)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 16, 64])
    parser.add_argument("--rounds", type=int, default=None)
    parser.add_argument("--breakdown", action="store_true", help="also print where one step's time goes")
    parser.add_argument("--context", choices=("dr", "default"), default="dr",
                        help="dr: domain-randomized (MOLunarLanderDR-v0); default: the fixed default context")
    args = parser.parse_args()
    global ENV_ID
    ENV_ID = "MOLunarLanderDR-v0" if args.context == "dr" else "MOLunarLanderDefault-v0"
    torch.set_num_threads(1)
    warnings.filterwarnings("ignore")
    rounds = args.rounds or (2 if args.quick else 5)
    sub_env_steps = 1_000 if args.quick else 4_000  # per configuration and round

    import gymnasium as gym

    runners: dict[str, Callable[[], int]] = {
        "gymnasium LunarLander-v3 (1 env)": gymnasium_runner(
            lambda: gym.make("LunarLander-v3", enable_wind=True), sub_env_steps
        )
    }
    try:
        import mo_gymnasium as mo_gym

        runners["mo-gymnasium mo-lunar-lander-v3 (1 env)"] = gymnasium_runner(
            lambda: mo_gym.make("mo-lunar-lander-v3", enable_wind=True), sub_env_steps
        )
    except ImportError:
        pass
    for n in args.sizes:
        runners[f"morl_trl {ENV_ID} num_envs={n}"] = morl_trl_runner(n, max(sub_env_steps // n, 20))

    best = {name: (0.0, 0.0) for name in runners}
    for _ in range(rounds):
        for name, run in runners.items():
            wall, cpu = _clock(run)
            best[name] = (max(best[name][0], wall), max(best[name][1], cpu))

    base_wall, base_cpu = next(iter(best.values()))
    print(f"\nbest of {rounds} interleaved rounds, {sub_env_steps} sub-env steps each")
    print(f"{'environment':<44}{'steps/s (wall)':>15}{'ratio':>8}{'steps/s (CPU)':>15}{'ratio':>8}")
    print("-" * 90)
    for name, (wall, cpu) in best.items():
        print(f"{name:<44}{wall:>15,.0f}{wall / base_wall:>7.2f}x{cpu:>15,.0f}{cpu / base_cpu:>7.2f}x")
    print("\nratio = rate / gymnasium LunarLander-v3's; target: >= 1.0 at num_envs=16")
    if args.breakdown:
        breakdown(16)


if __name__ == "__main__":
    main()
