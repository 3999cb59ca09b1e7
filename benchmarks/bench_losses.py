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


# ------------------------------------------------------------------- MORL-Baselines itself
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


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a short sanity run (1 round of 8 updates)")
    p.add_argument("--tiny", action="store_true",
                   help="a seconds-long dry run (small buffer, 2 updates): every row runs, nothing is measured")
    p.add_argument("--table", default=None, help="append each row, tab-separated, to this file")
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
    global CLOCK, SYNC, TABLE
    TABLE = args.table
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
    env_tr = random_transitions(filled, ENVELOPE["obs"], ENVELOPE["k"], num_actions=ENVELOPE["actions"])
    cap_tr = random_transitions(filled, CAPQL["obs"], CAPQL["k"], act_dim=CAPQL["act"], seed=1)
    ours_env = {"eager": ours_envelope(env_tr, buffer_size, device)[0]}
    ours_cap = {"eager": ours_capql(cap_tr, buffer_size, device)}
    for mode in capture:
        ours_env[mode] = ours_envelope(env_tr, buffer_size, device, capture=mode)[0]
        if not mode.startswith("whole"):  # CAPQL's uniform replay: nothing more to capture
            ours_cap[mode] = ours_capql(cap_tr, buffer_size, device, capture=mode)
    peers = {"morl-baselines": (mb_envelope, mb_capql), "recreation": (rec_envelope, rec_capql)}.get(peer)
    peer_env = peers[0](env_tr, buffer_size, **({"device": str(device)} if peer == "morl-baselines" else {})) \
        if peers else None
    peer_cap = peers[1](cap_tr, buffer_size, **({"device": str(device)} if peer == "morl-baselines" else {})) \
        if peers else None
    print("(ours: Agent.update as the recipe runs it: fused Adam, our prioritized sampler for Envelope)")
    print(f"{'loss':<10} {'update':<11} {'ours/s':>10} {'peer/s':>10} {'ratio':>9} {'vs eager':>10}")
    compare("Envelope", ours_env, peer_env, warmup=warmup, updates=updates, rounds=rounds, device=device)
    compare("CAPQL", ours_cap, peer_cap, warmup=warmup, updates=updates, rounds=rounds, device=device)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
