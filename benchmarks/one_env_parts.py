"""Per-call cost of the pieces of a one-env frame, in isolation: Envelope on deep-sea-treasure-v0 at the parity
case's settings (``[64, 64]``, batch 32, the prioritized buffer), process CPU time, one thread.

Prints ms per call of ``Agent.store`` (one collector batch), ``buffer.sample()``, ``update_tensordict_priority`` (32
priorities), the ε-greedy policy, the policy plus ``step_and_maybe_reset``, a reset of the transformed env, and the
loss's forward. In a training loop each costs two to three times this (the update evicts the caches between frames:
``benchmarks/profile_frame.py`` measures them there). Compare two checkouts by running it in each::

    python benchmarks/one_env_parts.py
    PYTHONPATH=/tmp/base python benchmarks/one_env_parts.py
"""

from __future__ import annotations

import argparse
import time

import torch


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--calls", type=int, default=2000, help="calls per piece")
    args = p.parse_args()
    torch.set_num_threads(1)
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    from morl_trl._torchrl_compat import new_tensordict_unsafe
    from morl_trl.algorithms.envelope.recipe import make_envelope_agent
    from morl_trl.recipes import resolve_config
    from morl_trl.training.parts import make_collector, make_replay_buffer, make_training_env

    cfg = resolve_config("envelope", "deep-sea-treasure-v0", hidden=[64, 64], batch_size=32, frames=10**6, seed=0)
    dev = torch.device("cpu")
    env = make_training_env(cfg, dev)
    agent = make_envelope_agent(cfg, env, gamma=0.99, device=dev)
    agent.exploration_module.eps.fill_(0.5)
    buffer = make_replay_buffer(cfg, dev)
    it = iter(make_collector(cfg, env, agent.explore_policy, dev, return_same_td=True))
    batch = None
    for _ in range(500):  # (a buffer with transitions to sample; the same batch stored again below)
        batch = next(it)
        agent.store(buffer, batch)
    sample = buffer.sample()
    sample["td_error"] = torch.rand(32, generator=torch.Generator().manual_seed(0))
    td = env.reset()
    reset = new_tensordict_unsafe({"_reset": torch.ones(*env.batch_size, 1, dtype=torch.bool)},
                                  batch_size=env.batch_size, device=env.device)
    state = {"td": td}

    def step():
        out, state["td"] = env.step_and_maybe_reset(agent.explore_policy(state["td"]))

    pieces = {
        "Agent.store (one batch)": lambda: agent.store(buffer, batch),
        "buffer.sample() (32)": buffer.sample,
        "update_tensordict_priority (32)": lambda: buffer.update_tensordict_priority(sample),
        "policy (eps-greedy)": lambda: agent.explore_policy(state["td"]),
        "policy + step_and_maybe_reset": step,
        "env reset (one sub-env)": lambda: env._reset(reset.clone()),
        "Envelope loss forward": lambda: agent.loss(sample),
    }
    print(f"torch {torch.__version__}, 1 thread, process CPU time, {args.calls} calls per piece")
    with set_exploration_type(ExplorationType.RANDOM):
        for name, fn in pieces.items():
            fn()
            start = time.process_time()
            for _ in range(args.calls):
                fn()
            print(f"{name:34s} {(time.process_time() - start) / args.calls * 1e3:.3f} ms")


if __name__ == "__main__":
    main()
