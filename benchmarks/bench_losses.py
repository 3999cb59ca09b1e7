"""Gradient updates per second of the MORL losses against MORL-Baselines, measured in one run.

Each figure is a full update as a training loop runs it, replay sampling included:

* **Envelope** at the paper's MO-LunarLander settings: observation 26 (8 x 3 with the
  state-action history + 2), 4 actions, 4 objectives, 4 x 256 MLP, batch 128 x 8 sampled
  preferences, homotopy lambda 0.95, prioritized replay (alpha 0.6) with priority updates,
  gradient clipping at 1, hard target update every 1000 updates. Ours:
  ``EnvelopeQLoss`` + ``TensorDictReplayBuffer`` with ``morl_trl.data.prioritized_sampler``.
* **CAPQL** at the Hopper settings: observation 39 (11 x 3 + 3 x 2), 3 actions, 3
  objectives, 4 x 256 MLPs, batch 256, alpha 0.2, two vector critics, Polyak 0.005.
  Ours: ``CAPQLLoss`` + ``TensorDictReplayBuffer``.

* **GPI-LS / GPI-PD** at the MO-LunarLander settings (see :func:`ours_gpi`).
* **PCN** at MO-LunarLander ([pcn.lunarlander] in ../shared/reference/hyperparameters.toml):
  the authors' network (``net_arch = [256] * 4``), batch 256, lr 3e-4, on a replay of 1000
  episodes. Ours: ``recipes.pcn.update``; peer: ``PCN.update()`` with the authors' network.
* **MORL/D** (SB) at MO-Hopper ([morld_sb.hopper]): one *population update* = each of the 6
  members updated once (batch 256 each from the shared buffer, 4 x 256 MLPs, two critics,
  learned temperature). Ours: ``morl_trl.algorithms.morld.recipe.update`` (one batched step); peer: ``MOSAC.update()``
  of each member, as MORL-Baselines' MORL/D steps them.
* **PGMORL** at MO-Hopper ([pgmorl.hopper]): one *update* = one clipped-PPO minibatch step of the
  whole population (6 members, 4 envs x 2048 steps each, 10 epochs x 32 minibatches, 4 x 256 tanh
  MLPs); timed as whole iterations (GAE included) divided by their 320 updates. Ours:
  ``recipes.pgmorl.on_batch``; peer: each member's ``MOPPO`` advantages and ``update()``.

PCN, MORL/D and PGMORL are built as ``morl-trl train`` builds them (``resolve_config`` at the
paper's domain) and time on the CPU only. The peer is MORL-Baselines' ``Envelope.update()`` /
``CAPQL.update()`` / ... on the same settings, driven directly on a filled buffer. Install it in a scratch environment that
reuses our torch (``morl-baselines`` itself pulls an unpinned torch):

    python benchmarks/parity/run_parity.py --mb-venv /tmp/mbvenv --mb-venv-only   # the one place it is made (ensure_mb_venv)
    /tmp/mbvenv/bin/python benchmarks/bench_losses.py [--quick]

Without it (``--peer recreation``, or ``auto`` when the import fails) the peer is our
re-creation of its update loops (same networks, same tensor work: the target network
evaluated on batch x N x N rows for Envelope, separate critic/actor passes for CAPQL),
and the output says so.

Ours is the recipe's own ``update`` as ``morl-trl train`` runs it (fused Adam, sampling and priority updates
included). ``--device cuda`` runs ours (and MORL-Baselines, when installed) on the GPU and adds
rows for the captured update (``compile``, ``cudagraphs``, ``both``: see
``morl_trl.training.capture``) with their speed-up over the eager one:

    python benchmarks/bench_losses.py --device cuda [--capture cudagraphs both]

Ours and the peer alternate in rounds so that machine load hits both alike; the
median rate over rounds is reported. Both run in this one process, under the same allocator
settings: ``--malloc tuned`` (default) sets glibc's thresholds as a trainer does
(``morl_trl.training.allocator``), ``--malloc default`` leaves glibc's own. On a shared machine, ``--threads 1 --clock cpu``
(process CPU time) gives steadier figures than wall time.
"""

from __future__ import annotations

import argparse
import math
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
from torchrl.objectives import HardUpdate  # noqa: E402

from morl_trl.data import prioritized_sampler  # noqa: E402
from morl_trl.training.agent import adam  # noqa: E402
from morl_trl.objectives import (  # noqa: E402
    CAPQLLoss,
    EnvelopeQLoss,
    PolyakUpdate,
    make_gaussian_actor,
    make_vector_critic,
    make_vector_q_network,
)

warnings.filterwarnings("ignore", message="No target network updater")

NET = [256, 256, 256, 256]
LR = 3e-4
GAMMA = 0.99
ENVELOPE = dict(obs=26, actions=4, k=4, batch=128, n_w=8, lam=0.95, per_alpha=0.6, target_every=1000)
CAPQL = dict(obs=39, act=3, k=3, batch=256, alpha=0.2, tau=0.005)
GPI = dict(obs=26, actions=4, k=4, batch=128, per_alpha=0.6)
#: overrides of the recipes' configs (PCN, MORL/D, PGMORL); ``--tiny`` fills it
RECIPE_OVERRIDES: dict = {}


def make_tiny() -> None:
    """``--tiny``: every network 2 x 16 and every batch 16 (PGMORL: one epoch of two minibatches),
    so that the dry run's cost is a few seconds of work on any CPU: it checks that every row runs,
    not how fast (the settings above are the paper's, for measuring)."""
    NET[:] = [16, 16]
    for c in (ENVELOPE, CAPQL, GPI):
        c["batch"] = 16
    RECIPE_OVERRIDES.update(hidden=(16, 16), batch_size=16, pgmorl_epochs=1, pgmorl_minibatches=2)


def random_transitions(n, obs, k, *, num_actions=None, act_dim=None, seed=0):
    g = np.random.default_rng(seed)
    out = {
        "obs": g.standard_normal((n, obs)).astype(np.float32),
        "next_obs": g.standard_normal((n, obs)).astype(np.float32),
        "reward": g.standard_normal((n, k)).astype(np.float32),
        "done": (g.random(n) < 0.01),
        "w": np.abs(g.standard_normal((n, k))).astype(np.float32),
    }
    out["w"] /= out["w"].sum(1, keepdims=True)
    if num_actions is not None:
        out["action"] = g.integers(num_actions, size=n)
    else:
        out["action"] = g.uniform(-1, 1, (n, act_dim)).astype(np.float32)
    return out


def as_tensordict(tr) -> TensorDict:
    n = len(tr["obs"])
    done = torch.as_tensor(tr["done"]).unsqueeze(-1)
    return TensorDict(
        {
            "observation": torch.as_tensor(tr["obs"]),
            "action": torch.as_tensor(tr["action"]),
            "preference": torch.as_tensor(tr["w"]),
            ("next", "observation"): torch.as_tensor(tr["next_obs"]),
            ("next", "reward"): torch.as_tensor(tr["reward"]),
            ("next", "done"): done,
            ("next", "terminated"): done.clone(),
        },
        [n],
    )


# ------------------------------------------------------------------------------------ ours
def _agent_step(recipe, loss, optimizers, updater, rb, device, *, max_grad_norm=None, prioritized=False,
                capture=None):
    """The recipe's ``update`` (``recipe``: :mod:`morl_trl.algorithms.envelope.recipe` or
    :mod:`~morl_trl.algorithms.actor_critic.recipe`) on ``rb``, as ``morl-trl train`` runs it: eager, or captured
    (``"compile"``, ``"cudagraphs"``, ``"both"``) with the non-finite flag read every 100 updates."""
    from types import SimpleNamespace

    from morl_trl.training.agent import Agent

    cfg = SimpleNamespace(algo="bench", max_grad_norm=max_grad_norm, prioritized=prioritized, finite_check_interval=100,
                          compile=capture in ("compile", "both", "whole+compile"), compile_mode=None,
                          cudagraphs=capture in ("cudagraphs", "both", "whole", "whole+compile"),
                          capture_sampling=capture in ("whole", "whole+compile"), policy_freq=1, joint_update=False)
    agent = Agent(cfg, loss, None, None, optimizers, updater, device=device, capturable=True)

    def step():
        recipe.update(agent, rb)

    return step


def ours_envelope(tr, buffer_size, device=torch.device("cpu"), capture=None):
    c = ENVELOPE
    loss = EnvelopeQLoss(
        make_vector_q_network(c["obs"], c["actions"], c["k"], num_cells=NET),
        num_preference_samples=c["n_w"],
        homotopy_lambda=c["lam"],
        preference_distribution="gaussian",
    ).to(device)
    loss.make_value_estimator(gamma=GAMMA)
    updater = HardUpdate(loss, value_network_update_interval=c["target_every"])
    optim = adam(loss.parameters(), LR)
    # the whole-update graph needs the pure-torch trees (TorchRL's native ones read the host)
    sampler = prioritized_sampler(buffer_size, alpha=c["per_alpha"], beta=0.4, device=device,
                                  backend="torch" if capture and capture.startswith("whole") else "auto")
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(buffer_size, device=device), sampler=sampler,
                                batch_size=c["batch"])
    rb.extend(as_tensordict(tr).to(device))
    from morl_trl.algorithms.envelope import recipe as envelope

    step = _agent_step(envelope, loss, {"qvalue": optim}, updater, rb, device, max_grad_norm=1.0, prioritized=True,
                       capture=capture)
    return step, type(sampler).__name__


def ours_capql(tr, buffer_size, device=torch.device("cpu"), capture=None):
    c = CAPQL
    spec = Bounded(-1.0, 1.0, (c["act"],), device=device)
    loss = CAPQLLoss(
        make_gaussian_actor(c["obs"], spec, c["k"], num_cells=NET).to(device),
        make_vector_critic(c["obs"], c["act"], c["k"], num_cells=NET).to(device),
        alpha=c["alpha"],
    )
    loss.make_value_estimator(gamma=GAMMA)
    updater = PolyakUpdate(loss, tau=c["tau"])
    optimizers = {"actor": adam(loss.actor_network_params.values(True, True), LR),
                  "qvalue": adam(loss.qvalue_network_params.values(True, True), LR)}
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(buffer_size, device=device), batch_size=c["batch"])
    rb.extend(as_tensordict(tr).to(device))
    from morl_trl.algorithms.actor_critic import recipe as actor_critic

    return _agent_step(actor_critic, loss, optimizers, updater, rb, device, capture=capture)


def ours_gpi(tr, support, buffer_size, gpi_pd):
    """:func:`morl_trl.algorithms.gpi.recipe.update` (discrete, no model buffer), the recipe's update, at the MO-LunarLander
    settings: ``GPILoss`` on the authors' Q-network (ensemble of 2, dropout 0.01, LayerNorm), fused Adam,
    prioritized replay (alpha 0.6, min priority 0.01) with priority updates; ``gpi_pd``: GPI priorities over the
    support."""
    from morl_trl.objectives import GPILoss, GPIPolicy, GPIQNetwork
    from morl_trl.recipes import resolve_config
    from morl_trl.algorithms.gpi import recipe as gpi

    g = GPI
    qnet = GPIQNetwork(g["obs"], g["actions"], g["k"], hidden=tuple(NET), num_nets=2, dropout=0.01, layer_norm=True)
    loss = GPILoss(qnet, gpi_pd=gpi_pd, min_priority=0.01)
    loss.make_value_estimator(gamma=GAMMA)
    cfg = resolve_config("gpi_pd" if gpi_pd else "gpi_ls", "MOLunarLanderDR-v0", batch_size=g["batch"], lr=LR)
    agent = gpi.GPIAgent(cfg, loss, GPIPolicy(qnet, include_preference=True), GPIPolicy(qnet, dropout=False),
                         {"qvalue": adam(loss.value_network_params.values(True, True), LR)}, device=torch.device("cpu"),
                         exploration_module=None, gamma=GAMMA, preference_transform=None, num_actions=g["actions"])
    loss.set_weights(torch.as_tensor(support[0]), torch.as_tensor(support))  # (a mid-run support, not the first)
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(buffer_size),
                                sampler=prioritized_sampler(buffer_size, alpha=g["per_alpha"], beta=0.4),
                                batch_size=g["batch"], priority_key="td_error")
    rb.extend(as_tensordict(tr).exclude("preference"))
    return lambda: gpi.update(agent, rb)


def gpi_support(seed=0):
    """The 4 extreme weights and 2 random ones (a weight support of 6, as mid-run)."""
    rng = np.random.default_rng(seed)
    k = GPI["k"]
    return np.concatenate([np.eye(k), rng.dirichlet(np.ones(k), 2)]).astype(np.float32)


# ---------------------------------------------- ours: PCN, MORL/D, PGMORL (the recipes' agents)
# These three are built as ``morl-trl train`` builds them (``resolve_config`` at the paper's
# domain: ../shared/reference/hyperparameters.toml [pcn.lunarlander], [morld_sb.hopper],
# [pgmorl.hopper]), so their networks, batch sizes and optimizers are the recipe's.
PCN_ENV, MORLD_ENV, PGMORL_ENV = "MOLunarLanderDR-v0", "MOHopperDR-v5", "MOHopperDR-v5"


def pcn_episodes(n, obs, actions, k, seed=2):
    """``n`` episodes of 100-300 random steps ``(obs [T, obs], action [T], reward [T, k])``: the
    replay PCN learns from once its ``num_er_episodes = 1000`` random episodes are in
    ([pcn.lunarlander.train]; MO-LunarLander episodes run up to 1000 steps, most end far sooner)."""
    g = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        t = int(g.integers(100, 300))
        out.append((g.standard_normal((t, obs)).astype(np.float32), g.integers(actions, size=t),
                    g.standard_normal((t, k)).astype(np.float32)))
    return out


def _recipe_agent(algo, env_id, **overrides):
    from morl_trl.envs import domain_of
    from morl_trl.recipes import build_agent, build_training_env, resolve_config
    from morl_trl.recipes.config.train_config import valid_keys
    from morl_trl.training.parts import run_discount

    overrides = {**{k: v for k, v in RECIPE_OVERRIDES.items() if k in valid_keys(algo)}, **overrides}
    cfg = resolve_config(algo, env_id, device="cpu", logger="none", progress=False, **overrides)
    env = build_training_env(cfg, torch.device("cpu"))
    agent = build_agent(cfg, env, gamma=run_discount(cfg, domain_of(env_id)), device=torch.device("cpu"))
    return cfg, env, agent


def ours_pcn(eps):
    """``recipes.pcn.update``: 256 steps of the episode replay (``EpisodeReplay.sample``), ``PCNLoss``
    on the authors' network (26 -> 256 embeddings, 3 x 256 head), fused Adam (lr 3e-4)."""
    from morl_trl.algorithms.pcn import recipe as pcn

    _, _, agent = _recipe_agent("pcn", PCN_ENV)
    for o, a, r in eps:
        agent.replay.add(torch.from_numpy(o), torch.from_numpy(a), torch.from_numpy(r))
    return lambda: pcn.update(agent)


def morld_transitions(n, obs, act, k, seed=3):
    g = np.random.default_rng(seed)
    done = torch.as_tensor(g.random(n) < 0.01).unsqueeze(-1)
    return TensorDict({
        "observation": torch.as_tensor(g.standard_normal((n, obs)), dtype=torch.float32),
        "action": torch.as_tensor(g.uniform(-1, 1, (n, act)), dtype=torch.float32),
        ("next", "observation"): torch.as_tensor(g.standard_normal((n, obs)), dtype=torch.float32),
        ("next", "reward"): torch.as_tensor(g.standard_normal((n, k)), dtype=torch.float32),
        ("next", "done"): done, ("next", "terminated"): done.clone()}, [n])


def ours_morld(td, buffer_size):
    """``morld.update`` (MORL/D SB at MO-Hopper): all 6 members at once, 256 transitions each
    from the shared buffer, critics + actor + temperature, one optimizer step per network kind,
    Polyak targets."""
    from morl_trl.algorithms.morld import recipe as morld
    from morl_trl.training.parts import make_replay_buffer

    cfg, _, agent = _recipe_agent("morld", MORLD_ENV, buffer_size=buffer_size)
    rb = make_replay_buffer(cfg, torch.device("cpu"))
    rb.extend(td)
    return lambda: morld.update(agent, rb), cfg


def ours_pgmorl(steps):
    """``recipes.pgmorl.on_batch``: one iteration (its evaluation and evolution left out): vector GAE
    of the 6 x 4 x ``steps`` batch, then 10 epochs x 32 minibatches, each one clipped-PPO step of
    the whole batched population (4 x 256 tanh actor and critic per member)."""
    from morl_trl.algorithms.pgmorl import recipe as pgmorl

    cfg, env, agent = _recipe_agent("pgmorl", PGMORL_ENV, frames_per_batch=24 * steps)
    P, E = cfg.pgmorl_pop, cfg.pgmorl_envs_per_member
    n, obs = P * E, env.observation_spec["observation"].shape[-1]
    act, k = env.action_spec.shape[-1], env.full_reward_spec["reward"].shape[-1]
    g = torch.Generator().manual_seed(4)
    batch = TensorDict({
        "observation": torch.randn(n, steps, obs, generator=g), "action": torch.randn(n, steps, act, generator=g).clamp(-1, 1),
        "next": {"observation": torch.randn(n, steps, obs, generator=g), "reward": torch.randn(n, steps, k, generator=g),
                 "done": torch.zeros(n, steps, 1, dtype=torch.bool), "terminated": torch.zeros(n, steps, 1, dtype=torch.bool),
                 "episode_discounted_return": torch.zeros(n, steps, k)},
    }, [n, steps])
    with torch.no_grad():
        batch.set("action_log_prob", agent.actor.get_dist(batch.select("observation")).log_prob(batch["action"]))

    def step():
        agent.iteration = 1  # past the first iteration's evaluation of the untrained members; no evolution
        pgmorl.on_batch(agent, batch, None, 0)

    return step, cfg.pgmorl_epochs * cfg.pgmorl_minibatches, obs, act, k


# ------------------------------------------------------------------- MORL-Baselines itself
def mb_gpi(tr, support, buffer_size, gpi_pd, device="cpu"):
    """MORL-Baselines' ``GPIPD.update(w)`` (``gpi_pd=False``: GPI-LS; ``dyna=False``) on a filled
    buffer. Its module-level imports for the linear support and plots (``cdd``, ``cvxpy``,
    ``seaborn``) are stubbed: ``update`` uses none of them."""
    import types

    for name in ("cdd", "cvxpy", "seaborn"):
        stub = types.ModuleType(name)
        stub.SolverError = RuntimeError
        sys.modules.setdefault(name, stub)
    import gymnasium as gym
    from morl_baselines.multi_policy.gpi_pd.gpi_pd import GPIPD

    g = GPI
    agent = GPIPD(_spaces_env(g["obs"], gym.spaces.Discrete(g["actions"]), g["k"]), learning_rate=LR, gamma=GAMMA,
                  batch_size=g["batch"], net_arch=NET, num_nets=2, buffer_size=buffer_size, per=True, gpi_pd=gpi_pd,
                  dyna=False, learning_starts=0, target_net_update_freq=1000, log=False, seed=0, device=device)
    for i in range(len(tr["obs"])):
        agent.replay_buffer.add(tr["obs"][i], tr["action"][i], tr["reward"][i], tr["next_obs"][i], tr["done"][i])
    agent.set_weight_support(list(support))
    w = torch.as_tensor(support[0])
    agent.global_step = 1  # below dynamics_rollout_starts: one gradient update per call

    def step():
        agent.update(w)

    return step



def mb_pcn(eps, obs, actions, k):
    """MORL-Baselines' ``PCN.update()`` on the same episodes, with the authors' network (their
    fork's ``net_arch = [256] * 4``: embeddings 256 wide, then 3 x (Linear 256, ReLU) and the
    output; MORL-Baselines 1.3.0's default model has one hidden head layer of ``hidden_dim``,
    so the authors' is passed as ``model_class``), batch 256, lr 3e-4 ([pcn.lunarlander.init])."""
    import gymnasium as gym
    from morl_baselines.multi_policy.pcn.pcn import PCN as MBPCN, BasePCNModel, Transition

    class AuthorsModel(BasePCNModel):
        def __init__(self, state_dim, action_dim, reward_dim, scaling_factor, hidden_dim):
            super().__init__(state_dim, action_dim, reward_dim, scaling_factor, hidden_dim)
            nn = torch.nn
            self.s_emb = nn.Sequential(nn.Linear(state_dim, NET[0]), nn.Sigmoid())
            self.c_emb = nn.Sequential(nn.Linear(reward_dim + 1, NET[0]), nn.Sigmoid())
            layers = [m for a, b in zip(NET[:-1], NET[1:]) for m in (nn.Linear(a, b), nn.ReLU())]
            self.fc = nn.Sequential(*layers, nn.Linear(NET[-1], action_dim), nn.LogSoftmax(dim=1))

    pcn = MBPCN(_spaces_env(obs, gym.spaces.Discrete(actions), k), scaling_factor=np.full(k + 1, 0.1),
                learning_rate=LR, gamma=GAMMA, batch_size=256, hidden_dim=NET[0], log=False, seed=0, device="cpu",
                model_class=AuthorsModel)
    step = 0
    for o, a, r in eps:
        trans = [Transition(o[t], int(a[t]), r[t].copy(), o[t], False) for t in range(len(o))]
        step += len(trans)
        pcn._add_episode(trans, max_size=100_000, step=step)
    return lambda: pcn.update()


def mb_morld(td, buffer_size, weights):
    """MORL-Baselines' MORL/D SB steps one member at a time: one population update there is
    ``MOSAC.update()`` of each of its 6 members on their shared buffer, with the paper's policy
    arguments ([morld_sb.hopper.policy_args]: batch 256, 4 x 256, policy_lr 3e-4, q_lr 1e-3,
    policy_freq 2 -- two actor and temperature updates every other call --, tau 0.005, autotune)."""
    import gymnasium as gym
    from morl_baselines.single_policy.ser.mosac_continuous_action import MOSAC

    obs, act, k = td["observation"].shape[-1], td["action"].shape[-1], td["next", "reward"].shape[-1]
    env = _spaces_env(obs, gym.spaces.Box(-1.0, 1.0, (act,), np.float32), k)
    pop = [MOSAC(env, weights[p], scalarization=torch.matmul, buffer_size=buffer_size, gamma=GAMMA, tau=0.005,
                 batch_size=256, learning_starts=0, net_arch=list(NET), policy_lr=3e-4, q_lr=1e-3, policy_freq=2,
                 target_net_freq=1, autotune=True, id=p, device="cpu", log=False, seed=p) for p in range(len(weights))]
    shared = pop[0].get_buffer()
    for m in pop:
        m.set_buffer(shared)
    o, a, r = td["observation"].numpy(), td["action"].numpy(), td["next", "reward"].numpy()
    no, d = td["next", "observation"].numpy(), td["next", "done"].numpy()
    for i in range(td.shape[0]):
        shared.add(obs=o[i], next_obs=no[i], action=a[i], reward=r[i], done=d[i, 0])
    for m in pop:
        m.global_step = 1

    def step():
        for m in pop:
            m.global_step += 1
            m.update()

    return step


def mb_pgmorl(steps, obs, act, k, epochs=10, minibatches=32):
    """MORL-Baselines' PGMORL learns member by member: for each of the 6 members, ``MOPPO``'s
    advantage computation and ``update()`` (10 epochs x 32 minibatches, lr 3e-4, clip 0.2,
    max_grad_norm 0.5, GAE lambda 0.95, 4 x 256 tanh ``MOPPONet``: [pgmorl.hopper.moppo]) on
    its own filled 4 x ``steps`` batch."""
    import types

    from morl_baselines.single_policy.ser.mo_ppo import MOPPO, MOPPONet

    agents = []
    g = torch.Generator().manual_seed(5)
    for i in range(6):
        net = MOPPONet((obs,), (act,), k, list(NET))
        ag = MOPPO(i, net, np.full(k, 1 / k, dtype=np.float32), types.SimpleNamespace(num_envs=4), log=False,
                   steps_per_iteration=steps, num_minibatches=minibatches, update_epochs=epochs, learning_rate=LR,
                   gamma=GAMMA, anneal_lr=False, clip_coef=0.2, ent_coef=0.0, vf_coef=0.5, clip_vloss=True,
                   max_grad_norm=0.5, norm_adv=True, gae=True, gae_lambda=0.95, device="cpu", seed=i)
        for _ in range(steps):
            o = torch.randn(4, obs, generator=g)
            with torch.no_grad():
                a, lp, _, v = net.get_action_and_value(o)
            ag.batch.add(o, a, lp, torch.randn(4, k, generator=g), torch.zeros(4), v)
        agents.append(ag)
    nxt = torch.randn(4, obs, generator=g)

    def step():
        for ag in agents:
            ag.returns, ag.advantages = ag._MOPPO__compute_advantages(nxt, torch.zeros(4))
            ag.update()

    return step


def _spaces_env(obs, action_space, k):
    import gymnasium as gym

    class SpacesOnly(gym.Env):
        """Carries the spaces MORL-Baselines reads; never stepped."""

        def __init__(self):
            self.observation_space = gym.spaces.Box(-np.inf, np.inf, (obs,), np.float32)
            self.action_space = action_space
            self.reward_space = gym.spaces.Box(-np.inf, np.inf, (k,), np.float32)

    return SpacesOnly()


def mb_envelope(tr, buffer_size, device="cpu"):
    import gymnasium as gym
    from morl_baselines.multi_policy.envelope.envelope import Envelope

    c = ENVELOPE
    agent = Envelope(
        _spaces_env(c["obs"], gym.spaces.Discrete(c["actions"]), c["k"]),
        learning_rate=LR,
        gamma=GAMMA,
        batch_size=c["batch"],
        net_arch=NET,
        num_sample_w=c["n_w"],
        per=True,
        per_alpha=c["per_alpha"],
        initial_homotopy_lambda=c["lam"],
        final_homotopy_lambda=1.0,
        target_net_update_freq=c["target_every"],
        tau=1.0,
        buffer_size=buffer_size,
        learning_starts=0,
        max_grad_norm=1.0,
        log=False,
        seed=0,
        device=device,
    )
    for i in range(len(tr["obs"])):
        agent.replay_buffer.add(tr["obs"][i], tr["action"][i], tr["reward"][i], tr["next_obs"][i], tr["done"][i])
    agent.global_step = 1

    def step():
        agent.global_step += 1
        agent.update()

    return step


def mb_capql(tr, buffer_size, device="cpu"):
    import gymnasium as gym
    from morl_baselines.multi_policy.capql.capql import CAPQL as MBCAPQL

    c = CAPQL
    agent = MBCAPQL(
        _spaces_env(c["obs"], gym.spaces.Box(-1.0, 1.0, (c["act"],), np.float32), c["k"]),
        learning_rate=LR,
        gamma=GAMMA,
        tau=c["tau"],
        buffer_size=buffer_size,
        net_arch=NET,
        batch_size=c["batch"],
        num_q_nets=2,
        alpha=c["alpha"],
        learning_starts=0,
        log=False,
        seed=0,
        device=device,
    )
    for i in range(len(tr["obs"])):
        agent.replay_buffer.push(tr["obs"][i], tr["action"][i], tr["w"][i], tr["reward"][i], tr["next_obs"][i], tr["done"][i])
    agent.global_step = 1

    def step():
        agent.global_step += 1
        agent.update()

    return step


# --------------------------------------------------- re-creation of MORL-Baselines' loops
def _mlp(i, o):
    layers, w = [], i
    for h in NET:
        layers += [torch.nn.Linear(w, h), torch.nn.ReLU()]
        w = h
    return torch.nn.Sequential(*layers, torch.nn.Linear(w, o))


class _NumpyPER:
    """Proportional PER over a flat NumPy array of priorities (cumulative-sum sampling)."""

    def __init__(self, n, rng):
        self.p = np.ones(n)
        self.rng = rng

    def sample(self, batch):
        c = np.cumsum(self.p)
        return np.searchsorted(c, self.rng.uniform(0, c[-1], batch))

    def update(self, idx, priority):
        self.p[idx] = priority


def rec_envelope(tr, buffer_size):
    """Envelope.update(): batch repeated N times, target nets on B * N * N rows, PER updates."""
    c = ENVELOPE
    b, n, a, k = c["batch"], c["n_w"], c["actions"], c["k"]
    rng = np.random.default_rng(0)
    q, q_t = _mlp(c["obs"] + k, a * k), _mlp(c["obs"] + k, a * k)
    q_t.load_state_dict(q.state_dict())
    optim = torch.optim.Adam(q.parameters(), lr=LR)
    per = _NumpyPER(len(tr["obs"]), rng)
    state = {"step": 0}

    def net(m, obs, w):
        return m(torch.cat([obs, w], -1)).view(-1, a, k)

    def step():
        idx = per.sample(b)
        obs, act, rew, nxt, done = (
            torch.tensor(tr[key][idx]).float() for key in ("obs", "action", "reward", "next_obs", "done")
        )
        sw = torch.tensor(np.abs(rng.standard_normal((n, k)))).float()
        sw = sw / sw.sum(1, keepdim=True)
        w = sw.repeat_interleave(b, 0)
        obs, act, rew, nxt, done = obs.repeat(n, 1), act.repeat(n), rew.repeat(n, 1), nxt.repeat(n, 1), done.repeat(n)
        with torch.no_grad():
            big_w = sw.repeat(nxt.size(0), 1)
            big_next = nxt.repeat_interleave(n, 0)
            nq = net(q, big_next, big_w).view(nxt.size(0), n, a, k)
            best_q, best_a = torch.einsum("br,bwar->bwa", w, nq).max(2)
            pref = best_q.argmax(1)
            nq_t = net(q_t, big_next, big_w).view(nxt.size(0), n, a, k)
            target = nq_t.gather(2, best_a[:, :, None, None].expand(-1, -1, 1, k)).squeeze(2)
            target = target.gather(1, pref[:, None, None].expand(-1, 1, k)).squeeze(1)
            target_q = rew + (1 - done)[:, None] * GAMMA * target
        qv = net(q, obs, w).gather(1, act.long()[:, None, None].expand(-1, 1, k)).squeeze(1)
        loss = torch.nn.functional.mse_loss(qv, target_q)
        aux = torch.nn.functional.mse_loss((qv * w).sum(-1), (target_q * w).sum(-1))
        loss = (1 - c["lam"]) * loss + c["lam"] * aux
        optim.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(q.parameters(), 1.0)
        optim.step()
        td = ((qv[:b] - target_q[:b]).detach() * w[:b]).sum(-1).abs().numpy()
        per.update(idx, (td + 1e-5) ** c["per_alpha"])
        state["step"] += 1
        if state["step"] % c["target_every"] == 0:
            q_t.load_state_dict(q.state_dict())

    return step


def rec_capql(tr, buffer_size):
    """CAPQL.update(): list-buffer sampling, two critics and the actor in separate passes."""
    c = CAPQL
    rng = np.random.default_rng(0)
    o, d, k = c["obs"], c["act"], c["k"]
    critics = [_mlp(o + d + k, k) for _ in range(2)]
    targets = [_mlp(o + d + k, k) for _ in range(2)]
    for t, q in zip(targets, critics):
        t.load_state_dict(q.state_dict())
    body, mean, log_std = _mlp(o + k, NET[-1]), torch.nn.Linear(NET[-1], d), torch.nn.Linear(NET[-1], d)
    actor_params = [*body.parameters(), *mean.parameters(), *log_std.parameters()]
    q_optim = torch.optim.Adam([p for q in critics for p in q.parameters()], lr=LR)
    pi_optim = torch.optim.Adam(actor_params, lr=LR)
    memory = [tuple(tr[key][i] for key in ("obs", "action", "w", "reward", "next_obs", "done")) for i in range(len(tr["obs"]))]

    def policy(obs, w):
        h = torch.relu(body(torch.cat([obs, w], -1)))
        mu, ls = mean(h), log_std(h).clamp(-20, 2)
        x = mu + ls.exp() * torch.randn_like(mu)
        y = torch.tanh(x)
        logp = torch.distributions.Normal(mu, ls.exp()).log_prob(x).sum(1) - torch.log(1 - y.pow(2) + 1e-6).sum(1)
        return y, logp.clamp(-1e3, 1e3)

    def step():
        batch = [memory[i] for i in rng.choice(len(memory), c["batch"], replace=False)]
        obs, act, w, rew, nxt, done = (torch.tensor(np.stack(x), dtype=torch.float32) for x in zip(*batch))
        with torch.no_grad():
            na, nlogp = policy(nxt, w)
            qt = torch.stack([t(torch.cat([nxt, na, w], -1)) for t in targets]).min(0)[0] - c["alpha"] * nlogp[:, None]
            y = rew + (1 - done[:, None]) * GAMMA * qt
        closs = sum(torch.nn.functional.mse_loss(q(torch.cat([obs, act, w], -1)), y) for q in critics) / 2
        q_optim.zero_grad()
        closs.backward()
        q_optim.step()
        pi, logp = policy(obs, w)
        mq = (torch.stack([q(torch.cat([obs, pi, w], -1)) for q in critics]).min(0)[0] * w).sum(-1)
        ploss = (c["alpha"] * logp - mq).mean()
        pi_optim.zero_grad()
        ploss.backward()
        pi_optim.step()
        with torch.no_grad():
            for q, t in zip(critics, targets):
                for p, pt in zip(q.parameters(), t.parameters()):
                    pt.mul_(1 - c["tau"]).add_(c["tau"] * p)

    return step


# ------------------------------------------------------------------------- know the limit
def matmuls_of(step, n=1):
    """The matrix products ``n`` calls of ``step`` run (forward and backward of every network it
    touches): ``[(op, shapes)]``, recorded at the dispatcher (``torch.utils._python_dispatch``)."""
    from torch.utils._python_dispatch import TorchDispatchMode

    aten = torch.ops.aten
    kinds = {aten.mm.default: "mm", aten.addmm.default: "addmm", aten.bmm.default: "bmm",
             aten.baddbmm.default: "baddbmm"}

    class Recorder(TorchDispatchMode):
        calls: list = []

        def __torch_dispatch__(self, func, types, args=(), kwargs=None):
            if func in kinds:
                a, b = (args[1], args[2]) if kinds[func] in ("addmm", "baddbmm") else (args[0], args[1])
                self.calls.append((kinds[func], tuple(a.shape), tuple(b.shape), a.dtype))
            return func(*args, **(kwargs or {}))

    rec = Recorder()
    rec.calls = []
    with rec:
        for _ in range(n):
            step()
    return rec.calls


def matmul_flops(calls) -> float:
    """``2 m k n`` per product (``2 b m k n`` batched): the floating-point work of the matmuls."""
    total = 0.0
    for _, a, b, _ in calls:
        batch = a[0] if len(a) == 3 else 1
        m, k = a[-2], a[-1]
        total += 2.0 * batch * m * k * b[-1]
    return total


def matmul_rate(calls, device, seconds=0.2, windows=5) -> float:
    """GFLOP/s of this machine's torch running exactly these products back to back (same shapes,
    same threads, contiguous operands): the dense-matmul limit for this update's shapes.

    The best of ``windows`` timings of ``seconds`` each: a limit is what the machine can do, and a
    busy moment only ever lowers a window's rate (one 0.5 s window once read GPI-PD's limit at
    42 GFLOP/s where its update itself ran its products at 78)."""
    ops = []
    for kind, a, b, dtype in calls:
        x, y = torch.randn(a, device=device, dtype=dtype), torch.randn(b, device=device, dtype=dtype)
        ops.append((torch.bmm if len(a) == 3 else torch.mm, x, y))
    flops = matmul_flops(calls)
    for f, x, y in ops:  # warm-up
        f(x, y)
    best = 0.0
    for _ in range(windows):
        n, t = 0, CLOCK()
        while True:
            for f, x, y in ops:
                f(x, y)
            n += 1
            if SYNC:
                SYNC()
            if CLOCK() - t >= seconds:
                break
        best = max(best, n * flops / (CLOCK() - t) / 1e9)
    return best


LIMITS = []  # rows of the "know the limit" table: (name, GFLOP per update, updates/s, matmul GFLOP/s)
RATIOS: dict[str, float] = {}  # eager ours / peer per update, for the target line under the table
#: issue 31's target: every method's eager update at least this many times MORL-Baselines' updates/s
TARGET = 1.5


def target_line(ratios: dict[str, float], target: float = TARGET) -> str:
    """The line under the updates/s table: which updates reach ``target`` x the peer's rate.

    Example:
        >>> target_line({"Envelope": 3.2, "CAPQL": 1.07, "PCN": 1.5})
        'target 1.5x MORL-Baselines: met by Envelope 3.20x, PCN 1.50x; not met: CAPQL 1.07x'
    """
    met = [f"{name} {r:.2f}x" for name, r in ratios.items() if r >= target]
    missed = [f"{name} {r:.2f}x" for name, r in ratios.items() if not r >= target]  # (NaN: not met)
    return (f"target {target:g}x MORL-Baselines: met by {', '.join(met) or 'none'}; "
            f"not met: {', '.join(missed) or 'none'}")


# ------------------------------------------------------------------------------- harness
CLOCK = time.perf_counter
SYNC = None  # torch.cuda.synchronize on a CUDA device: the rate covers the work, not its launch


def rate(step, n):
    if SYNC:
        SYNC()
    t = CLOCK()
    for _ in range(n):
        step()
    if SYNC:
        SYNC()
    return n / (CLOCK() - t)


METHODS = ("envelope", "capql", "gpi_ls", "gpi_pd", "pcn", "morld", "pgmorl")
CAPTURE_MODES = ("compile", "cudagraphs", "both", "whole", "whole+compile")
FLOPS = True  # --no-flops: skip the "know the limit" table
#: --min-round-seconds: each round runs at least this long (more calls than --updates where an update is fast)
MIN_ROUND_SECONDS = 0.0
TABLE = None  # --table FILE: each row appended, tab-separated (benchmarks/gpu/check.sh collects them)


def _table(*fields) -> None:
    if TABLE:
        with open(TABLE, "a") as f:
            f.write("\t".join(str(x) for x in fields) + "\n")


def round_calls(call_seconds, updates: int) -> int:
    """Calls of each step a round runs: ``updates``, or more where the fastest step (``call_seconds``: each
    step's last warm-up call, ``None`` where it had none) would finish a round in under
    :data:`MIN_ROUND_SECONDS`; the same count for ours and the peer. A round of 20 four-millisecond PCN
    updates is 0.08 s, and such rounds swung PCN's ratio from 1.18x to 1.51x in back-to-back runs; 1 s
    rounds gave 1.16-1.33x."""
    timed = [t for t in call_seconds if t is not None]
    if MIN_ROUND_SECONDS <= 0 or not timed:
        return updates
    return max(updates, math.ceil(MIN_ROUND_SECONDS / max(min(timed), 1e-9)))


def warm_up(step, n: int) -> float | None:
    """``n`` calls of ``step``; the seconds the last one took (``None`` for ``n = 0``)."""
    seconds = None
    for _ in range(n):
        seconds = 1.0 / rate(step, 1)
    return seconds


def compare(name, variants, peer, *, warmup, updates, rounds, device="cpu", per_call=1, flop_calls=1):
    """Rows ``name / variant``: median updates/s of each of ours, the peer's, and their ratios.

    ``per_call``: updates one call of a step runs (PGMORL: a step is one iteration's 10 x 32
    minibatch updates); ``updates`` counts calls; ``flop_calls``: calls the FLOP count averages
    over (MORL/D: 2, MORL-Baselines' MOSAC updates its actor twice every other call). A variant that fails (e.g. a capture mode on a
    new device) is reported and skipped."""
    failed, call_seconds = {}, []
    for label, step in list(variants.items()):
        try:
            call_seconds.append(warm_up(step, warmup))
        except Exception as err:
            failed[label] = f"{type(err).__name__}: {str(err).splitlines()[0][:300] if str(err) else ''}"
            del variants[label]
            print(f"{name:<10} {label:<11} failed: {failed[label]}", flush=True)
            _table("losses", name, device, label, "updates/s", "FAILED", "", "", failed[label])
    if peer is not None:
        call_seconds.append(warm_up(peer, warmup))
    calls = round_calls(call_seconds, updates)
    if calls > updates:
        print(f"({name}: {calls} calls a round, each round >= {MIN_ROUND_SECONDS:g} s)", flush=True)
    rates = {label: [] for label in variants}
    r_peer = []
    for _ in range(rounds):
        for label, step in variants.items():
            rates[label].append(rate(step, calls) * per_call)
        if peer is not None:
            r_peer.append(rate(peer, calls) * per_call)
    b = statistics.median(r_peer) if peer is not None else float("nan")
    eager = statistics.median(rates["eager"]) if "eager" in rates else float("nan")
    for label in variants:
        a = statistics.median(rates[label])
        vs_peer = f"{b:>10.1f} {a / b:>8.2f}x" if peer is not None else f"{'-':>10} {'-':>9}"
        print(f"{name:<10} {label:<11} {a:>10.1f} {vs_peer} {a / eager:>9.2f}x", flush=True)
        _table("losses", name, device, label, "updates/s", f"{a:.1f}", f"{b:.1f}" if peer is not None else "",
               f"{a / b:.2f}x" if peer is not None else "", f"{a / eager:.2f}x vs eager")
    if peer is not None and "eager" in rates:
        RATIOS[name] = eager / b
    if FLOPS and "eager" in variants:
        calls = matmuls_of(variants["eager"], flop_calls)
        peer_gf = (matmul_flops(matmuls_of(peer, flop_calls)) / 1e9 / per_call / flop_calls if peer is not None
                   else float("nan"))
        LIMITS.append((name, matmul_flops(calls) / 1e9 / per_call / flop_calls, eager, matmul_rate(calls, device),
                       len(calls) // (per_call * flop_calls), peer_gf, b))


def time_recipe_agents(methods, peer, args, warmup, updates, rounds, buffer_size, filled) -> None:
    """The PCN, MORL/D and PGMORL rows (ours: the recipes' agents; peer: MORL-Baselines, when importable)."""
    mb = peer == "morl-baselines"
    if "pcn" in methods:
        # the replay PCN learns from: 1000 episodes (obs 26 = 8 x 3 + 2, 4 actions, 4 objectives)
        eps = pcn_episodes(16 if args.tiny else 1000, ENVELOPE["obs"], ENVELOPE["actions"], ENVELOPE["k"])
        compare("PCN", {"eager": ours_pcn(eps)}, mb_pcn(eps, ENVELOPE["obs"], ENVELOPE["actions"], ENVELOPE["k"])
                if mb else None, warmup=warmup, updates=updates, rounds=rounds)
    if "morld" in methods:
        td = morld_transitions(filled, CAPQL["obs"], CAPQL["act"], CAPQL["k"])
        step, _ = ours_morld(td, buffer_size)
        # (one population update: every member updated once; the same weights on both sides)
        from morl_trl.preferences import energy_weights

        w = energy_weights(CAPQL["k"], 6, seed=0, dtype=torch.float32).numpy()
        compare("MORL/D", {"eager": step}, mb_morld(td, buffer_size, w) if mb else None, warmup=max(1, warmup // 2),
                updates=max(1, updates // 4), rounds=rounds, flop_calls=2)
    if "pgmorl" in methods:
        steps = args.pgmorl_steps or (16 if args.tiny else 256 if args.quick else 2048)
        step, per_call, obs, act, k = ours_pgmorl(steps)
        compare("PGMORL", {"eager": step}, mb_pgmorl(steps, obs, act, k) if mb else None, warmup=1, updates=1,
                rounds=rounds, per_call=per_call)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a short sanity run (1 round of 8 updates)")
    p.add_argument("--tiny", action="store_true",
                   help="a seconds-long dry run on any CPU (2 x 16 networks, batches of 16, 2 updates, one thread unless "
                        "--threads): every row runs, nothing is measured")
    p.add_argument("--table", default=None, help="append each row, tab-separated, to this file")
    p.add_argument("--no-flops", action="store_true", help="skip the FLOP count / dense-matmul limit table")
    p.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS), help="which updates to time")
    p.add_argument("--pgmorl-steps", type=int, default=None,
                   help="PGMORL steps per env and iteration (default: the paper's 2048; --quick: 256)")
    p.add_argument("--peer", choices=["auto", "morl-baselines", "recreation", "none"], default="auto")
    p.add_argument("--device", default="cpu", help="cpu or cuda: where ours (and MORL-Baselines) run")
    p.add_argument("--capture", nargs="*", default=None, choices=list(CAPTURE_MODES),
                   help="captured variants timed beside the eager update (default: all on cuda, none on cpu); "
                        "whole: sampling + update + priority writes as one CUDA graph (Envelope only)")
    p.add_argument("--updates", type=int, default=40, help="updates per round")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--min-round-seconds", type=float, default=0.5,
                   help="each round runs at least this long: more calls than --updates for a fast update, the "
                        "same count for ours and the peer (default 0.5; 0: exactly --updates; --tiny/--quick: 0)")
    p.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    p.add_argument(
        "--clock",
        choices=["wall", "cpu"],
        default="wall",
        help="wall time (default), or this process's CPU time: steadier on a shared machine, with --threads 1",
    )
    p.add_argument("--malloc", choices=["tuned", "default"], default="tuned",
                   help="tuned (default): glibc's thresholds set as a trainer sets them "
                        "(morl_trl.training.allocator.tune_malloc); default: glibc's own. One process: "
                        "the peer runs under the same setting")
    args = p.parse_args(argv)
    global CLOCK, SYNC, TABLE, FLOPS, MIN_ROUND_SECONDS
    if args.malloc == "default":
        import os

        os.environ["MORL_TRL_MALLOC"] = "0"  # (the recipes' build_agent would set it otherwise)
        malloc_label = "glibc defaults"
    else:
        from morl_trl.training.allocator import tune_malloc

        malloc_label = ("glibc thresholds set (mmap 32 MiB, trim 256 MiB)" if tune_malloc()
                        else "unchanged (not glibc, or MORL_TRL_MALLOC / MALLOC_*_ set)")
    TABLE = args.table
    FLOPS = not (args.no_flops or args.tiny)
    MIN_ROUND_SECONDS = 0.0 if (args.tiny or args.quick) else args.min_round_seconds
    CLOCK = time.perf_counter if args.clock == "wall" else time.process_time
    device = torch.device(args.device)
    if device.type == "cuda":
        if not torch.cuda.is_available():
            raise SystemExit("--device cuda: no CUDA device here")
        SYNC = torch.cuda.synchronize
    if args.threads:
        torch.set_num_threads(args.threads)
    elif args.tiny:  # a dry run on a busy CPU: OpenMP's threads would wait on descheduled siblings at every op
        torch.set_num_threads(1)
    capture = args.capture if args.capture is not None else (list(CAPTURE_MODES) if device.type == "cuda" else [])
    warmup, updates, rounds = (1, 2, 1) if args.tiny else (2, 8, 1) if args.quick else (5, args.updates, args.rounds)
    warmup = max(warmup, 8) if capture else warmup  # compile and graph capture happen in the warm-up
    if args.tiny:
        make_tiny()
    buffer_size, filled = (256, 256) if args.tiny else (4_096, 4_096) if args.quick else (100_000, 20_000)

    peer = args.peer
    if peer in ("auto", "morl-baselines"):
        try:
            import morl_baselines  # noqa: F401

            peer = "morl-baselines"
        except ImportError as err:
            if args.peer == "morl-baselines":
                raise SystemExit(f"morl-baselines is not importable ({err}); see this script's docstring.")
            peer = "recreation" if device.type == "cpu" else "none"
    if peer == "morl-baselines":
        from importlib.metadata import version

        peer_label = f"MORL-Baselines {version('morl-baselines')} on {device}"
    elif peer == "recreation":
        if device.type != "cpu":
            raise SystemExit("the re-created peer runs on the CPU only; pass --peer none or install morl-baselines")
        peer_label = "re-creation of MORL-Baselines' update loops (MORL-Baselines not importable)"
    else:
        peer_label = "none"
    torch.manual_seed(0)
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, {args.clock} clock, device {device}; "
          f"peer: {peer_label}")
    at_least = f" (more where a round would be under {MIN_ROUND_SECONDS:g} s)" if MIN_ROUND_SECONDS > 0 else ""
    print(f"{warmup} warm-up updates, then {rounds} round(s) of {updates} updates each{at_least}, alternating; "
          "median updates/s")
    print(f"allocator: {malloc_label}, for ours and the peer alike (one process)")
    methods = args.methods if device.type == "cpu" else [m for m in args.methods if not m.startswith("gpi")]
    env_tr = random_transitions(filled, ENVELOPE["obs"], ENVELOPE["k"], num_actions=ENVELOPE["actions"])
    cap_tr = random_transitions(filled, CAPQL["obs"], CAPQL["k"], act_dim=CAPQL["act"], seed=1)
    ours_env = {"eager": ours_envelope(env_tr, buffer_size, device)[0]} if "envelope" in methods else {}
    ours_cap = {"eager": ours_capql(cap_tr, buffer_size, device)} if "capql" in methods else {}
    for mode in capture:
        if "envelope" in methods:
            ours_env[mode] = ours_envelope(env_tr, buffer_size, device, capture=mode)[0]
        if "capql" in methods and not mode.startswith("whole"):  # CAPQL's uniform replay: nothing more to capture
            ours_cap[mode] = ours_capql(cap_tr, buffer_size, device, capture=mode)
    peers = {"morl-baselines": (mb_envelope, mb_capql), "recreation": (rec_envelope, rec_capql)}.get(peer)
    kw = {"device": str(device)} if peer == "morl-baselines" else {}
    peer_env = peers[0](env_tr, buffer_size, **kw) if peers and "envelope" in methods else None
    peer_cap = peers[1](cap_tr, buffer_size, **kw) if peers and "capql" in methods else None
    print("(ours: the recipe's update as morl-trl train runs it: fused Adam, our prioritized sampler for Envelope)")
    print(f"{'loss':<10} {'update':<11} {'ours/s':>10} {'peer/s':>10} {'ratio':>9} {'vs eager':>10}")
    if "envelope" in methods:
        compare("Envelope", ours_env, peer_env, warmup=warmup, updates=updates, rounds=rounds, device=device)
    if "capql" in methods:
        compare("CAPQL", ours_cap, peer_cap, warmup=warmup, updates=updates, rounds=rounds, device=device)
    support = gpi_support()
    for name, pd in (("GPI-LS", False), ("GPI-PD", True)):
        if name.lower().replace("-", "_") not in methods:
            continue
        peer_gpi = mb_gpi(env_tr, support, buffer_size, pd) if peer == "morl-baselines" else None
        compare(name, {"eager": ours_gpi(env_tr, support, buffer_size, pd)}, peer_gpi, warmup=warmup, updates=updates,
                rounds=rounds, device=device)
    cpu_only = [m for m in ("pcn", "morld", "pgmorl") if m in methods]
    if cpu_only and device.type != "cpu":
        print(f"({', '.join(cpu_only)}: timed on the CPU only)")
    elif cpu_only:
        time_recipe_agents(cpu_only, peer, args, warmup, updates, rounds, buffer_size, filled)
    if RATIOS:
        print(target_line(RATIOS))
    if LIMITS:
        print("\nknow the limit (ours, eager): matmul FLOPs of one update (forward + backward of every network it "
              "touches, counted at the dispatcher) x updates/s, beside torch running the same products back to back")
        print(f"{'loss':<10} {'GFLOP/update':>13} {'matmuls':>8} {'updates/s':>10} {'GFLOP/s':>9} "
              f"{'matmul GFLOP/s':>15} {'of limit':>9} | {'peer GFLOP/upd':>14} {'peer GFLOP/s':>13} {'of limit':>9}")
        for name, gf, ups, peak, n, pgf, pups in LIMITS:
            print(f"{name:<10} {gf:>13.3f} {n:>8d} {ups:>10.1f} {gf * ups:>9.1f} {peak:>15.1f} {gf * ups / peak:>8.0%} | "
                  f"{pgf:>14.3f} {pgf * pups:>13.1f} {pgf * pups / peak:>8.0%}")
            _table("limit", name, device, "eager", "GFLOP/s", f"{gf * ups:.1f}", f"{peak:.1f}", f"{gf * ups / peak:.0%}",
                   f"{gf:.3f} GFLOP/update, {n} matmuls; peer column: dense matmul, same shapes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
