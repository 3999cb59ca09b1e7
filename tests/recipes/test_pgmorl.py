"""PGMORL: the prediction model on synthetic data, weight grid, performance buffer, task selection,
vector GAE, the population's independence, the agent's evaluation policy, one iteration (pgmorl.on_batch), and
short runs from the CLI's entry point (their counters, the budget's iterations, a resume)."""


import numpy as np
import pytest
import torch
from tensordict import TensorDict

from morl_trl.objectives.batched import BatchedMLP
from morl_trl.objectives.pgmorl import (PPOGaussianHead, make_population_ppo_actor, make_population_value_network,
                                     ppo_population_mlp, scalarize_advantage, vector_gae)
from morl_trl.recipes import resolve_config, run_training, train
from morl_trl.algorithms.pgmorl import recipe as pgmorl
from morl_trl.algorithms.registry import REGISTRY
from morl_trl.algorithms.pgmorl.recipe import make_pgmorl_agent, make_pgmorl_training_env, pgmorl_iterations
from morl_trl.algorithms.pgmorl.evolution import PerformanceBuffer, PerformancePredictor, generate_weights, select_tasks
from tests.recipes._helpers import csv_rows, last_checkpoints


def _model(x, A, a, b, c):
    return A * np.tanh(a * (x - b) / 2.0) + c  # = A (e^{a(x-b)} - 1) / (e^{a(x-b)} + 1) + c


TRUE = [(10.0, 4.0, 0.5, 2.0), (6.0, 3.0, 0.4, -1.0)]  # (A, a, b, c) per objective


def _predictor(with_outlier=False):
    pp = PerformancePredictor()
    F = np.array([1000.0, 800.0])
    for w0 in np.linspace(0.0, 1.0, 9):
        w = np.array([w0, 1.0 - w0])
        delta = np.array([_model(w[j], *TRUE[j]) for j in range(2)])
        pp.add(w, F, F + delta)
    if with_outlier:  # evaluated far from F: outside every neighbourhood that already holds 4 samples
        pp.add(np.array([0.5, 0.5]), 3 * F, 3 * F + 400.0)
    return pp, F


@pytest.mark.parametrize("with_outlier", [False, True])
def test_prediction_model_recovers_the_hyperbolic_improvement_on_synthetic_data(with_outlier):
    pp, F = _predictor(with_outlier)
    test_w = np.array([[0.3, 0.7], [0.8, 0.2], [0.55, 0.45]])
    delta, nxt = pp.predict(test_w, F)
    truth = np.array([[_model(w[j], *TRUE[j]) for j in range(2)] for w in test_w])
    np.testing.assert_allclose(delta, truth, atol=0.3)
    np.testing.assert_allclose(nxt, F + delta)


def test_prediction_model_needs_four_distinct_samples():
    pp = PerformancePredictor()
    for _ in range(5):
        pp.add([0.5, 0.5], [1.0, 1.0], [2.0, 2.0])
    with pytest.raises(ValueError, match="at least 4 distinct samples, it has 1"):
        pp.predict([[0.5, 0.5]], [1.0, 1.0])


def test_weight_grid_is_the_authors():
    np.testing.assert_allclose(generate_weights(0.2, 2), [[0, 1], [0.2, 0.8], [0.4, 0.6], [0.6, 0.4], [0.8, 0.2], [1, 0]],
                               atol=1e-7)
    w3 = generate_weights(0.25, 3)
    assert len(w3) == 15 and np.allclose(w3.sum(-1), 1.0)
    assert w3[:6].tolist() == [[0, 0, 1], [0, 0.25, 0.75], [0, 0.5, 0.5], [0, 0.75, 0.25], [0, 1, 0], [0.25, 0, 0.75]]
    with pytest.raises(ValueError, match="delta must divide 1"):
        generate_weights(0.3, 2)


def test_performance_buffer_bins_keep_the_largest_norms():
    buf = PerformanceBuffer(num_bins=2, size=2, origin=np.array([-1.0, -1.0]))
    for name, ev in [("a", [9.0, 0.0]), ("b", [4.0, 0.0]), ("c", [6.0, 1.0]), ("d", [0.0, 5.0])]:
        buf.add(name, np.array(ev))
    # centred on -origin: angle from the 2nd objective; a, b, c share the bin near objective 1 (size 2: b leaves)
    assert buf.bins == [["d"], ["c", "a"]]
    buf3 = PerformanceBuffer(num_bins=3, size=1, origin=np.zeros(3))  # directions of generate_weights(0.5, 3)
    assert buf3.num_bins == 6
    buf3.add("x", np.array([0.0, 0.0, 2.0]))
    buf3.add("y", np.array([0.0, 0.0, 1.0]))  # same bin, smaller norm: "x" stays
    assert buf3.individuals == ["x"]


def test_task_selection_prefers_the_predicted_hypervolume_gain():
    pp, F = _predictor()
    buf = PerformanceBuffer(num_bins=10, size=2, origin=np.zeros(2))
    buf.add("pol", F)
    tasks = select_tasks(buf, [F], pp, 2, delta_weight=0.2, ref_point=np.zeros(2), sparsity_coef=0.0,
                         rng=np.random.default_rng(0))
    # candidates: weights on the 0.1 grid; objective 0's improvement is up to 12, objective 1's up to 5 (at w=1):
    # HV of {F, pred} grows most with the first objective raised -> w = (1, 0), then the next best distinct weight
    assert [t[0] for t in tasks] == [0, 0]
    assert tasks[0][1].tolist() == [1.0, 0.0]
    assert tasks[1][1].tolist() != [1.0, 0.0]


def test_vector_gae_matches_a_hand_computation_and_scalarizes_per_member():
    r = torch.tensor([[[1.0, 2.0], [0.0, 1.0], [3.0, 0.0]]])  # [1, T=3, k=2]
    v = torch.tensor([[[0.5, 0.5], [1.0, 0.0], [0.0, 2.0]]])
    nv = torch.tensor([[[1.0, 0.0], [0.0, 2.0], [4.0, 4.0]]])
    done = torch.tensor([[[False], [True], [False]]])  # step 1 ends (terminated): no bootstrap, the trace stops
    adv, target = vector_gae(0.9, 0.5, v, nv, r, done, done)
    d2 = r[0, 2] + 0.9 * nv[0, 2] - v[0, 2]
    d1 = r[0, 1] - v[0, 1]
    d0 = r[0, 0] + 0.9 * nv[0, 0] - v[0, 0]
    expected = torch.stack([d0 + 0.45 * d1, d1, d2])
    assert torch.allclose(adv[0], expected) and torch.allclose(target, adv + v)
    a = scalarize_advantage(torch.tensor([[[1.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [0.0, 1.0]]]),
                            torch.tensor([[1.0, 0.0], [0.25, 0.75]]))
    assert a.squeeze(-1).tolist() == [[1.0, 0.0], [0.25, 0.75]]


def test_population_members_are_independent():
    net = ppo_population_mlp(3, 4, 2, (8,))
    x = torch.randn(3, 5, 4)
    net(x)[1].sum().backward()  # member 1's output only
    for w in net.parameters():
        assert w.grad[0].abs().sum() == 0 and w.grad[2].abs().sum() == 0 and w.grad[1].abs().sum() > 0
    state = net.member_state(0)
    net.load_member_state(2, state)
    same_input = x[[2]].expand(3, 5, 4)
    assert torch.allclose(net(same_input)[2], net(same_input)[0])  # member 2 is now a copy of member 0
    assert not torch.allclose(net(same_input)[1], net(same_input)[0])


def _agent(**kw):
    cfg = resolve_config("pgmorl", "MOHalfCheetahDR-v5", quick=True, pgmorl_pop=2, num_envs=2, pgmorl_envs_per_member=1,
                         frames_per_batch=32, hidden=(8,), **kw)
    env = make_pgmorl_training_env(cfg, torch.device("cpu"))
    return cfg, env, make_pgmorl_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))


@pytest.mark.parametrize("eval_obs", ["raw", "normalized"])
def test_eval_policy_acts_with_the_nearest_member(eval_obs):
    cfg, env, agent = _agent(pgmorl_eval_obs=eval_obs)
    head = agent.eval_policy.head
    obs = torch.randn(2, env.observation_spec["observation"].shape[-1])
    prefs = torch.tensor([[0.9, 0.1], [0.05, 0.95]])  # nearest: member 1 (0.2, 0.8) for both... and member 0 (0, 1)
    agent.weights.copy_(torch.tensor([[0.0, 1.0], [1.0, 0.0]]))
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    with set_exploration_type(ExplorationType.DETERMINISTIC):
        act = agent.eval_policy(TensorDict({"observation": obs, "preference": prefs}, [2]))["action"]
    x = obs
    if eval_obs == "normalized":
        norm = agent.eval_policy.obs_norm
        x = ((obs - norm.loc["observation"]) / norm.scale["observation"]).clamp(-10, 10)
    loc, _ = head(x.unsqueeze(0).expand(2, *x.shape))
    expected = torch.stack([loc[1, 0], loc[0, 1]]).clamp(-1, 1)
    assert torch.allclose(act, expected)


def test_on_batch_runs_ppo_on_every_member_and_state_round_trips():
    cfg, env, agent = _agent(pgmorl_epochs=2, pgmorl_minibatches=2)
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):  # as the collector
        batch = env.rollout(16, agent.explore_policy, break_when_any_done=False)  # [2, 16]
    before = [p.detach().clone() for p in agent.loss.parameters()]
    losses, n = pgmorl.on_batch(agent, batch, None, 32)
    assert n == 4 and torch.isfinite(losses["loss_objective"]) and agent.iteration == 1
    moved = [(p.detach() - b).reshape(2, -1).abs().sum(-1) for p, b in zip(agent.loss.parameters(), before)]
    assert all(bool((m > 0).all()) for m in moved if m.numel())  # both members were updated
    state = agent.state_dict()
    _, _, other = _agent(pgmorl_epochs=2, pgmorl_minibatches=2)
    other.load_state_dict(state)
    assert other.iteration == 1 and torch.equal(other.weights, agent.weights)
    # the observation statistics travel with the agent (a re-evaluation with normalised observations needs them)
    assert torch.equal(other.obs_norm.loc["observation"], agent.obs_norm.loc["observation"])
    assert torch.equal(other.reward_norm.loc["reward"], agent.reward_norm.loc["reward"])


@pytest.mark.slow
def test_a_short_pgmorl_run_selects_tasks(tmp_path):
    cfg = resolve_config("pgmorl", "MOHopperDR-v5", pgmorl_pop=4, num_envs=4, pgmorl_envs_per_member=1,
                         frames_per_batch=4 * 256, frames=6 * 256, pgmorl_warmup=2, pgmorl_evo_iterations=2,
                         pgmorl_minibatches=2, pgmorl_epochs=1, hidden=(16,), eval_interval=6 * 256, eval_weights=3,
                         eval_contexts=("MOHopperDefault-v5",), progress=False, eval_random_baseline=False,
                         run_dir=str(tmp_path / "run"))
    summary, agent, _, _ = run_training(cfg)
    assert summary["frames"] == 6 * 256 and 0.0 <= summary["nhgr_mean"] <= 1.0  # one member's frames
    assert agent.iteration == 6 and agent.generation >= 1  # warm-up 2, then task selections at 2, 4, 6
    assert len(agent.predictor) >= 4 and agent.population.individuals


def test_a_tiny_pgmorl_run_resumes_with_its_population(tmp_path):
    cfg = resolve_config("pgmorl", "MOHopperDR-v5", pgmorl_pop=2, num_envs=2, pgmorl_envs_per_member=1,
                         frames_per_batch=128, frames=128, pgmorl_warmup=1, pgmorl_evo_iterations=1,
                         pgmorl_minibatches=2, pgmorl_epochs=1, hidden=(8,), eval_interval=128, eval_weights=3,
                         checkpoint_interval=64, eval_contexts=("MOHopperDefault-v5",), progress=False,
                         eval_random_baseline=False, run_dir=str(tmp_path / "run"))
    _, first, _, _ = run_training(cfg)
    cfg.frames = 192  # (an iteration counts one member's 64 frames)
    summary, agent, _, _ = run_training(cfg, resume=tmp_path / "run")
    assert summary["frames"] == 192 and agent.iteration == first.iteration + 1 == 3
    n = len(first.predictor)  # the prediction samples of the first part carried over, one more evaluation added
    assert n >= 2 and len(agent.predictor) == n + 2
    assert all(np.array_equal(a, b) for a, b in zip(agent.predictor.after[:n], first.predictor.after))


@pytest.mark.parametrize("fused", [True, False])
def test_optimizer_follows_fused_optimizer_with_the_authors_eps(fused):
    _, _, agent = _agent(fused_optimizer=fused)
    (group,) = agent.optimizers["ppo"].param_groups
    assert (group["fused"], group["eps"]) == (fused, 1e-5)


@pytest.mark.parametrize("env_id, iterations, counted", [("MOHopperDR-v5", 400, 3_276_800),
                                                         ("MOHalfCheetahDR-v5", 620, 5_079_040),
                                                         ("MOHumanoidDR-v5", 1240, 10_158_080)])
def test_the_paper_budget_gives_the_authors_ppo_iterations(env_id, iterations, counted):
    """The authors count one member's 4 x 2048 steps per iteration and finish the generation that
    reaches the budget (hyperparameters.toml pgmorl.*.derived: iterations_run, final_global_step)."""
    cfg = resolve_config("pgmorl", env_id)
    per = cfg.frames_per_batch // cfg.pgmorl_pop
    assert per == 8192
    n = pgmorl_iterations(cfg.frames, per, cfg.pgmorl_warmup, cfg.pgmorl_evo_iterations)
    assert (n, n * per, n * cfg.frames_per_batch) == (iterations, counted, 6 * counted)


def test_a_run_does_the_iterations_of_its_budget_counting_one_members_frames(tmp_path):
    # 2 members x 1 env x 32 steps: 64 frames collected, 32 counted per iteration; budget 130 -> 4 iterations
    # wanted, warm-up 1 + whole generations of 2 -> 5 iterations, 160 counted frames (320 collected)
    cfg = resolve_config("pgmorl", "MOHopperDR-v5", pgmorl_pop=2, num_envs=2, pgmorl_envs_per_member=1,
                         frames_per_batch=64, frames=130, pgmorl_warmup=1, pgmorl_evo_iterations=2,
                         pgmorl_minibatches=1, pgmorl_epochs=1, hidden=(8,), eval_interval=10_000, eval_weights=3,
                         eval_contexts=("MOHopperDefault-v5",), progress=False, eval_random_baseline=False,
                         run_dir=str(tmp_path / "run"))
    summary, agent, _, _ = run_training(cfg)
    assert agent.iteration == 5 and summary["frames"] == 160


# 2 members x 2 sub-envs x 32 steps: 128 frames collected, 64 counted (one member's) per iteration; budget 192 ->
# 3 iterations. Warm-up 1 iteration, then generations of 1: the members are evaluated after iterations 1-3 (2
# prediction samples each) and the task selection runs once the prediction model holds 4 (after iterations 2 and
# 3); 2 epochs x 2 minibatches = 4 PPO updates per iteration; checkpoints every 128 counted frames (at 128 and
# the end), evaluations at 0 and 192 (32 weights: the paper's 3-objective set, read from a file, not computed)
TINY = dict(frames=192, pgmorl_pop=2, pgmorl_envs_per_member=2, num_envs=4, frames_per_batch=128, pgmorl_warmup=1,
            pgmorl_evo_iterations=1, pgmorl_epochs=2, pgmorl_minibatches=2, hidden=(8,), eval_interval=192,
            eval_weights=32, checkpoint_interval=128, eval_contexts=("MOHopperDefault-v5",), progress=False,
            eval_random_baseline=False)


def test_a_tiny_pgmorl_run_evaluates_the_members_and_selects_tasks_each_generation(tmp_path, monkeypatch):
    pytest.importorskip("mujoco", reason="PGMORL runs on MuJoCo (continuous actions): needs mujoco")
    # (report.md's figures take seconds to draw and are not read)
    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    calls = {"select_tasks": 0}
    select = pgmorl.PGMORLAgent.select_tasks

    def counted(self, *args, **kw):
        calls["select_tasks"] += 1
        return select(self, *args, **kw)
    monkeypatch.setattr(pgmorl.PGMORLAgent, "select_tasks", counted)
    assert REGISTRY["pgmorl"].train is pgmorl.train_pgmorl
    train(resolve_config("pgmorl", "MOHopperDR-v5", run_dir=str(tmp_path / "run"), **TINY))
    # a task selection at the end of the warm-up and of every generation
    assert calls == {"select_tasks": 3}
    (ckpt,) = last_checkpoints(tmp_path / "run")
    # one member's frames counted (3 iterations x 2 sub-envs x 32 steps), 4 PPO updates per iteration
    assert (ckpt["frames"], ckpt["updates"]) == (192, 12)
    state = ckpt["agent"]
    assert state["iteration"] == 3
    # the prediction model: 2 samples per evaluation after iterations 1-3 (the members' first evaluation, after
    # iteration 0's rollout, has no predecessor); the task selection ran after iterations 2 and 3 (4 samples)
    assert len(state["predictor"][2]) == 6 and state["generation"] == 2
    assert state["member_seeds"] == [42, 42]  # both slots are copies the task selection made
    assert 1 <= len(state["archive"]) == len(state["archive_members"]) <= 10
    assert [len(r) for r in state["population"]["bins"]] and state["population"]
    assert [int(r["frames"]) for r in csv_rows(tmp_path / "run" / "eval/metrics.csv")] == [0, 192]


def test_population_networks_have_the_authors_mo_ppo_init():
    # hyperparameters.toml [pgmorl.hopper.network] (mo_ppo.py:154-209): orthogonal init, hidden gain sqrt(2),
    # critic output gain 1, actor output gain 0.01, zero biases; the state-independent log-std starts at 0
    torch.manual_seed(3)
    actor = make_population_ppo_actor(3, obs_dim=5, action_dim=2, num_cells=(16, 16))
    critic = make_population_value_network(3, obs_dim=5, num_objectives=3, num_cells=(16, 16))
    head = next(m for m in actor.modules() if isinstance(m, PPOGaussianHead))
    assert torch.equal(head.log_std.detach(), torch.zeros(3, 1, 2))
    for net, out_gain in [(head.mean, 0.01), (next(m for m in critic.modules() if isinstance(m, BatchedMLP)), 1.0)]:
        linears = [m for m in net.mlp if hasattr(m, "member_linear")]
        assert len(linears) == 3
        for e in range(3):
            for i, layer in enumerate(linears):
                lin = layer.member_linear(e)
                w = lin.weight.detach()  # [out, in]
                gram = w.T @ w if w.shape[0] >= w.shape[1] else w @ w.T  # gain^2 I for an orthogonal init
                gain2 = 2.0 if i < 2 else out_gain ** 2
                torch.testing.assert_close(gram, gain2 * torch.eye(gram.shape[0]), rtol=0, atol=1e-5 * max(gain2, 1))
                assert torch.equal(lin.bias.detach(), torch.zeros_like(lin.bias))
