"""The authors' mechanisms (issue 27; docs/algorithms-fidelity-mechanisms.md): each with concrete
expected values read from SPEC §6 and hyperparameters.toml."""

import math

import numpy as np
import pytest
import torch

from morl_trl.recipes import resolve_config
from morl_trl.algorithms.actor_critic import recipe as actor_critic
from morl_trl.algorithms.gpi import recipe as gpi
from morl_trl.algorithms.morld import recipe as morld
from morl_trl.algorithms.gpi.recipe import make_gpi_agent
from morl_trl.recipes.off_policy import make_replay_buffer, make_training_env

CPU = torch.device("cpu")


def _gpi(algo="gpi_ls", env_id="MOLavaGridDR-v0", gamma=0.995, **kw):
    torch.manual_seed(0)
    base = dict(num_envs=4, frames_per_batch=32, init_random_frames=0, batch_size=16, hidden=(16, 16),
                buffer_size=4096, gpi_iteration_frames=10_000, gpi_front_episodes=1, gpi_dynamics_hidden=(16,),
                progress=False)
    if algo != "gpi_pd":  # GPI-LS has no dynamics model (a key it does not have is an error)
        del base["gpi_dynamics_hidden"]
    cfg = resolve_config(algo, env_id, **{**base, **kw})
    env = make_training_env(cfg, CPU)
    return cfg, env, make_gpi_agent(cfg, env, gamma=gamma, device=CPU)


def _adam_steps(opt) -> int:
    return int(next(iter(opt.state.values()))["step"]) if opt.state else 0


# ---------------------------------------------------------------------- GPI-LS / GPI-PD, discrete
@pytest.mark.parametrize("gradient_updates, expected", [(1, [16, 16, 16]), (3, [16, 48, 48])])
def test_discrete_gpi_does_gradient_updates_per_frame_from_rollout_starts(gradient_updates, expected, single_thread):
    """The authors' ``range(gradient_updates if global_step >= dynamics_rollout_starts else 1)`` per env step
    (gpi_pd.py:434); every script passes ``gradient_updates 1``: one Adam step per frame throughout."""
    cfg, env, agent = _gpi(updates_per_batch=0, gpi_gradient_updates=gradient_updates,
                           gpi_dynamics_rollout_starts=32)
    buffer = make_replay_buffer(cfg, CPU)
    opt = agent.optimizers["qvalue"]
    counts = []
    for frames in (16, 32, 48):  # 16 frames per batch; from frame 32 on gradient_updates per frame
        td = env.rollout(4, agent.explore_policy, break_when_any_done=False)  # [4, 4]
        before = _adam_steps(opt)
        _, n = gpi.on_batch(agent, td, buffer, frames)
        counts.append(_adam_steps(opt) - before)
        assert n == counts[-1]
    assert counts == expected


# ---------------------------------------------------------------------- CAPQL
def test_every_capql_training_weight_lies_within_22_5_degrees_of_equal_weights(single_thread):
    """The authors draw each step's w with theta ~ U(0, pi/8) around ones(d)/sqrt(d) (capql.py:70-100)."""
    pytest.importorskip("mujoco")
    from morl_trl.recipes import build_agent

    torch.manual_seed(0)
    cfg = resolve_config("capql", "MOHopperDR-v5", hidden=(16,), num_envs=4, buffer_size=1024, progress=False)
    env = make_training_env(cfg, CPU)
    agent = build_agent(cfg, env, gamma=0.99, device=CPU)
    buffer = make_replay_buffer(cfg, CPU)
    with torch.no_grad():
        td = env.rollout(50, agent.explore_policy, break_when_any_done=False)  # [4, 50]
    actor_critic.on_batch(agent, td, buffer, 200)
    w = buffer.storage[torch.arange(len(buffer))]["preference"].double()  # every stored (training) weight
    assert w.shape == (200, 3) and len({tuple(r) for r in w.tolist()}) == 200  # a new one every step
    centre = torch.full((3,), 3 ** -0.5, dtype=torch.float64)
    angle = torch.rad2deg(torch.arccos((w @ centre / w.norm(dim=-1)).clamp(max=1.0)))
    assert float(angle.max()) <= 22.5 + 1e-4 and float(angle.max()) > 18.0
    assert bool((w.min(-1).values >= 0.1381 - 1e-4).all() and (w.max(-1).values <= 0.5286 + 1e-4).all())
    torch.testing.assert_close(w.sum(-1), torch.ones(200, dtype=torch.float64))


# ---------------------------------------------------------------------- GPI evaluation
class _SignActor(torch.nn.Module):
    """pi(s, w) = +1 for w = e_1, -1 for w = e_2 (one action dimension)."""

    num_objectives = 2

    def forward(self, obs, w, noise=None, noise_clip=None):
        return (w[..., :1] - w[..., 1:2]).float()


class _Critic(torch.nn.Module):
    """Q_0(s, a, w_c) = [s * a * (2 w_c[0] - w_c[1]), 0] (one net)."""

    def forward(self, obs, action, w):
        q0 = obs[..., :1] * action * (2 * w[..., :1] - w[..., 1:2])
        return torch.cat([q0, torch.zeros_like(q0)], -1).unsqueeze(0)


@pytest.mark.parametrize("conditioning, expected", [("authors", [1.0, -1.0, -1.0, 1.0]),
                                                    ("support", [1.0, -1.0, 1.0, -1.0])])
def test_continuous_gpi_evaluation_picks_the_policy_of_the_support_per_state(conditioning, expected):
    """GPI over M = {e_1, e_2}: a_j = pi(s, w_j) scored by w . Q_0(s, a_j, w_c(i)). The authors' vectorised
    evaluator conditions candidate row i of evaluation context e (of E = 2) on w_floor((e*2+i)/2): context 0 on
    e_1 only, context 1 on e_2 only; their single-env path on w_i."""
    from tensordict import TensorDict

    from morl_trl.objectives.gpi import GPIContinuousPolicy

    table = torch.tensor([[0.0], [1.0]])  # E = 2 evaluation contexts
    policy = GPIContinuousPolicy(_SignActor(), _Critic(), support=torch.eye(2), gpi=True,
                                 context_table=table if conditioning == "authors" else None)
    td = TensorDict(observation=torch.tensor([[1.0], [-1.0], [1.0], [-1.0]]), preference=torch.tensor([[1.0, 0.0]] * 4),
                    context=torch.tensor([[0.0], [0.0], [1.0], [1.0]]), batch_size=[4])
    # state +1 in context 0: a = +1 (policy of e_1); state -1: a = -1 (policy of e_2); context 1 flips under the slip
    assert policy(td)["action"].flatten().tolist() == expected


def test_continuous_gpi_recipe_evaluates_by_gpi_and_fills_the_ccs_with_gpi_returns(single_thread):
    pytest.importorskip("mujoco")
    cfg, _, agent = _gpi("gpi_ls", "MOHopperDR-v5", gamma=0.99)
    assert cfg.gpi_eval_conditioning == "authors"
    ev = agent.eval_policy
    assert ev.gpi and ev.critic is agent.gpi_policy.critic and ev.context_table.shape == (6, 8)
    assert agent.gpi_policy.context_table is None  # corner weights and CCS values: the single-env indexing
    seen = []
    agent._evaluate = lambda weights, support, policy=None: seen.append(policy) or np.zeros((len(weights), 3))
    agent.end_iteration()
    assert seen == [agent.gpi_policy]
    _, _, fixed = _gpi("gpi_ls", "MOHopperDR-v5", gamma=0.99, gpi_eval_conditioning="support")
    assert fixed.eval_policy.gpi and fixed.eval_policy.context_table is None


def test_discrete_gpi_acts_with_dropout_and_evaluates_without(single_thread):
    from tensordict import TensorDict

    _, _, agent = _gpi(gpi_dropout=0.5)
    qnet = agent.eval_policy.qnet
    assert agent.eval_policy.dropout is False and agent.explore_policy[0].dropout is True
    obs = torch.randn(64, 125)
    td = lambda: TensorDict(observation=obs, preference=torch.full((64, 2), 0.5), batch_size=[64])  # noqa: E731
    a1, a2 = agent.eval_policy(td())["action"], agent.eval_policy(td())["action"]
    assert torch.equal(a1, a2) and qnet.training  # deterministic; the net's mode is restored
    q = [agent.explore_policy[0](td())["action"] for _ in range(5)]
    assert any(not torch.equal(q[0], x) for x in q[1:])  # dropout 0.5 while acting changes the greedy choice


# ---------------------------------------------------------------------- PCN
def _pcn(env_id="MOLavaGridDR-v0", **kw):
    from morl_trl.algorithms.pcn.recipe import make_pcn_agent, make_pcn_training_env

    torch.manual_seed(0)
    cfg = resolve_config("pcn", env_id, quick=True, num_envs=2, **kw)
    env = make_pcn_training_env(cfg, CPU)
    return cfg, env, make_pcn_agent(cfg, env, gamma=0.99 if "Lava" not in env_id else 0.995, device=CPU)


class _Recorder(torch.nn.Module):
    def __init__(self, policy):
        super().__init__()
        self.policy, self.seen = policy, []

    def forward(self, td):
        td = self.policy(td)
        self.seen.append(td.select("desired_return", "desired_horizon", "eval_episode_return").clone())
        return td


def test_pcn_evaluation_updates_the_command_after_every_step(single_thread):
    """The authors' evaluator: desired_return -= r (undiscounted vector reward, clipped above at max_return),
    horizon = max(horizon - 1, 1), from the top episode's (return, length) at the start (SPEC §6)."""
    from morl_trl.evaluation import MultiContextEvaluator

    cfg, _, agent = _pcn(hidden=(16, 16), eval_weights=2)
    obs = torch.zeros(4, 125)
    agent.replay.add(obs, torch.zeros(4, dtype=torch.long), torch.tensor([[10.0, -3.0]] * 4))  # length 4
    d0, h0 = agent.eval_commands(2)
    torch.testing.assert_close(h0, torch.tensor([4.0, 4.0]))
    rec = _Recorder(agent.eval_policy)
    MultiContextEvaluator(rec, ["MOLavaGridRoom-v0"], weights=2, gamma=0.995, seed=0, max_steps=8).evaluate()
    steps = torch.stack([td[0] for td in rec.seen])  # sub-env 0's first episode: 8 steps (cut at max_steps)
    assert steps["desired_horizon"].flatten().tolist() == [4.0, 3.0, 2.0, 1.0, 1.0, 1.0, 1.0, 1.0]
    # every LavaGrid step costs -3 on objective 1 (no goal is within 8 steps of Room's start)
    expected_1 = [d0[0, 1].item() + 3.0 * t for t in range(8)]
    torch.testing.assert_close(steps["desired_return"][:, 1], torch.tensor(expected_1))
    # objective 0: the start minus the undiscounted return so far (far below max_return 300: no clip)
    torch.testing.assert_close(steps["desired_return"][:, 0], d0[0, 0] - steps["eval_episode_return"][:, 0].float())


def test_pcn_clips_the_evaluation_command_at_max_return():
    from tensordict import TensorDict

    _, _, agent = _pcn(hidden=(16, 16), eval_weights=2, pcn_max_return=(300.0, 5.0))
    agent.eval_policy._commands = lambda: (torch.tensor([[1.0, 2.0], [1.0, 2.0]]), torch.tensor([3.0, 3.0]))
    agent.eval_policy.stale = True
    w = torch.tensor([[1.0, 0.0]])
    seen = []
    for ret, disc in (([0.0, 0.0], 1.0), ([-1.0, -4.0], 0.995), ([-2.0, -5.0], 0.99)):  # rewards [-1,-4], [-1,-1]
        td = TensorDict(observation=torch.zeros(1, 125), preference=w, eval_episode_return=torch.tensor([ret]),
                        eval_episode_discount=torch.tensor([[disc]]), batch_size=[1])
        td = agent.eval_policy(td)
        seen.append(td["desired_return"][0].tolist() + td["desired_horizon"][0].tolist())
    assert seen == [[1.0, 2.0, 3.0], [2.0, 5.0, 2.0], [3.0, 5.0, 1.0]]  # min(2 + 4, 5) = 5, min(5 + 1, 5) = 5


def test_continuous_pcn_noise_is_drawn_per_action_dimension(single_thread):
    pytest.importorskip("mujoco")
    from tensordict import TensorDict

    cfg, _, agent = _pcn("MOHalfCheetahDR-v5", hidden=(16, 16))
    assert cfg.pcn_noise == 0.2
    policy = agent.explore_policy
    policy.random_actions = False
    policy.network.module.fc[-1].weight.data.zero_()
    policy.network.module.fc[-1].bias.data.zero_()  # prediction 0: the action is the noise
    td = TensorDict(observation=torch.zeros(4000, 17 * 3 + 6 * 2), desired_return=torch.zeros(4000, 2),
                    desired_horizon=torch.ones(4000, 1), batch_size=[4000])
    a = policy(td)["action"]  # [4000, 6]
    assert a.shape == (4000, 6) and abs(float(a.std()) - 0.2) < 0.01
    corr = torch.corrcoef(a.T)  # independent dimensions (one shared value would give correlation 1)
    assert float((corr - torch.eye(6)).abs().max()) < 0.1


def test_pcn_network_is_the_authors_net_arch():
    cfg, _, agent = _pcn(hidden=(256, 256, 256, 256))
    assert "pcn_hidden" not in cfg.keys()  # PCN's widths are hidden (pcn_hidden: a renamed key)
    net = agent.loss.policy_network.module
    assert (net.s_emb[0].out_features, net.c_emb[0].out_features) == (256, 256)
    assert [m.out_features for m in net.fc if isinstance(m, torch.nn.Linear)] == [256, 256, 256, 3]
    with pytest.warns(DeprecationWarning, match="pcn_hidden"):  # MORL-Baselines' hidden_dim: one hidden layer
        _, _, old = _pcn(hidden=(256, 256, 256, 256), pcn_hidden=64)
    assert [m.out_features for m in old.loss.policy_network.module.fc if isinstance(m, torch.nn.Linear)] == [64, 3]


# ---------------------------------------------------------------------- PGMORL / MORL/D evaluation
def test_pgmorl_evaluates_with_the_nearest_pareto_archive_snapshot(single_thread):
    """The authors' PGMORL.eval: the archive snapshot of nearest weight acts (pgmorl.py:719-768)."""
    pytest.importorskip("mujoco")
    from tensordict import TensorDict
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    from morl_trl.algorithms.pgmorl.recipe import make_pgmorl_agent, make_pgmorl_training_env

    cfg = resolve_config("pgmorl", "MOHalfCheetahDR-v5", quick=True, pgmorl_pop=2, num_envs=2,
                         pgmorl_envs_per_member=1, frames_per_batch=32, hidden=(8,))
    env = make_pgmorl_training_env(cfg, CPU)
    agent = make_pgmorl_agent(cfg, env, gamma=0.99, device=CPU)

    def snapshot(mean):  # a policy whose mean action is `mean` everywhere
        state = agent.head.member_state(0)
        for name, t in state.items():
            t.zero_()
        state[max(n for n in state if n.startswith("mean.mlp.") and n.endswith(".bias"))].fill_(mean)  # the output bias
        return state

    agent._archive_snapshot(np.array([10.0, 0.0]), torch.tensor([0.9, 0.1]), snapshot(0.5))
    agent._archive_snapshot(np.array([0.0, 10.0]), torch.tensor([0.1, 0.9]), snapshot(-0.5))
    agent._archive_snapshot(np.array([-1.0, -1.0]), torch.tensor([0.5, 0.5]), snapshot(0.9))  # dominated: dropped
    torch.testing.assert_close(torch.stack([e["weight"] for e in agent.archive_members]),
                               torch.tensor([[0.9, 0.1], [0.1, 0.9]]))
    obs = torch.randn(4, env.observation_spec["observation"].shape[-1])
    td = TensorDict(observation=obs, preference=torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.6, 0.4], [0.45, 0.55]]),
                    batch_size=[4])
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        action = agent.eval_policy(td)["action"]
    torch.testing.assert_close(action, torch.tensor([0.5, -0.5, 0.5, -0.5]).unsqueeze(-1).expand(4, 6))


def test_morld_evaluates_with_the_nearest_pareto_archive_snapshot(single_thread):
    """The authors' MORL/D eval: the archive snapshot of nearest weight acts (morld.py:434-488)."""
    from tensordict import TensorDict
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    from morl_trl.algorithms.morld.recipe import make_morld_agent, make_morld_training_env

    cfg = resolve_config("morld", "MOLavaGridDR-v0", quick=True, hidden=(8,))
    env = make_morld_training_env(cfg, CPU)
    agent = make_morld_agent(cfg, env, gamma=0.995, device=CPU)
    params = agent.loss.actor_network_params.detach().cpu()

    def snapshot(action):  # a policy that always prefers `action` (logits: 10 on it, 0 elsewhere)
        one = params.apply(lambda x: torch.zeros_like(x[0]))
        one["module", "0", "module", "mlp", "2", "bias"][..., action] = 10.0
        return {"weight": torch.tensor([0.8, 0.2]), "actor": one} if action == 2 else \
            {"weight": torch.tensor([0.3, 0.7]), "actor": one}

    obs = torch.randn(4, 125)
    td = lambda: TensorDict(observation=obs, preference=torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.6, 0.4], [0.5, 0.5]]),  # noqa: E731
                            batch_size=[4])
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        before = agent.eval_policy(td())["action"]  # empty archive: the population's members
        agent.archive.add(torch.tensor([[5.0, 1.0], [1.0, 5.0]]), [snapshot(2), snapshot(0)])
        after = agent.eval_policy(td())["action"]
    assert before.shape == (4,)
    # nearest snapshot weight: [0.8, 0.2] (action 2) for [1, 0] and [0.6, 0.4]; [0.3, 0.7] (action 0) for the others
    assert after.tolist() == [2, 0, 2, 0]


# ---------------------------------------------------------------------- GPI-PD model rollouts
def test_model_termination_functions_are_the_authors():
    from morl_trl.objectives.dynamics import model_termination

    ll = torch.zeros(4, 26)  # history-stacked: the last 8 dims are the state [x, y, vx, vy, angle, angvel, leg1, leg2]
    ll[0, -8] = 1.0                   # |x| >= 1
    ll[1, -2:] = 1.0                  # both legs down, reward[0] != 0
    ll[2, -2:] = 1.0                  # both legs down, reward[0] == 0
    reward = torch.tensor([[0.0] * 4, [5.0, 0, 0, 0], [0.0] * 4, [0.0] * 4])
    assert model_termination("lunar_lander", ll, reward).tolist() == [True, True, False, False]
    hum = torch.zeros(3, 1078)
    hum[:, -348] = torch.tensor([1.4, 0.9, 2.1])  # z
    assert model_termination("humanoid", hum, torch.zeros(3, 2)).tolist() == [False, True, True]
    assert model_termination(None, hum, torch.zeros(3, 2)).tolist() == [False, False, False]


def test_gpi_pd_rollouts_start_by_priority_and_stop_at_terminal_states(single_thread):
    pytest.importorskip("mujoco")
    cfg, env, agent = _gpi("gpi_pd", "MOHopperDR-v5", gamma=0.99, gpi_dynamics_rollout_len=2,
                           gpi_dynamics_rollout_batch=8, gpi_uncertainty_threshold=1e9)
    assert cfg.prioritized and cfg.gpi_model_termination == "authors"
    buffer = make_replay_buffer(cfg, CPU)
    with torch.no_grad():
        td = env.rollout(16, agent.explore_policy, break_when_any_done=False)  # [4, 16]
    buffer.extend(td.reshape(-1))
    priority = torch.full((64,), 1e-8)
    priority[5] = 1e8
    buffer.update_priority(torch.arange(64), priority)
    starts = []

    def step(x, **kw):  # the first half of each call's rows lands at height 0.5 (terminal), the rest at 1.25
        obs = x[:, :39]
        starts.append(obs.clone())
        n = x.shape[0]
        target = obs.clone()
        target[:, -11:] = 0.0
        target[:, -11] = torch.where(torch.arange(n) < n // 2, 0.5, 1.25)
        return torch.cat([torch.zeros(n, 3), target - obs], -1), torch.zeros(n)

    agent.dynamics.model.step = step
    assert agent.rollout_model(buffer) == 8 + 4  # 8 starts, then the 4 non-terminal continue
    stored = agent.model_buffer.storage[torch.arange(12)]
    assert stored["next", "terminated"].flatten().tolist() == [True] * 4 + [False] * 4 + [True] * 2 + [False] * 2
    first = buffer.storage[torch.arange(64)]["observation"][5]
    assert all(torch.equal(row, first) for row in starts[0])  # every start state is the top-priority transition


def test_capql_collects_with_the_deterministic_tanh_mean_action(single_thread):
    """The authors' CAPQL: after learning_starts the behaviour action is tanh(mean) (capql.py:454-459)."""
    pytest.importorskip("mujoco")
    from tensordict import TensorDict
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    from morl_trl.recipes import build_agent

    acts = {}
    for det in (True, False):
        torch.manual_seed(0)
        cfg = resolve_config("capql", "MOHopperDR-v5", hidden=(16,), num_envs=2, progress=False,
                             capql_deterministic_collection=det)
        env = make_training_env(cfg, CPU)
        agent = build_agent(cfg, env, gamma=0.99, device=CPU)
        td = TensorDict(observation=torch.randn(8, 39), preference=torch.full((8, 3), 1 / 3), batch_size=[8])
        with set_exploration_type(ExplorationType.RANDOM):  # as the collector
            acts[det] = [agent.explore_policy(td.clone())["action"] for _ in range(2)]
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            mean = agent.eval_policy(td.clone())["action"]
        assert torch.equal(acts[det][0], mean) is det
    assert torch.equal(acts[True][0], acts[True][1]) and not torch.equal(acts[False][0], acts[False][1])


# ---------------------------------------------------------------------- initialisation
def _orthogonal(w: torch.Tensor) -> bool:
    w = w.detach().double()
    m = w @ w.T if w.shape[0] <= w.shape[1] else w.T @ w
    return bool(torch.allclose(m, torch.eye(m.shape[0], dtype=torch.float64), atol=1e-4))


@pytest.mark.parametrize("algo, env_id", [("capql", "MOHopperDR-v5"), ("sac", "MOHopperDR-v5"),
                                          ("sac", "MOLavaGridDR-v0"), ("pcn", "MOLavaGridDR-v0"),
                                          ("morld", "MOLavaGridDR-v0"), ("morld", "MOHopperDR-v5")])
def test_every_layer_has_the_authors_orthogonal_init(algo, env_id, single_thread):
    """The authors' layer_init on every layer: orthogonal weights (gain 1), zero biases (hyperparameters.toml
    ``<method>.<domain>.network.init``)."""
    if "Hopper" in env_id:
        pytest.importorskip("mujoco")
    from morl_trl.recipes import build_agent, build_training_env

    cfg = resolve_config(algo, env_id, quick=True, hidden=(16, 8), progress=False)
    env = build_training_env(cfg, CPU)
    agent = build_agent(cfg, env, gamma=0.99, device=CPU)
    checked = 0
    for name, t in agent.loss.named_parameters():
        if name.endswith("weight") and t.ndim >= 2:
            ws = t.reshape(-1, *t.shape[-2:])  # (ensembles / populations: every member)
            assert all(_orthogonal(w) for w in ws), name
            checked += 1
        elif name.endswith("bias"):
            assert bool((t == 0).all()), name
    assert checked >= 3
    target = getattr(agent.loss, "target_qvalue_network_params", None)
    if target is not None:  # the target critics start as the (re-initialised) critics
        assert (target.data == agent.loss.qvalue_network_params.data).all()


# ---------------------------------------------------------------------- SAC / MOSAC: delayed actor, tanh log-std
def _updates(algo, agent, buffer, n) -> None:
    """``n`` of the recipe's updates (MORL/D's off the shared clock)."""
    if algo == "morld":
        morld.updates_at(agent, buffer, [None] * n)
    else:
        for _ in range(n):
            actor_critic.update(agent, buffer)


def _steps(agent) -> dict:
    return {name: _adam_steps(opt) for name, opt in agent.optimizers.items()}


@pytest.mark.parametrize("algo, policy_freq, expected", [
    ("sac", 2, {"actor": 4, "qvalue": 5, "alpha": 4}),  # turns at updates 2 and 4: 2 actor steps each
    ("sac", 1, {"actor": 5, "qvalue": 5, "alpha": 5}),  # an actor turn at every update (policy_freq=1)
    ("morld", 2, {"actor": 4, "qvalue": 5, "alpha": 4}),  # MORL/D's MOSAC members, one batched step
])
def test_sac_and_mosac_delay_the_actor_as_the_authors(algo, policy_freq, expected, single_thread):
    """The authors' continuous SAC/MOSAC: a critic step every update; ``if global_step % 2 == 0`` two actor
    (+ temperature) steps (sac_continuous.py:435-456; mosac_continuous_action.py:460-482): 5 updates ->
    5 critic, 4 actor and 4 temperature Adam steps."""
    pytest.importorskip("mujoco")
    from morl_trl.recipes import build_agent, build_training_env

    torch.manual_seed(0)
    # (MORL/D's round robin takes its actor turns from the shared frame clock, test_morld_round_robin.py;
    # here its batched concurrent schedule, whose updates count them as SAC's)
    extra = dict(morld_schedule="concurrent", frames_per_batch=60) if algo == "morld" else {}
    cfg = resolve_config(algo, "MOHopperDR-v5", quick=True, hidden=(16,), batch_size=8, buffer_size=1024,
                         progress=False, policy_freq=policy_freq, **extra)
    assert resolve_config(algo, "MOHopperDR-v5").policy_freq == 2  # the default: the authors'
    env = build_training_env(cfg, CPU)
    agent = build_agent(cfg, env, gamma=0.99, device=CPU)
    buffer = make_replay_buffer(cfg, CPU)
    buffer.extend(env.rollout(8, break_when_any_done=False).reshape(-1))
    critic = agent.loss.qvalue_network_params.clone()
    actor = agent.loss.actor_network_params.clone()
    _updates(algo, agent, buffer, 1)  # update 1: critic only when delayed
    moved = (agent.loss.actor_network_params != actor).any()
    assert bool(moved) is (policy_freq == 1)
    assert bool((agent.loss.qvalue_network_params != critic).any())
    _updates(algo, agent, buffer, 4)
    assert _steps(agent) == expected
    assert agent.critic_steps == 5


def test_sac_and_mosac_actors_rescale_the_log_std_with_tanh_into_minus_5_to_2(single_thread):
    """The authors' SAC/MOSAC actor: ``log_std = -5 + 3.5 (tanh(x) + 1)`` (mosac_continuous_action.py:95-103)."""
    from torchrl.data import Bounded

    from morl_trl.objectives.networks import gaussian_head

    head = gaussian_head(torch.nn.Identity(), "tanh_log_std")
    x = torch.tensor([0.3, -0.2, 0.0, 50.0, -50.0, 0.5])  # loc [0.3, -0.2, 0.0], log-std input [50, -50, 0.5]
    loc, scale = head(x)
    torch.testing.assert_close(loc, torch.tensor([0.3, -0.2, 0.0]))
    expected = [2.0, -5.0, -5 + 3.5 * (math.tanh(0.5) + 1)]  # the bounds, and tanh(0.5) = 0.4621 -> 0.1175
    torch.testing.assert_close(scale.log(), torch.tensor(expected), atol=1e-5, rtol=0)
    for algo in ("sac", "morld", "morld_psa", "mosac"):
        assert resolve_config(algo, "MOHopperDR-v5").actor_scale == "tanh_log_std", algo
    from morl_trl.objectives import make_gaussian_actor

    actor = make_gaussian_actor(3, Bounded(-1.0, 1.0, (2,)), 2, num_cells=(8,), scale="tanh_log_std")
    assert type(actor.module[0].module).__name__ == "_LocTanhLogStd"


# ---------------------------------------------------------------------- Envelope: PER priorities
def test_envelope_per_adds_the_running_max_priority_as_the_authors(single_thread):
    """MORL-Baselines' buffer (envelope.py:344-349; prioritized_buffer.py:93,141,188-196): an update writes
    (|w . delta| + M)^0.6 with M the running maximum written priority (1e-5 at first); new items get M."""
    from tensordict import TensorDict

    from morl_trl.data import RunningMaxPrioritizedSampler

    cfg = resolve_config("envelope", "MOLavaGridDR-v0", hidden=(16,), num_envs=2, batch_size=4, buffer_size=64,
                         progress=False)
    assert (cfg.prioritized, cfg.per_running_max, cfg.per_alpha) == (True, True, 0.6)
    buffer = make_replay_buffer(cfg, CPU)
    sampler = buffer._sampler
    assert type(sampler) is RunningMaxPrioritizedSampler
    buffer.extend(TensorDict({"x": torch.arange(6.0)}, [6]))
    torch.testing.assert_close(sampler._sum_tree.leaves()[:6], torch.full((6,), 1e-5))
    buffer.update_priority(torch.tensor([1, 4]), torch.tensor([0.5, 2.0]))
    first = torch.tensor([(0.5 + 1e-5) ** 0.6, (2.0 + 1e-5) ** 0.6])  # 0.65976, 1.51572
    torch.testing.assert_close(sampler._sum_tree.leaves()[[1, 4]], first)
    buffer.update_priority(torch.tensor([2]), torch.tensor([0.5]))  # + the running max 1.51572 now
    assert sampler._sum_tree.leaves()[2].item() == pytest.approx((0.5 + float(first[1])) ** 0.6, rel=1e-6)  # 1.52285
    buffer.extend(TensorDict({"x": torch.arange(2.0)}, [2]))  # new items at the running max
    leaves = sampler._sum_tree.leaves()[:8]
    assert leaves[6].item() == leaves[7].item() == pytest.approx(1.52285, rel=1e-4)
    assert leaves[0].item() == pytest.approx(1e-5)  # never updated: still the first running max
    # TorchRL's rule stays an option: (p + eps)^alpha, new items at the largest raw priority
    other = make_replay_buffer(resolve_config("envelope", "MOLavaGridDR-v0", per_running_max=False), CPU)
    assert type(other._sampler) is not RunningMaxPrioritizedSampler


def test_the_pixel_networks_cnn_gets_the_authors_orthogonal_init_too():
    """The authors' layer_init covers every Linear and Conv2d (mo_utils/networks.py:143-157): Envelope's,
    discrete SAC's and GPI's NatureCNN on Mario (hyperparameters.toml ``<method>.mario.network.init``)."""
    from morl_trl.objectives import make_vector_q_network
    from morl_trl.objectives.gpi import GPIQNetwork

    torch.manual_seed(0)
    envelope = make_vector_q_network((4, 84, 84), 7, 3, num_cells=(16,), preference_layer=1, init="orthogonal")
    gpi = GPIQNetwork((4, 84, 84), 7, 3, hidden=(16, 16), num_nets=2)
    for net in (envelope, gpi):
        convs = [m for m in net.modules() if isinstance(m, torch.nn.Conv2d)]
        assert len(convs) == 3 * (2 if net is gpi else 1)
        for conv in convs:
            w = conv.weight.reshape(conv.weight.shape[0], -1)  # [32, 256], [64, 512], [64, 576]: rows orthonormal
            torch.testing.assert_close(w @ w.T, torch.eye(w.shape[0]), atol=1e-4, rtol=0)
            assert bool((conv.bias == 0).all())


# ---------------------------------------------------------------------- GPI-PD: the dynamics model's fit
def test_gpi_pd_humanoid_model_clips_gradients_at_10_and_starts_max_logvar_at_0_1(monkeypatch):
    """The authors' Humanoid GPI-PD script: dynamics_max_grad_norm 10, dynamics_max_logvar_scale 0.1 (the other
    domains: no clipping, 0.5); probabilistic_ensemble.py:29-43."""
    from morl_trl.objectives.dynamics import DynamicsLoss, ProbabilisticEnsemble, fit_dynamics

    got = {env: (c.gpi_dynamics_max_grad_norm, c.gpi_dynamics_max_logvar) for env in
           ("MOHumanoidDR-v5", "MOHopperDR-v5", "MOLunarLanderDR-v0")
           for c in [resolve_config("gpi_pd", env)]}
    assert got == {"MOHumanoidDR-v5": (10.0, 0.1), "MOHopperDR-v5": (None, 0.5), "MOLunarLanderDR-v0": (None, 0.5)}
    torch.manual_seed(0)
    model = ProbabilisticEnsemble(3, 2, hidden=(8,), max_logvar=0.1)
    assert model.max_logvar.tolist() == [[pytest.approx(0.1)] * 2] and model.min_logvar.tolist() == [[-10.0] * 2]
    _, logvar = model(torch.randn(5, 3) * 100)
    assert logvar.max().item() == pytest.approx(0.1, abs=1e-3)  # the soft upper bound starts at 0.1
    calls = []
    real = torch.nn.utils.clip_grad_norm_

    def spy(params, max_norm, *a, **k):
        params = list(params)
        calls.append(max_norm)
        out = real(params, max_norm, *a, **k)
        assert torch.linalg.vector_norm(torch.stack([p.grad.norm() for p in params])) <= max_norm * (1 + 1e-5)
        return out

    monkeypatch.setattr(torch.nn.utils, "clip_grad_norm_", spy)
    x, y = torch.randn(40, 3) * 50, torch.randn(40, 2) * 50  # 4 held out, 36 trained: 3 batches of 16 per epoch
    for norm, expected in ((10.0, [10.0] * 6), (None, [])):
        calls.clear()
        fit_dynamics(DynamicsLoss(model, num_actions=None), x, y, batch_size=16, max_epochs=2, patience=10,
                     max_grad_norm=norm)
        assert calls == expected
    # the recipe passes both to the model and to every fit
    pytest.importorskip("mujoco")
    fits = []
    monkeypatch.setattr("morl_trl.algorithms.gpi.recipe.fit_dynamics", lambda *a, **k: fits.append(k["max_grad_norm"]))
    cfg, env, agent = _gpi("gpi_pd", "MOHopperDR-v5", gamma=0.99, gpi_dynamics_max_grad_norm=10.0,
                           gpi_dynamics_max_logvar=0.1, gpi_dynamics_train_freq=16, gpi_dynamics_rollout_starts=10**6)
    assert agent.dynamics.model.max_logvar.flatten()[0].item() == pytest.approx(0.1)
    buffer = make_replay_buffer(cfg, CPU)
    buffer.extend(env.rollout(8, break_when_any_done=False).reshape(-1))
    agent._dyna(buffer, 0, 16)
    assert fits == [10.0]


# ---------------------------------------------------------------------- PGMORL: a reset at every iteration
@pytest.mark.parametrize("reset, continuing", [(True, 0), (False, 4)])
def test_pgmorl_resets_every_sub_env_at_the_start_of_each_iteration(reset, continuing, single_thread):
    """The authors' member train() starts with envs.reset (mo_ppo.py:628): no episode runs across iterations
    (``pgmorl_reset_each_iteration``; false: all 4 sub-envs' episodes go on, none ends within 16 steps)."""
    pytest.importorskip("mujoco")
    from morl_trl.recipes.off_policy import make_collector
    from morl_trl.algorithms.pgmorl.recipe import make_pgmorl_agent, make_pgmorl_training_env

    cfg = resolve_config("pgmorl", "MOHopperDR-v5", pgmorl_pop=2, num_envs=4, pgmorl_envs_per_member=2,
                         frames_per_batch=64, frames=192, hidden=(8,), progress=False, pgmorl_reset_each_iteration=reset)
    assert resolve_config("pgmorl", "MOHopperDR-v5").pgmorl_reset_each_iteration is True
    torch.manual_seed(0)
    env = make_pgmorl_training_env(cfg, CPU)
    agent = make_pgmorl_agent(cfg, env, gamma=0.99, device=CPU)
    collector = make_collector(cfg, env, agent.explore_policy, CPU, frames_to_go=192, track_traj_ids=True)
    batches = [b.clone() for _, b in zip(range(3), collector)]  # [4 sub-envs, 16 steps] each
    collector.shutdown()
    assert [tuple(b.shape) for b in batches] == [(4, 16)] * 3
    for before, after in zip(batches[:-1], batches[1:]):
        last, first = before["collector", "traj_ids"][:, -1], after["collector", "traj_ids"][:, 0]
        assert not bool(before["next", "done"][:, -1].any())
        assert int((last == first).sum()) == continuing  # sub-envs whose episode continues into the next batch


# ---------------------------------------------------------------------- MORL/D: the archive evaluation
def test_morld_evaluates_each_member_on_5_separate_stochastic_episodes_per_exchange(single_thread):
    """The authors' MORL/D evaluates every member after each exchange with num_eval_episodes_for_front = 5
    stochastic episodes on a DR env (morld.py:281-334,576-578): pop_size x 5 episodes (LavaGrid 25,
    the others 30), never counted as training frames; the archive holds the non-dominated evaluations."""
    from morl_trl.algorithms.morld.recipe import make_morld_agent, make_morld_training_env

    assert [resolve_config(a, e).pop_size * resolve_config(a, e).morld_eval_episodes for a, e in
            (("morld", "MOLavaGridDR-v0"), ("morld_psa", "MOLunarLanderDR-v0"))] == [25, 30]
    torch.manual_seed(0)
    cfg = resolve_config("morld", "MOLavaGridDR-v0", quick=True, hidden=(8,))
    env = make_morld_training_env(cfg, CPU)
    agent = make_morld_agent(cfg, env, gamma=0.995, device=CPU)
    evals = agent.evaluate_members()
    assert evals.shape == (5, 2) and bool(torch.isfinite(evals).all())
    assert agent.eval_episodes == 25 and agent._eval_env.batch_size == torch.Size([25])
    agent.exchange()
    assert agent.eval_episodes == 50 and agent.exchanges == 1
    archived = agent.archive.evaluations
    assert 1 <= archived.shape[0] <= 5
    # without it (morld_eval_episodes=0) the archive takes the training episodes' returns: none ended yet
    other = make_morld_agent(resolve_config("morld", "MOLavaGridDR-v0", quick=True, hidden=(8,), morld_eval_episodes=0),
                             env, gamma=0.995, device=CPU)
    other.exchange()
    assert other.eval_episodes == 0 and len(other.archive) == 0


def test_capql_recipe_scores_log_pi_as_the_authors_and_an_older_run_resumes_with_torchrls(single_thread):
    """``capql_log_prob``: the recipe's loss uses the authors' log pi (1e-6 in the Jacobian's log, clamped to
    [-1000, 1000]; hyperparameters.toml [capql.hopper.network] log_prob) by default; a config.json written before the
    key existed resumes with TorchRL's exact TanhNormal, what its code computed."""
    pytest.importorskip("mujoco")
    from morl_trl.recipes import build_agent
    from morl_trl.recipes.config.train_config import upgrade_keys

    for form in ("clamped", "exact"):
        kw = {} if form == "clamped" else dict(capql_log_prob="exact")
        cfg = resolve_config("capql", "MOHopperDR-v5", hidden=(16,), num_envs=2, progress=False, **kw)
        assert cfg.capql_log_prob == form
        agent = build_agent(cfg, make_training_env(cfg, CPU), gamma=0.99, device=CPU)
        assert agent.loss.log_prob_form == form
    assert upgrade_keys({}, "capql", "config.json", saved=True)["capql_log_prob"] == "exact"
    with pytest.raises(ValueError, match="capql_log_prob"):
        resolve_config("capql", "MOHopperDR-v5", capql_log_prob="tanh")
