"""Throughput of the batched MO-LunarLander against the raw single Gymnasium env.

Measures, in one run, sub-env steps per second of

* ``gymnasium.make("LunarLander-v3", enable_wind=True)``: one env, random actions
  (pre-drawn, so the peer pays nothing for sampling), reset when an episode ends;
* ``mo_gymnasium.make("mo-lunar-lander-v3", enable_wind=True)``: the same with the vector reward;
* with ``--context dr`` (the default), the Gymnasium env again, given a fresh context from
  our DR space before each reset (gravity, wind and turbulence power, main and side engine
  power; its spawn point stays Gymnasium's): the same randomized physics as the DR id, whose
  episodes cost more to simulate than the default context's;
* ``morl_trl.envs.make_env(ENV_ID, num_envs=N)`` for N in 1, 16, 64 (``MOLunarLanderDR-v0``,
  or ``MOLunarLanderDefault-v0`` with ``--context default``, the peer's exact physics):
  random actions from the action spec (pre-drawn too), ``env.step_and_maybe_reset`` (what
  collectors call: ``step`` + ``step_mdp`` + a partial reset of the finished sub-envs, with
  a fresh random context each under domain randomization);

and prints each rate with its ratio to the Gymnasium env (and, under DR, to the DR peer).
Same physics on both sides: wind and turbulence on, Box2D ``Step`` with 180/60 iterations,
no exhaust particles (Gymnasium only makes them when rendering).

The configurations are measured in interleaved rounds and the best round of each is kept,
so that a burst of load from other processes hurts all of them alike. Besides wall-clock
rates the table shows rates per second of this process's CPU time, which a shared machine
disturbs less.

    python benchmarks/bench_lunar_lander.py                    # ~1 min
    python benchmarks/bench_lunar_lander.py --context default  # the fixed default context
    python benchmarks/bench_lunar_lander.py --quick            # ~15 s
    python benchmarks/bench_lunar_lander.py --breakdown        # + where one call's time goes
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


def gymnasium_runner(make: Callable, steps: int, seed: int = 0, before_reset: Callable | None = None) -> Callable[[], int]:
    env = make()
    rng = np.random.default_rng(seed)
    if before_reset is not None:
        before_reset(env)
    env.reset(seed=seed)

    def run() -> int:
        for a in rng.integers(0, 4, size=steps).tolist():
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                if before_reset is not None:
                    before_reset(env)
                env.reset()
        return steps

    run()  # warm-up
    return run


def dr_context_setter(seed: int = 0) -> Callable:
    """Before each reset of a Gymnasium LunarLander: a context drawn from our DR space."""
    import gymnasium.envs.box2d.lunar_lander as gym_lander

    from morl_trl.envs import context_space

    space = context_space("MOLunarLanderDR-v0")
    generator = torch.Generator().manual_seed(seed)

    def set_context(env) -> None:
        c = dict(zip(space.names, space.sample(1, generator=generator)[0].tolist()))
        lander = env.unwrapped
        lander.gravity, lander.wind_power, lander.turbulence_power = c["gravity"], c["wind_power"], c["turbulence_power"]
        # module constants in Gymnasium, read at every step
        gym_lander.MAIN_ENGINE_POWER, gym_lander.SIDE_ENGINE_POWER = c["main_engine_power"], c["side_engine_power"]

    return set_context


def _restore_gymnasium_constants() -> None:
    import gymnasium.envs.box2d.lunar_lander as gym_lander

    gym_lander.MAIN_ENGINE_POWER, gym_lander.SIDE_ENGINE_POWER = 13.0, 0.6


def morl_trl_runner(env_id: str, num_envs: int, steps: int, seed: int = 0) -> Callable[[], int]:
    from morl_trl.envs import make_env

    env = make_env(env_id, num_envs=num_envs, seed=seed)
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


def breakdown(env_id: str, num_envs: int) -> None:
    """CPU microseconds per call of the pieces of one batched step and one auto-reset."""
    from torchrl.envs import EnvBase

    from morl_trl.envs import make_env
    from morl_trl.envs.lunar_lander import physics

    env = make_env(env_id, num_envs=num_envs, seed=0)
    noop = torch.zeros(num_envs, dtype=torch.long)
    calls = 30  # no-op steps from a fresh reset: every lander is still in the air, none finishes
    box2d = _cpu_us(lambda: [w.world.Step(physics.TIME_STEP, 180, 60) for w in env._worlds], calls, env.reset)
    domain = _cpu_us(lambda: env._step_subenvs(noop), calls, env.reset)
    state = {}

    def fresh() -> None:
        state["td"] = env.reset().set("action", noop)

    def lean() -> None:
        state["td"] = env.step_and_maybe_reset(state["td"])[1].set("action", noop)

    def generic() -> None:
        state["td"] = EnvBase._step_and_maybe_reset(env, state["td"])[1].set("action", noop)

    lean_us = _cpu_us(lean, calls, fresh)
    generic_us = _cpu_us(generic, calls, fresh)
    one = torch.zeros(num_envs, dtype=torch.bool)
    one[0] = True
    reset_lean = _cpu_us(lambda: env._auto_reset(one), calls)
    td = env.reset()
    td["done"] = one[:, None].clone()
    reset_generic = _cpu_us(lambda: env.maybe_reset(td.clone()), calls)
    world = _cpu_us(lambda: env._reset_subenvs(torch.tensor([0]), env._context[:1]), calls)
    rows = [
        (f"Box2D world.Step x{num_envs}", box2d),
        ("domain step (_step_subenvs, incl. those Steps)", domain),
        ("env.step_and_maybe_reset (no sub-env done)", lean_us),
        ("  the same through TorchRL's generic path", generic_us),
        ("auto-reset of 1 sub-env (lean path)", reset_lean),
        ("  the same through TorchRL's maybe_reset", reset_generic),
        ("  of which the domain's world rebuild + no-op step", world),
    ]
    print(f"\nCPU us per call at num_envs={num_envs}, {env_id} (landers in the air):")
    for name, us in rows:
        print(f"  {name:<52}{us:8.0f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps and rounds (~15 s)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 16, 64])
    parser.add_argument("--rounds", type=int, default=None)
    parser.add_argument("--breakdown", action="store_true", help="also print where one step's time goes")
    parser.add_argument("--context", choices=("dr", "default"), default="dr",
                        help="dr: domain-randomized (MOLunarLanderDR-v0); default: the fixed default context")
    args = parser.parse_args()
    env_id = "MOLunarLanderDR-v0" if args.context == "dr" else "MOLunarLanderDefault-v0"
    torch.set_num_threads(1)
    warnings.filterwarnings("ignore")
    rounds = args.rounds or (2 if args.quick else 5)
    sub_env_steps = 1_000 if args.quick else 4_000  # per configuration and round

    import gymnasium as gym

    gym_name = "gymnasium LunarLander-v3 (1 env)"
    dr_name = "gymnasium LunarLander-v3, DR contexts"
    runners: dict[str, Callable[[], int]] = {
        gym_name: gymnasium_runner(lambda: gym.make("LunarLander-v3", enable_wind=True), sub_env_steps)
    }
    try:
        import mo_gymnasium as mo_gym

        runners["mo-gymnasium mo-lunar-lander-v3 (1 env)"] = gymnasium_runner(
            lambda: mo_gym.make("mo-lunar-lander-v3", enable_wind=True), sub_env_steps
        )
    except ImportError:
        pass
    if args.context == "dr":
        set_context = dr_context_setter()
        dr_run = gymnasium_runner(lambda: gym.make("LunarLander-v3", enable_wind=True), sub_env_steps,
                                  before_reset=set_context)

        def dr_peer() -> int:  # the engine powers are Gymnasium module constants: put them back after
            try:
                return dr_run()
            finally:
                _restore_gymnasium_constants()

        _restore_gymnasium_constants()
        runners[dr_name] = dr_peer
    for n in args.sizes:
        runners[f"morl_trl {env_id} num_envs={n}"] = morl_trl_runner(env_id, n, max(sub_env_steps // n, 20))

    best = {name: (0.0, 0.0) for name in runners}
    for _ in range(rounds):
        for name, run in runners.items():
            wall, cpu = _clock(run)
            best[name] = (max(best[name][0], wall), max(best[name][1], cpu))

    base_wall, base_cpu = best[gym_name]
    peer = best.get(dr_name)
    print(f"\nbest of {rounds} interleaved rounds, {sub_env_steps} sub-env steps each")
    header = f"{'environment':<44}{'steps/s (wall)':>15}{'ratio':>8}{'steps/s (CPU)':>15}{'ratio':>8}"
    print(header + (f"{'vs DR peer':>12}" if peer else ""))
    print("-" * (len(header) + (12 if peer else 0)))
    for name, (wall, cpu) in best.items():
        row = f"{name:<44}{wall:>15,.0f}{wall / base_wall:>7.2f}x{cpu:>15,.0f}{cpu / base_cpu:>7.2f}x"
        if peer:
            row += f"{wall / peer[0]:>11.2f}x"
        print(row)
    print(f"\nratio = rate / {gym_name}'s" + ("; vs DR peer = wall rate / the DR peer's" if peer else ""))
    print("target: >= 1.0 at num_envs=16")
    if args.breakdown:
        breakdown(env_id, 16)


if __name__ == "__main__":
    main()
