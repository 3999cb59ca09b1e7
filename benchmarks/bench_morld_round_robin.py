"""MORL/D round robin: the acting member's own update, computed for that member alone against the
earlier masked update (every member computed, the step masked to the acting one), in one run.

Paper settings of MO-Hopper (``morl-trl config morld MOHopperDR-v5``: ``P = 6``, 4 x 256 MLPs,
batch 256, two vector critics, delayed actor ``policy_freq = 2``, learned temperature). The same
agent state and replay buffer (1,024 random transitions of the training env) serve both;
rounds alternate the two (sliced, masked, masked, sliced, ...) and each times ``--updates``
updates of member 1 (``morl_trl.algorithms.morld.recipe.update`` with ``agent.clock`` set as in training). Prints the
median updates/s of each and their ratio. One update per frame is what the round robin does
(``update_frequency = 1``), so the ratio bounds the end-to-end frames/s gain from above.

    nice -n 10 python benchmarks/bench_morld_round_robin.py [--updates 20] [--rounds 3] [--clock cpu]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer  # noqa: E402

from morl_trl.recipes import TRAINING_ENV_BUILDERS, resolve_config  # noqa: E402
from morl_trl.algorithms.morld import recipe as morld
from morl_trl.algorithms.morld.recipe import make_morld_agent  # noqa: E402


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="MOHopperDR-v5")
    p.add_argument("--updates", type=int, default=20, help="updates timed per round and mode")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--clock", choices=["wall", "cpu"], default="cpu")
    p.add_argument("--tiny", action="store_true", help="a seconds-long dry run (small networks)")
    args = p.parse_args(argv)
    warnings.filterwarnings("ignore")
    torch.set_num_threads(1)
    timer = time.process_time if args.clock == "cpu" else time.perf_counter
    extra = dict(hidden=(16,), batch_size=8) if args.tiny else {}
    cfg = resolve_config("morld", args.env, logger="none", progress=False, **extra)
    dev = torch.device("cpu")
    env = TRAINING_ENV_BUILDERS["morld"](cfg, dev)
    torch.manual_seed(0)
    data = env.rollout(1024, break_when_any_done=False).reshape(-1)
    agent = make_morld_agent(cfg, env, gamma=0.99, device=dev)
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(2048), batch_size=cfg.batch_size)
    buffer.extend(data.select(*agent.loss.in_keys, strict=False))
    agent.active_member.fill_(1)
    agent.members.copy_(torch.arange(agent.population) == 1)
    rates = {True: [], False: []}
    for r in range(args.rounds):
        for sliced in ((True, False) if r % 2 == 0 else (False, True)):
            agent.slice_acting_member = sliced
            t0 = timer()
            for i in range(args.updates):
                agent.clock = 20_000 + i  # (the shared frame counter: actor turns on even frames)
                morld.update(agent, buffer)
            agent.clock = None
            rates[sliced].append(args.updates / (timer() - t0))
    s, m = statistics.median(rates[True]), statistics.median(rates[False])
    print(f"morld round robin on {args.env}: P={cfg.pop_size}, hidden={tuple(cfg.hidden)}, batch={cfg.batch_size}, "
          f"{args.updates} updates x {args.rounds} rounds, 1 thread, {args.clock} clock")
    print(f"masked (every member computed): {m:8.2f} updates/s")
    print(f"sliced (the acting member only): {s:7.2f} updates/s   sliced/masked {s / m:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
