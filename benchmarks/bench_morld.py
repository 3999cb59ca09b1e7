"""MORL/D population updates per second: one batched update against P sequential MOSAC updates
and against MORL-Baselines' MORL/D, measured in one run.

One *population update* updates every one of the ``P`` members once (critics, actor,
temperature, Polyak targets), replay sampling included, at the paper's MO-Hopper settings:
``P = 6``, observation 39 (11 x 3 + 3 x 2 with the state-action history), 3 actions, 3
objectives, 4 x 256 MLPs, batch 256 per member, two vector critics, tau 0.005, learned
temperature, one shared replay buffer (MORL/D SB).

* **ours (batched)**: :class:`~morl_trl.objectives.population.PopulationMOSACLoss`: one
  ``[P, 256]`` sample of the shared ``TensorDictReplayBuffer``, one forward/backward, one Adam
  step per network kind, one ``SoftUpdate``.
* **ours (sequential)**: ``P`` separate :class:`~morl_trl.objectives.MOSACLoss` updates (networks
  without preference input, fixed preference ``w_p``), each with its own sample, optimizers
  and ``SoftUpdate``: what a Python loop over members costs.
* **MORL-Baselines**: its MORL/D steps its population one member at a time; one population
  update there is ``MOSAC.update()`` of each of the ``P`` members on their shared buffer
  (its defaults: ``policy_freq=2`` updates the actor twice every other call, the same actor
  work on average). Install it in a scratch environment that reuses our torch, as
  ``benchmarks/bench_losses.py`` explains::

      python benchmarks/parity/run_parity.py --mb-venv /tmp/mbvenv --mb-venv-only
      /tmp/mbvenv/bin/python benchmarks/bench_morld.py [--quick]

  Without it (``--peer recreation``, or ``auto`` when the import fails) the third column is
  skipped and the output says so (the sequential column is then the closest peer).

The three alternate in rounds so that machine load hits them alike; the median rate over rounds
is reported, with the ratios of ours (batched) to the other two.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from tensordict import TensorDict  # noqa: E402
from torchrl.data import Bounded, LazyTensorStorage, TensorDictReplayBuffer  # noqa: E402
from torchrl.objectives import SoftUpdate  # noqa: E402

from morl_trl.objectives import MOSACLoss, make_gaussian_actor, make_vector_critic  # noqa: E402
from morl_trl.objectives.population import (  # noqa: E402
    PopulationMOSACLoss,
    make_population_critic,
    make_population_gaussian_actor,
)
from morl_trl.preferences import energy_weights  # noqa: E402

warnings.filterwarnings("ignore", message="No target network updater")

NET = (256, 256, 256, 256)
LR = 3e-4
GAMMA = 0.99
HOPPER = dict(P=6, obs=39, act=3, k=3, batch=256, tau=0.005, alpha=0.2)


def transitions(n, device, seed=0):
    c = HOPPER
    g = np.random.default_rng(seed)
    return {
        "obs": g.standard_normal((n, c["obs"])).astype(np.float32),
        "next_obs": g.standard_normal((n, c["obs"])).astype(np.float32),
        "action": g.uniform(-1, 1, (n, c["act"])).astype(np.float32),
        "reward": g.standard_normal((n, c["k"])).astype(np.float32),
        "done": g.random(n) < 0.01,
    }


def _buffer(tr, size, device, batch=None):
    n = len(tr["obs"])
    t = {k: torch.as_tensor(v, device=device) for k, v in tr.items()}
    td = TensorDict({
        "observation": t["obs"], "action": t["action"],
        ("next", "observation"): t["next_obs"], ("next", "reward"): t["reward"],
        ("next", "done"): t["done"].view(n, 1), ("next", "terminated"): t["done"].view(n, 1)}, [n], device=device)
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(size, device=device), batch_size=batch)
    rb.extend(td)
    return rb


def _adam(loss):
    return [torch.optim.Adam(loss.actor_network_params.values(True, True), lr=LR),
            torch.optim.Adam(loss.qvalue_network_params.values(True, True), lr=LR),
            torch.optim.Adam([loss.log_alpha], lr=LR)]


def _update(loss, opts, updater, batch):
    out = loss(batch)
    total = out["loss_actor"] + out["loss_qvalue"] + out["loss_alpha"]
    for o in opts:
        o.zero_grad(set_to_none=True)
    total.backward()
    for o in opts:
        o.step()
    updater.step()


def ours_batched(tr, size, device):
    c = HOPPER
    spec = Bounded(-1.0, 1.0, (c["act"],), device=device)
    w = energy_weights(c["k"], c["P"], dtype=torch.float32)
    loss = PopulationMOSACLoss(make_population_gaussian_actor(c["P"], c["obs"], spec, num_cells=NET).to(device),
                               make_population_critic(c["P"], c["obs"], c["act"], c["k"], num_cells=NET).to(device),
                               weights=w, alpha_init=c["alpha"], action_spec=spec)
    loss.make_value_estimator(gamma=GAMMA)
    opts, upd = _adam(loss), SoftUpdate(loss, tau=c["tau"])
    rb = _buffer(tr, size, device)

    def step():
        _update(loss, opts, upd, rb.sample(c["P"] * c["batch"]).reshape(c["P"], c["batch"]))

    return step


def ours_sequential(tr, size, device):
    c = HOPPER
    spec = Bounded(-1.0, 1.0, (c["act"],), device=device)
    w = energy_weights(c["k"], c["P"], dtype=torch.float32)
    members = []
    for p in range(c["P"]):
        loss = MOSACLoss(make_gaussian_actor(c["obs"], spec, c["k"], num_cells=NET, preference_key=None).to(device),
                         make_vector_critic(c["obs"], c["act"], c["k"], num_cells=NET, preference_key=None).to(device),
                         num_objectives=c["k"], preference=w[p], alpha_init=c["alpha"], action_spec=spec)
        loss.make_value_estimator(gamma=GAMMA)
        members.append((loss, _adam(loss), SoftUpdate(loss, tau=c["tau"])))
    rb = _buffer(tr, size, device, batch=c["batch"])

    def step():
        for loss, opts, upd in members:
            _update(loss, opts, upd, rb.sample())

    return step


def mb_morld(tr, size, device):
    import gymnasium as gym
    from morl_baselines.single_policy.ser.mosac_continuous_action import MOSAC

    c = HOPPER

    class SpacesOnly(gym.Env):
        def __init__(self):
            self.observation_space = gym.spaces.Box(-np.inf, np.inf, (c["obs"],), np.float32)
            self.action_space = gym.spaces.Box(-1.0, 1.0, (c["act"],), np.float32)
            self.reward_space = gym.spaces.Box(-np.inf, np.inf, (c["k"],), np.float32)

    env = SpacesOnly()
    w = energy_weights(c["k"], c["P"]).numpy().astype(np.float32)
    pop = [MOSAC(env, w[p], scalarization=torch.matmul, buffer_size=size, gamma=GAMMA, tau=c["tau"],
                 batch_size=c["batch"], learning_starts=0, net_arch=list(NET), alpha=c["alpha"], autotune=True,
                 id=p, device=str(device), log=False, seed=p) for p in range(c["P"])]
    shared = pop[0].get_buffer()
    for m in pop:  # MORL/D's shared buffer
        m.set_buffer(shared)
    for i in range(len(tr["obs"])):
        shared.add(obs=tr["obs"][i], next_obs=tr["next_obs"][i], action=tr["action"][i], reward=tr["reward"][i],
                   done=tr["done"][i])
    for m in pop:
        m.global_step = 1

    def step():
        for m in pop:  # MORL/D steps its population one policy at a time
            m.global_step += 1
            m.update()

    return step


CLOCK = time.perf_counter


def rate(step, n, device):
    if device.type == "cuda":
        torch.cuda.synchronize()
    t = CLOCK()
    for _ in range(n):
        step()
    if device.type == "cuda":
        torch.cuda.synchronize()
    return n / (CLOCK() - t)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a short sanity run (1 round of 3 population updates)")
    p.add_argument("--peer", choices=["auto", "morl-baselines", "recreation"], default="auto")
    p.add_argument("--updates", type=int, default=10, help="population updates per round")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--device", default="cpu")
    p.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    p.add_argument("--clock", choices=["wall", "cpu"], default="wall",
                   help="wall time (default), or this process's CPU time (steadier on a shared machine, --threads 1)")
    args = p.parse_args(argv)
    global CLOCK
    CLOCK = time.perf_counter if args.clock == "wall" else time.process_time
    if args.threads:
        torch.set_num_threads(args.threads)
    device = torch.device(args.device)
    warmup, updates, rounds = (1, 3, 1) if args.quick else (3, args.updates, args.rounds)
    size, filled = (4_096, 4_096) if args.quick else (100_000, 20_000)
    peer = args.peer
    if peer in ("auto", "morl-baselines"):
        try:
            import morl_baselines  # noqa: F401

            peer = "morl-baselines"
        except ImportError as err:
            if args.peer == "morl-baselines":
                raise SystemExit(f"morl-baselines is not importable ({err}); see this script's docstring.")
            peer = "none"
    if peer == "morl-baselines":
        from importlib.metadata import version

        label = f"MORL-Baselines {version('morl-baselines')} (P x MOSAC.update() on a shared buffer)"
    else:
        label = "none (MORL-Baselines not importable: see the docstring)"
    torch.manual_seed(0)
    c = HOPPER
    print(f"torch {torch.__version__}, {device}, {torch.get_num_threads()} threads, {args.clock} clock; peer: {label}")
    print(f"P = {c['P']}, batch {c['batch']} per member, obs {c['obs']}, act {c['act']}, k {c['k']}, MLPs {list(NET)}; "
          f"{warmup} warm-up, then {rounds} round(s) of {updates} population updates, alternating; median")
    tr = transitions(filled, device)
    runs = {"ours (batched)": ours_batched(tr, size, device), "ours (sequential)": ours_sequential(tr, size, device)}
    if peer == "morl-baselines":
        runs["MORL-Baselines MORL/D"] = mb_morld(tr, size, device)
    for step in runs.values():
        for _ in range(warmup):
            step()
    rates = {name: [] for name in runs}
    for _ in range(rounds):
        for name, step in runs.items():
            rates[name].append(rate(step, updates, device))
    med = {name: statistics.median(r) for name, r in rates.items()}
    ours = med["ours (batched)"]
    print(f"{'':<24} {'pop. updates/s':>15} {'member updates/s':>17} {'batched / this':>15}")
    for name, r in med.items():
        print(f"{name:<24} {r:>15.2f} {r * c['P']:>17.1f} {ours / r:>14.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
