"""Learning throughput of PCN and PGMORL against MORL-Baselines' implementations, measured in one run.

Each figure is the learning work of a training loop on filled data, environment stepping excluded
(both sides step their own simulators; that is benchmarked in bench_mujoco.py / bench_lunar_lander.py):

* **PCN updates/s** at the paper's MO-LunarLander settings: observation 26 (8 x 3 with the
  state-action history + 2), 4 actions, 4 objectives, hidden 64, batch 256, a replay of 1000
  episodes of 100-300 steps. Ours: ``recipes.pcn.update`` (``EpisodeReplay.sample`` + ``PCNLoss``
  + Adam). Peer: MORL-Baselines' ``PCN.update()`` on the same episodes.
* **PCN commands/s**: choosing a command on that replay (ranking every episode: crowding
  distance, non-dominated set, distances) -- ours ``EpisodeReplay.choose_command(1000)``, the
  peer ``PCN._choose_commands(1000)``.
* **PGMORL iteration learning, frames/s**: one iteration's learning of the whole population at the
  Hopper settings (population 6, 4 envs x 2048 steps per member, observation 39, 3 actions, 3
  objectives, 4 x 256 tanh MLPs, 10 epochs x 32 minibatches): ours ``recipes.pgmorl.on_batch`` (one
  batched population, vector GAE, ``ClipPPOLoss``); the peer runs, for each of the 6 members,
  MORL-Baselines' ``MOPPO`` advantage computation and ``update()`` on its own filled batch.
  Frames/s = 6 x 4 x 2048 / seconds.

The peer needs ``morl_baselines`` importable: run this script with the python of the scratch venv
that reuses our torch (``python benchmarks/parity/run_parity.py --mb-venv /tmp/mbvenv --mb-venv-only``). Ours and
the peer alternate in rounds; the median over rounds is reported, and the ratio ours / peer.

    /tmp/mbvenv/bin/python benchmarks/bench_pcn_pgmorl.py [--quick] [--threads 1]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import types
import warnings
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


warnings.filterwarnings("ignore")

OBS, ACTIONS, K, HIDDEN, BATCH = 26, 4, 4, 64, 256


def _episodes(n, rng):
    eps = []
    for _ in range(n):
        T = int(rng.integers(100, 300))
        obs = rng.normal(size=(T, OBS)).astype(np.float32)
        act = rng.integers(0, ACTIONS, T)
        rew = rng.normal(size=(T, K)).astype(np.float32)
        eps.append((obs, act, rew))
    return eps


# ---------------------------------------------------------------------- ours
def ours_pcn(eps):
    from morl_trl.recipes import resolve_config
    from morl_trl.algorithms.pcn.recipe import make_pcn_agent, make_pcn_training_env

    cfg = resolve_config("pcn", "MOLunarLanderDR-v0", num_envs=1)
    env = make_pcn_training_env(cfg, torch.device("cpu"))
    agent = make_pcn_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
    for o, a, r in eps:
        agent.replay.add(torch.from_numpy(o), torch.from_numpy(a), torch.from_numpy(r))
    return agent


def ours_pgmorl(quick):
    from tensordict import TensorDict

    from morl_trl.recipes import resolve_config
    from morl_trl.algorithms.pgmorl.recipe import make_pgmorl_agent, make_pgmorl_training_env

    steps = 256 if quick else 2048
    cfg = resolve_config("pgmorl", "MOHopperDR-v5", frames_per_batch=24 * steps)
    env = make_pgmorl_training_env(cfg, torch.device("cpu"))
    agent = make_pgmorl_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
    N, T, obs = 24, steps, env.observation_spec["observation"].shape[-1]
    g = torch.Generator().manual_seed(0)
    batch = TensorDict({
        "observation": torch.randn(N, T, obs, generator=g), "action": torch.randn(N, T, 3, generator=g).clamp(-1, 1),
        "next": {"observation": torch.randn(N, T, obs, generator=g), "reward": torch.randn(N, T, 3, generator=g),
                 "done": torch.zeros(N, T, 1, dtype=torch.bool), "terminated": torch.zeros(N, T, 1, dtype=torch.bool),
                 "episode_discounted_return": torch.zeros(N, T, 3)},
    }, [N, T])
    with torch.no_grad():
        batch.set("action_log_prob", agent.actor.get_dist(batch.select("observation")).log_prob(batch["action"]))
    return agent, batch, obs


# ---------------------------------------------------------------------- the peer (MORL-Baselines)
def peer_pcn(eps):
    import gymnasium as gym
    from morl_baselines.multi_policy.pcn.pcn import PCN, Transition

    class Spaces(gym.Env):
        observation_space = gym.spaces.Box(-np.inf, np.inf, (OBS,), np.float32)
        action_space = gym.spaces.Discrete(ACTIONS)
        reward_space = gym.spaces.Box(-np.inf, np.inf, (K,), np.float32)

    pcn = PCN(Spaces(), scaling_factor=np.full(K + 1, 0.1), batch_size=BATCH, hidden_dim=HIDDEN, gamma=0.99,
              log=False, seed=0, device="cpu")
    step = 0
    for o, a, r in eps:
        trans = [Transition(o[t], int(a[t]), r[t].copy(), o[t], False) for t in range(len(o))]
        step += len(trans)
        pcn._add_episode(trans, max_size=100_000, step=step)
    return pcn


def peer_moppo(obs_dim, quick):
    from morl_baselines.single_policy.ser.mo_ppo import MOPPO, MOPPONet

    steps = 256 if quick else 2048
    agents = []
    for i in range(6):
        net = MOPPONet((obs_dim,), (3,), 3, [256] * 4)
        envs = types.SimpleNamespace(num_envs=4)
        ag = MOPPO(i, net, np.array([1 / 3] * 3, dtype=np.float32), envs, log=False, steps_per_iteration=steps,
                   gamma=0.99, device="cpu", seed=i)
        for _ in range(steps):
            o = torch.randn(4, obs_dim)
            with torch.no_grad():
                a, lp, _, v = net.get_action_and_value(o)
            ag.batch.add(o, a, lp, torch.randn(4, 3), torch.zeros(4), v)
        agents.append(ag)
    return agents


def peer_moppo_iteration(agents, obs_dim):
    for ag in agents:
        ag.returns, ag.advantages = ag._MOPPO__compute_advantages(torch.randn(4, obs_dim), torch.zeros(4))
        ag.update()


# ---------------------------------------------------------------------- timing
def clock(kind):
    return time.process_time if kind == "cpu" else time.perf_counter


def rate(fn, n, timer):
    t0 = timer()
    for _ in range(n):
        fn()
    return n / max(timer() - t0, 1e-9)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="fewer rounds, 256 PPO steps per env instead of 2048")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--clock", choices=("wall", "cpu"), default="cpu")
    p.add_argument("--rounds", type=int, default=None)
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    timer = clock(args.clock)
    rounds = args.rounds or (3 if args.quick else 5)
    try:
        import morl_baselines  # noqa: F401
    except ImportError:
        sys.exit("morl_baselines is not importable: run with the scratch venv's python (see the docstring)")

    from morl_trl.algorithms.pcn import recipe as pcn
    from morl_trl.algorithms.pgmorl import recipe as pgmorl

    rng = np.random.default_rng(0)
    eps = _episodes(1000, rng)
    ours, peer = ours_pcn(eps), peer_pcn(eps)
    n_upd = 50 if args.quick else 200
    res = {"pcn updates/s": ([], []), "pcn commands/s": ([], []), "pgmorl learning frames/s": ([], [])}
    for _ in range(rounds):
        res["pcn updates/s"][0].append(rate(lambda: pcn.update(ours), n_upd, timer))
        res["pcn updates/s"][1].append(rate(lambda: peer.update(), n_upd, timer))
        res["pcn commands/s"][0].append(rate(lambda: ours.replay.choose_command(1000), 3, timer))
        res["pcn commands/s"][1].append(rate(lambda: peer._choose_commands(1000), 3, timer))
    agent, batch, obs_dim = ours_pgmorl(args.quick)
    agents = peer_moppo(obs_dim, args.quick)
    frames = batch.numel()
    for _ in range(max(1, rounds // 2 if not args.quick else 1)):
        t0 = timer()
        agent.iteration = 1  # (no evolution step inside the timed learning)
        pgmorl.on_batch(agent, batch, None, frames)
        res["pgmorl learning frames/s"][0].append(frames / (timer() - t0))
        t0 = timer()
        peer_moppo_iteration(agents, obs_dim)
        res["pgmorl learning frames/s"][1].append(frames / (timer() - t0))
    print(f"torch {torch.__version__}, threads {args.threads}, clock {args.clock}, rounds {rounds}"
          f"{', quick (256 PPO steps per env)' if args.quick else ''}; peer: MORL-Baselines "
          f"{getattr(morl_baselines, '__version__', '?')}")
    print(f"{'figure':<28}{'ours':>12}{'MORL-Baselines':>16}{'ratio':>8}")
    for name, (a, b) in res.items():
        ma, mb = statistics.median(a), statistics.median(b)
        print(f"{name:<28}{ma:>12.1f}{mb:>16.1f}{ma / mb:>8.2f}")


if __name__ == "__main__":
    main()
