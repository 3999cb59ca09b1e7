"""Gradient updates per second of GPI-LS / GPI-PD against MORL-Baselines' ``GPIPD.update``, in one run.

Each figure is one full update as the training loop runs it, replay sampling and priority
updates included, at the paper's MO-LunarLander settings: observation 26 (8 x 3 with the
state-action history + 2), 4 actions, 4 objectives, the authors' Q-network (``[256] * 4``,
ensemble of 2, dropout 0.01, LayerNorm), batch 128 doubled over a support of 6 weights,
prioritized replay (alpha 0.6, min priority 0.01). ``gpi_ls``: TD priorities; ``gpi_pd``:
GPI priorities (the GPI target over ``w`` and 4 support weights; the Dyna part is not timed).
Ours: :func:`morl_trl.algorithms.gpi.recipe.update` (what ``morl-trl train`` runs: :class:`~morl_trl.objectives.GPILoss`,
the recipe's Adam step, ``TensorDictReplayBuffer`` with ``morl_trl.data.prioritized_sampler``).

The peer is MORL-Baselines' own ``GPIPD.update(weight)`` (``gpi_pd=False/True``, ``dyna=False``),
driven on a filled buffer. MORL-Baselines imports ``pycddlib==2.1.6`` (``cdd``), ``cvxpy``
and ``seaborn`` at module level for its linear support and plots; ``update`` uses none of
them, so this script puts empty stand-ins for those three modules in ``sys.modules`` before
importing it (so it runs where the old pycddlib does not build). Install it as for bench_losses.py:

    python benchmarks/parity/run_parity.py --mb-venv /tmp/mbvenv --mb-venv-only
    OMP_NUM_THREADS=1 /tmp/mbvenv/bin/python benchmarks/bench_gpi.py --threads 1 --clock cpu [--quick]

Ours and the peer alternate in rounds (median over rounds).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import types
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tensordict import TensorDict  # noqa: E402
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer  # noqa: E402

from morl_trl.data import prioritized_sampler  # noqa: E402
from morl_trl.objectives import GPILoss, GPIPolicy, GPIQNetwork  # noqa: E402
from morl_trl.recipes import resolve_config  # noqa: E402
from morl_trl.algorithms.gpi.recipe import GPIAgent, update  # noqa: E402
from morl_trl.training.optim import adam, fused_choice  # noqa: E402

OBS, ACTIONS, K, NET, BATCH, GAMMA, LR = 26, 4, 4, [256, 256, 256, 256], 128, 0.99, 3e-4
CLOCK = time.perf_counter


def _support(rng):
    w = np.concatenate([np.eye(K), rng.dirichlet(np.ones(K), 2)])
    return w.astype(np.float32)


def _transitions(n, rng):
    return dict(obs=rng.standard_normal((n, OBS)).astype(np.float32), action=rng.integers(0, ACTIONS, n),
                reward=rng.standard_normal((n, K)).astype(np.float32),
                next_obs=rng.standard_normal((n, OBS)).astype(np.float32), done=rng.random(n) < 0.01)


def ours(tr, support, buffer_size, gpi_pd):
    """:func:`morl_trl.algorithms.gpi.recipe.update`, the recipe's update, on a :class:`~morl_trl.algorithms.gpi.recipe.GPIAgent`
    at these settings (the recipe's Adam) over a filled prioritized buffer."""
    torch.manual_seed(0)
    qnet = GPIQNetwork(OBS, ACTIONS, K, hidden=tuple(NET))
    loss = GPILoss(qnet, gpi_pd=gpi_pd)
    loss.make_value_estimator(gamma=GAMMA)
    cfg = resolve_config("gpi_pd" if gpi_pd else "gpi_ls", "MOLunarLanderDR-v0", batch_size=BATCH, lr=LR)
    agent = GPIAgent(cfg, loss, GPIPolicy(qnet, include_preference=True), GPIPolicy(qnet, dropout=False),
                     {"qvalue": adam(loss.value_network_params.values(True, True), LR, fused=fused_choice(cfg))},
                     device=torch.device("cpu"), exploration_module=None, gamma=GAMMA, preference_transform=None,
                     num_actions=ACTIONS)
    loss.set_weights(torch.as_tensor(support[0]), torch.as_tensor(support))  # (a mid-run support, not the first)
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(buffer_size),
                                    sampler=prioritized_sampler(buffer_size, alpha=0.6, beta=0.4),
                                    batch_size=BATCH, priority_key="td_error")
    n = len(tr["obs"])
    done = torch.as_tensor(tr["done"]).reshape(n, 1)
    buffer.extend(TensorDict({"observation": torch.as_tensor(tr["obs"]), "action": torch.as_tensor(tr["action"]),
                              ("next", "observation"): torch.as_tensor(tr["next_obs"]),
                              ("next", "reward"): torch.as_tensor(tr["reward"]),
                              ("next", "terminated"): done, ("next", "done"): done}, [n]))
    return lambda: update(agent, buffer)


def morl_baselines_peer(tr, support, buffer_size, gpi_pd):
    for name in ("cdd", "cvxpy", "seaborn"):  # linear-support solvers and plots: unused by update()
        stub = types.ModuleType(name)
        stub.SolverError = RuntimeError
        sys.modules.setdefault(name, stub)
    import gymnasium as gym
    from morl_baselines.multi_policy.gpi_pd.gpi_pd import GPIPD

    class SpacesOnly(gym.Env):
        def __init__(self):
            self.observation_space = gym.spaces.Box(-np.inf, np.inf, (OBS,), np.float32)
            self.action_space = gym.spaces.Discrete(ACTIONS)
            self.reward_space = gym.spaces.Box(-np.inf, np.inf, (K,), np.float32)

    agent = GPIPD(SpacesOnly(), learning_rate=LR, gamma=GAMMA, batch_size=BATCH, net_arch=NET, num_nets=2,
                  buffer_size=buffer_size, per=True, gpi_pd=gpi_pd, dyna=False, learning_starts=0,
                  target_net_update_freq=1000, log=False, seed=0, device="cpu")
    for i in range(len(tr["obs"])):
        agent.replay_buffer.add(tr["obs"][i], tr["action"][i], tr["reward"][i], tr["next_obs"][i], tr["done"][i])
    agent.set_weight_support(list(support))
    w = torch.as_tensor(support[0])
    agent.global_step = 1  # below dynamics_rollout_starts: one gradient update per call

    def step():
        agent.update(w)

    return step


def rate(step, n):
    t = CLOCK()
    for _ in range(n):
        step()
    return n / (CLOCK() - t)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a short sanity run (1 round of 8 updates)")
    p.add_argument("--updates", type=int, default=40)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--threads", type=int, default=None)
    p.add_argument("--clock", choices=["wall", "cpu"], default="wall")
    args = p.parse_args(argv)
    global CLOCK
    CLOCK = time.perf_counter if args.clock == "wall" else time.process_time
    if args.threads:
        torch.set_num_threads(args.threads)
    warmup, updates, rounds = (2, 8, 1) if args.quick else (5, args.updates, args.rounds)
    buffer_size, filled = (4_096, 4_096) if args.quick else (100_000, 20_000)
    rng = np.random.default_rng(0)
    tr, support = _transitions(filled, rng), _support(rng)
    from importlib.metadata import version

    print(f"peer: MORL-Baselines {version('morl-baselines')} GPIPD.update (cdd/cvxpy/seaborn stubbed); "
          f"torch {torch.__version__}, {torch.get_num_threads()} thread(s), clock {args.clock}")
    print(f"{'algo':<10} {'ours up/s':>12} {'peer up/s':>12} {'ratio':>8}")
    for name, pd in (("gpi_ls", False), ("gpi_pd", True)):
        a, b = ours(tr, support, buffer_size, pd), morl_baselines_peer(tr, support, buffer_size, pd)
        for _ in range(warmup):
            a()
            b()
        ra, rb = [], []
        for _ in range(rounds):
            ra.append(rate(a, updates))
            rb.append(rate(b, updates))
        x, y = statistics.median(ra), statistics.median(rb)
        print(f"{name:<10} {x:>12.1f} {y:>12.1f} {x / y:>8.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
