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

The peer is MORL-Baselines' ``Envelope.update()`` / ``CAPQL.update()`` on the same
settings, driven directly on a filled buffer. Install it in a scratch environment that
reuses our torch (``morl-baselines`` itself pulls an unpinned torch):

    python -m venv --system-site-packages /tmp/mb_venv
    /tmp/mb_venv/bin/pip install --no-deps morl-baselines
    /tmp/mb_venv/bin/pip install -c <(echo "torch==$(python -c 'import torch; print(torch.__version__)')") wandb
    /tmp/mb_venv/bin/python benchmarks/bench_losses.py [--quick]

Without it (``--peer recreation``, or ``auto`` when the import fails) the peer is our
re-creation of its update loops (same networks, same tensor work: the target network
evaluated on batch x N x N rows for Envelope, separate critic/actor passes for CAPQL),
and the output says so.

Ours is ``Agent.update`` as the recipes run it (fused Adam, sampling and priority updates
included). ``--device cuda`` runs ours (and MORL-Baselines, when installed) on the GPU and adds
rows for the captured update (``compile``, ``cudagraphs``, ``both``: see
``morl_trl.recipes.capture``) with their speed-up over the eager one:

    python benchmarks/bench_losses.py --device cuda [--capture cudagraphs both]

Ours and the peer alternate in rounds so that machine load hits both alike; the
median rate over rounds is reported. On a shared machine, ``--threads 1 --clock cpu``
(process CPU time) gives steadier figures than wall time.
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
from torchrl.objectives import HardUpdate  # noqa: E402

from morl_trl.data import prioritized_sampler  # noqa: E402
from morl_trl.recipes.agent import adam  # noqa: E402
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
def _agent_step(loss, optimizers, updater, rb, device, *, max_grad_norm=None, prioritized=False, capture=None):
    """``Agent.update`` on ``rb``, as the recipe runs it: eager, or captured (``"compile"``,
    ``"cudagraphs"``, ``"both"``) with the non-finite flag read every 100 updates."""
    from types import SimpleNamespace

    from morl_trl.recipes.agent import Agent

    cfg = SimpleNamespace(max_grad_norm=max_grad_norm, prioritized=prioritized, finite_check_interval=100,
                          compile=capture in ("compile", "both", "whole+compile"), compile_mode=None,
                          cudagraphs=capture in ("cudagraphs", "both", "whole", "whole+compile"),
                          capture_sampling=capture in ("whole", "whole+compile"))
    agent = Agent(cfg, loss, None, None, optimizers, updater, device=device)

    def step():
        agent.update(rb)

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
    step = _agent_step(loss, {"qvalue": optim}, updater, rb, device, max_grad_norm=1.0, prioritized=True,
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
    return _agent_step(loss, optimizers, updater, rb, device, capture=capture)


def ours_gpi(tr, support, buffer_size, gpi_pd):
    """``GPIAgent.update`` (discrete) at the MO-LunarLander settings: ``GPILoss`` on the authors'
    Q-network (ensemble of 2, dropout 0.01, LayerNorm), fused Adam, prioritized replay (alpha 0.6,
    min priority 0.01) with priority updates; ``gpi_pd``: GPI priorities over the support."""
    from morl_trl.objectives import GPILoss, GPIQNetwork

    g = GPI
    loss = GPILoss(GPIQNetwork(g["obs"], g["actions"], g["k"], hidden=tuple(NET), num_nets=2, dropout=0.01,
                               layer_norm=True), gpi_pd=gpi_pd, min_priority=0.01)
    loss.make_value_estimator(gamma=GAMMA)
    loss.set_weights(torch.as_tensor(support[0]), torch.as_tensor(support))
    opt = adam(loss.value_network_params.values(True, True), LR)
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(buffer_size),
                                sampler=prioritized_sampler(buffer_size, alpha=g["per_alpha"], beta=0.4),
                                batch_size=g["batch"], priority_key="td_error")
    rb.extend(as_tensordict(tr).exclude("preference"))

    def step():
        batch = rb.sample()
        out = loss(batch)
        total = out["loss_qvalue"]
        if not torch.isfinite(total):
            raise RuntimeError("non-finite loss")
        opt.zero_grad(set_to_none=True)
        total.backward()
        opt.step()
        rb.update_tensordict_priority(batch)

    return step


def gpi_support(seed=0):
    """The 4 extreme weights and 2 random ones (a weight support of 6, as mid-run)."""
    rng = np.random.default_rng(seed)
    k = GPI["k"]
    return np.concatenate([np.eye(k), rng.dirichlet(np.ones(k), 2)]).astype(np.float32)


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
def matmuls_of(step):
    """The matrix products one call of ``step`` runs (forward and backward of every network it
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


def matmul_rate(calls, device, seconds=0.5) -> float:
    """GFLOP/s of this machine's torch running exactly these products back to back (same shapes,
    same threads, contiguous operands): the dense-matmul limit for this update's shapes."""
    ops = []
    for kind, a, b, dtype in calls:
        x, y = torch.randn(a, device=device, dtype=dtype), torch.randn(b, device=device, dtype=dtype)
        ops.append((torch.bmm if len(a) == 3 else torch.mm, x, y))
    flops = matmul_flops(calls)
    for f, x, y in ops:  # warm-up
        f(x, y)
    n, t = 0, CLOCK()
    while True:
        for f, x, y in ops:
            f(x, y)
        n += 1
        if SYNC:
            SYNC()
        if CLOCK() - t >= seconds:
            break
    return n * flops / (CLOCK() - t) / 1e9


LIMITS = []  # rows of the "know the limit" table: (name, GFLOP per update, updates/s, matmul GFLOP/s)


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


CAPTURE_MODES = ("compile", "cudagraphs", "both", "whole", "whole+compile")
FLOPS = True  # --no-flops: skip the "know the limit" table
TABLE = None  # --table FILE: each row appended, tab-separated (benchmarks/gpu/check.sh collects them)


def _table(*fields) -> None:
    if TABLE:
        with open(TABLE, "a") as f:
            f.write("\t".join(str(x) for x in fields) + "\n")


def compare(name, variants, peer, *, warmup, updates, rounds, device="cpu"):
    """Rows ``name / variant``: median updates/s of each of ours, the peer's, and their ratios.

    A variant that fails (e.g. a capture mode on a new device) is reported and skipped."""
    failed = {}
    for label, step in list(variants.items()):
        try:
            for _ in range(warmup):
                step()
        except Exception as err:
            failed[label] = f"{type(err).__name__}: {str(err).splitlines()[0][:300] if str(err) else ''}"
            del variants[label]
            print(f"{name:<10} {label:<11} failed: {failed[label]}", flush=True)
            _table("losses", name, device, label, "updates/s", "FAILED", "", "", failed[label])
    if peer is not None:
        for _ in range(warmup):
            peer()
    rates = {label: [] for label in variants}
    r_peer = []
    for _ in range(rounds):
        for label, step in variants.items():
            rates[label].append(rate(step, updates))
        if peer is not None:
            r_peer.append(rate(peer, updates))
    b = statistics.median(r_peer) if peer is not None else float("nan")
    eager = statistics.median(rates["eager"]) if "eager" in rates else float("nan")
    for label in variants:
        a = statistics.median(rates[label])
        vs_peer = f"{b:>10.1f} {a / b:>8.2f}x" if peer is not None else f"{'-':>10} {'-':>9}"
        print(f"{name:<10} {label:<11} {a:>10.1f} {vs_peer} {a / eager:>9.2f}x", flush=True)
        _table("losses", name, device, label, "updates/s", f"{a:.1f}", f"{b:.1f}" if peer is not None else "",
               f"{a / b:.2f}x" if peer is not None else "", f"{a / eager:.2f}x vs eager")
    if FLOPS and "eager" in variants:
        calls = matmuls_of(variants["eager"])
        peer_gf = matmul_flops(matmuls_of(peer)) / 1e9 if peer is not None else float("nan")
        LIMITS.append((name, matmul_flops(calls) / 1e9, eager, matmul_rate(calls, device), len(calls), peer_gf, b))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a short sanity run (1 round of 8 updates)")
    p.add_argument("--tiny", action="store_true",
                   help="a seconds-long dry run (small buffer, 2 updates): every row runs, nothing is measured")
    p.add_argument("--table", default=None, help="append each row, tab-separated, to this file")
    p.add_argument("--no-flops", action="store_true", help="skip the FLOP count / dense-matmul limit table")
    p.add_argument("--methods", nargs="+", default=["envelope", "capql", "gpi_ls", "gpi_pd"],
                   choices=["envelope", "capql", "gpi_ls", "gpi_pd"], help="which updates to time")
    p.add_argument("--peer", choices=["auto", "morl-baselines", "recreation", "none"], default="auto")
    p.add_argument("--device", default="cpu", help="cpu or cuda: where ours (and MORL-Baselines) run")
    p.add_argument("--capture", nargs="*", default=None, choices=list(CAPTURE_MODES),
                   help="captured variants timed beside the eager update (default: all on cuda, none on cpu); "
                        "whole: sampling + update + priority writes as one CUDA graph (Envelope only)")
    p.add_argument("--updates", type=int, default=40, help="updates per round")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    p.add_argument(
        "--clock",
        choices=["wall", "cpu"],
        default="wall",
        help="wall time (default), or this process's CPU time: steadier on a shared machine, with --threads 1",
    )
    args = p.parse_args(argv)
    global CLOCK, SYNC, TABLE, FLOPS
    TABLE = args.table
    FLOPS = not (args.no_flops or args.tiny)
    CLOCK = time.perf_counter if args.clock == "wall" else time.process_time
    device = torch.device(args.device)
    if device.type == "cuda":
        if not torch.cuda.is_available():
            raise SystemExit("--device cuda: no CUDA device here")
        SYNC = torch.cuda.synchronize
    if args.threads:
        torch.set_num_threads(args.threads)
    capture = args.capture if args.capture is not None else (list(CAPTURE_MODES) if device.type == "cuda" else [])
    warmup, updates, rounds = (1, 2, 1) if args.tiny else (2, 8, 1) if args.quick else (5, args.updates, args.rounds)
    warmup = max(warmup, 8) if capture else warmup  # compile and graph capture happen in the warm-up
    buffer_size, filled = (1_024, 1_024) if args.tiny else (4_096, 4_096) if args.quick else (100_000, 20_000)

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
    print(f"{warmup} warm-up updates, then {rounds} round(s) of {updates} updates each, alternating; median updates/s")
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
    print("(ours: Agent.update as the recipe runs it: fused Adam, our prioritized sampler for Envelope)")
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
