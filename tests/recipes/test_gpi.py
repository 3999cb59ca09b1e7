"""GPI-LS / GPI-PD recipes: config, the weight-support loop, Dyna, and short real runs."""

import numpy as np
import pytest
import torch

from morl_trl.recipes import resolve_config, run_training, train
from morl_trl.recipes.config import valid_keys
from morl_trl.algorithms.gpi.recipe import GPIAgent, make_gpi_agent, on_batch
from morl_trl.recipes.off_policy import make_replay_buffer, make_training_env
from tests.recipes._helpers import assert_checkpoints_equal, assert_logs_equal, interrupt_then_resume, last_checkpoints

TINY = dict(num_envs=4, frames_per_batch=32, init_random_frames=64, updates_per_batch=2, batch_size=16,
            hidden=(16, 16), buffer_size=4096, gpi_iteration_frames=64, gpi_front_episodes=1,
            gpi_dynamics_hidden=(16,), gpi_dynamics_train_freq=64, gpi_dynamics_rollout_freq=32,
            gpi_dynamics_rollout_starts=64, gpi_dynamics_rollout_batch=50, progress=False)


def _tiny(algo):
    """TINY's keys that ``algo`` has (GPI-LS has no dynamics model)."""
    return {k: v for k, v in TINY.items() if k in valid_keys(algo)}


def test_config_has_the_authors_settings():
    ll = resolve_config("gpi_pd", "MOLunarLanderDR-v0")
    assert (ll.gpi_uncertainty_threshold, ll.gpi_dynamics_train_freq, ll.gpi_dynamics_rollout_freq) == (20.0, 5000, 5000)
    # hyperparameters.toml [gpi_pd.lunarlander.train]: num_eval_episodes_for_front = 1 (GPI-LS: 3)
    assert (ll.gpi_front_episodes, ll.gpi_num_nets, ll.gpi_dropout, ll.gpi_layer_norm) == (1, 2, 0.01, True)
    assert (ll.target_update_period, ll.eps_frames, ll.prioritized, ll.per_importance_weights) == (1000, 1_000_000, True, False)
    lava = resolve_config("gpi_pd", "MOLavaGridDR-v0")
    assert (lava.gpi_uncertainty_threshold, lava.gpi_dynamics_lr, lava.gpi_dynamics_hidden) == (1e4, 3e-5, (512, 512))
    assert (lava.eps_frames, lava.target_update_period, lava.gpi_iteration_frames) == (5_000_000, 200, 50_000)
    mario = resolve_config("gpi_ls", "MOSuperMarioBrosZeroShot-v2")
    assert (mario.hidden, mario.gpi_layer_norm, mario.eval_weights, mario.batch_size) == ((512, 512), False, 32, 64)


def _agent(algo, **kw):
    torch.manual_seed(0)
    cfg = resolve_config(algo, "MOLavaGridDR-v0", **{**_tiny(algo), **kw})
    env = make_training_env(cfg, torch.device("cpu"))
    return cfg, env, make_gpi_agent(cfg, env, gamma=0.995, device=torch.device("cpu"))


def test_first_iteration_trains_e1_with_the_other_extrema_in_the_support():
    _, env, agent = _agent("gpi_ls")
    np.testing.assert_array_equal(agent.weight, [1, 0])
    np.testing.assert_array_equal(agent.support, [[0, 1], [1, 0]])
    # every sub-env's first episode acts with w = e_1 (SPEC §6), later ones draw their weight from the support
    assert env.reset()["preference"].tolist() == [[1.0, 0.0]] * 4
    assert env.reset()["preference"].tolist() == [[0.0, 1.0], [1.0, 0.0], [1.0, 0.0], [1.0, 0.0]]
    torch.testing.assert_close(agent.loss.current_weight, torch.tensor([1.0, 0.0]))


@pytest.mark.parametrize("first", ["w", "support"])
def test_an_iteration_begins_with_every_sub_env_reset_acting_with_w_as_the_authors(first):
    """SPEC §6 (the authors' and MB's train_iteration: env.reset(), then act with the new corner weight w until that
    episode ends, then random.choice(M)); ``gpi_first_episode="support"``: the episodes in progress go on."""
    from morl_trl.runs.env_state import base_env_of
    from morl_trl.training.parts import make_collector

    cfg, env, agent = _agent("gpi_ls", gpi_first_episode=first)
    buffer = make_replay_buffer(cfg, torch.device("cpu"))
    collector = make_collector(cfg, env, agent.explore_policy, torch.device("cpu"), return_same_td=True)
    batches = iter(collector)
    batch = next(batches)  # [4 sub-envs, 8 steps]: 32 frames
    assert batch["preference"][:, 0].tolist() == ([[1.0, 0.0]] * 4 if first == "w" else
                                                 [[0.0, 1.0], [1.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    on_batch(agent, batch, buffer, 32)
    on_batch(agent, next(batches), buffer, 64)  # the iteration ends; no episode has ended yet (16 steps each)
    steps = base_env_of(env)._step_count
    preference_before = collector._carrier["preference"].clone()
    assert steps.tolist() == [16] * 4 and agent.begin_pending
    agent.begin_pending_iteration(buffer, collector)
    np.testing.assert_array_equal(agent.weight, [0, 1])
    batch = next(batches)
    if first == "w":  # new episodes, all acting with w = e_2
        assert batch["preference"].tolist() == [[[0.0, 1.0]] * 8] * 4
        assert batch["episode_return"][:, 0].abs().sum() == 0 and base_env_of(env)._step_count.tolist() == [8] * 4
    else:  # the episodes in progress go on
        assert torch.equal(batch["preference"][:, 0], preference_before)
        assert base_env_of(env)._step_count.tolist() == [24] * 4


@pytest.mark.parametrize("weight", ["iteration", "episode"])
def test_the_update_weight_is_the_iterations_or_with_the_option_the_episodes_as_mb(weight):
    """``gpi_update_weight``: the first half of each update's batch under the iteration's w (SPEC §6, the record), or
    under the weight of sub-env 0's episode at the batch's last step (MB 1.3.0's ``update(tensor_w)``)."""
    cfg, env, agent = _agent("gpi_ls", gpi_update_weight=weight, init_random_frames=0)
    buffer = make_replay_buffer(cfg, torch.device("cpu"))
    td = env.rollout(8, agent.explore_policy, break_when_any_done=False)
    td["preference"][0, -1] = torch.tensor([0.0, 1.0])  # (sub-env 0's last step acted with e_2)
    on_batch(agent, td, buffer, 32)
    expected = [0.0, 1.0] if weight == "episode" else [1.0, 0.0]
    assert agent.loss.current_weight.tolist() == expected
    on_batch(agent, env.rollout(8, agent.explore_policy, break_when_any_done=False), buffer, 64)
    agent.begin_pending_iteration(buffer)
    assert agent.loss.current_weight.tolist() == [0.0, 1.0]  # the next iteration's w (its PER priorities under it)


def test_iterations_grow_the_ccs_and_pick_the_next_weight():
    cfg, env, agent = _agent("gpi_ls")
    buffer = make_replay_buffer(cfg, torch.device("cpu"))
    td = env.rollout(16, agent.explore_policy, break_when_any_done=False)  # [4, 16] = 64 frames
    on_batch(agent, td, buffer, 64)  # reaches gpi_iteration_frames: evaluate M, add to the CCS
    assert agent.iteration == 1 and agent.begin_pending  # the next weight after the run's step (its evaluation)
    agent.begin_pending_iteration(buffer)
    assert agent.iteration == 2 and not agent.begin_pending
    assert len(agent.linear_support.visited_weights) == 2  # both weights of M were evaluated
    np.testing.assert_array_equal(agent.weight, [0, 1])  # the second extremum
    td = env.rollout(16, agent.explore_policy, break_when_any_done=False)
    on_batch(agent, td, buffer, 128)
    agent.begin_pending_iteration(buffer)
    assert agent.iteration == 3 and len(agent.linear_support.ccs) >= 1
    assert agent.weight.shape == (2,) and np.isclose(agent.weight.sum(), 1)
    # the evaluation policy acts by GPI over the support the loss trains on
    torch.testing.assert_close(agent.eval_policy.support, agent.loss.weight_support)


def test_an_evaluation_at_an_iterations_end_acts_over_the_support_it_trained_on():
    """Issue 48: the run's evaluation at an iteration's end used GPI over the next support (new corner
    weights never trained on: DST seed 11 read 0.663 at 20k frames where the trained support gave 0.844);
    MB's GPIPD.train evaluates after add_solution, before next_weight, and its parity side inside the step."""
    cfg, env, agent = _agent("gpi_ls")
    buffer = make_replay_buffer(cfg, torch.device("cpu"))
    trained = agent.eval_policy.support.clone()
    on_batch(agent, env.rollout(16, agent.explore_policy, break_when_any_done=False), buffer, 64)  # the iteration ends
    torch.testing.assert_close(agent.eval_policy.support, trained)  # what run.step evaluates now
    agent.begin_pending_iteration(buffer)
    assert agent.iteration == 2 and agent.eval_policy.support.shape[0] >= trained.shape[0]
    # a caller that never calls begin_pending_iteration: the next on_batch begins the iteration first
    cfg, env, other = _agent("gpi_ls")
    on_batch(other, env.rollout(16, other.explore_policy, break_when_any_done=False), buffer, 64)
    on_batch(other, env.rollout(16, other.explore_policy, break_when_any_done=False), buffer, 96)
    assert other.iteration == 2 and not other.begin_pending


def test_gpi_pd_rolls_out_the_model_into_its_buffer():
    cfg, env, agent = _agent("gpi_pd", gpi_uncertainty_threshold=1e9, gpi_iteration_frames=10_000)
    buffer = make_replay_buffer(cfg, torch.device("cpu"))
    td = env.rollout(16, agent.explore_policy, break_when_any_done=False)
    on_batch(agent, td, buffer, 64)  # fits the model (train freq 64) and rolls out (starts at 64)
    assert len(agent.model_buffer) == 50
    batch, real = agent.sample_batch(buffer)
    assert batch.shape == (16,) and real.shape == (8,)  # real_ratio 0.5
    cfg2, _, strict = _agent("gpi_pd", gpi_uncertainty_threshold=1e-9, gpi_iteration_frames=10_000)
    assert strict.rollout_model(buffer) == 0  # nothing is that certain


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["gpi_ls", "gpi_pd"])
def test_short_real_run_and_resume_state(tmp_path, algo):
    cfg = resolve_config(algo, "MOLavaGridDR-v0", **_tiny(algo), frames=256, eval_interval=256, eval_weights=3,
                         checkpoint_interval=128, eval_contexts=("MOLavaGridRoom-v0",), eval_random_baseline=False,
                         run_dir=str(tmp_path / algo))
    summary, agent, run_dir, _ = run_training(cfg)
    assert summary["frames"] == 256 and agent.iteration >= 4
    state = agent.state_dict()
    _, _, fresh = _agent(algo)
    fresh.load_state_dict(state)
    np.testing.assert_array_equal(fresh.support, agent.support)
    assert fresh.linear_support.ccs and len(fresh.linear_support.ccs) == len(agent.linear_support.ccs)


def test_continuous_settings_and_agent():
    hop = resolve_config("gpi_ls", "MOHopperDR-v5")
    assert (hop.batch_size, hop.init_random_frames, hop.gpi_gradient_updates, hop.gpi_iteration_frames, hop.tau) == \
        (256, 25_000, 1, 50_000, 0.005)
    pd = resolve_config("gpi_pd", "MOHopperDR-v5")
    assert (pd.gpi_dynamics_train_freq, pd.gpi_dynamics_rollout_freq, pd.gpi_real_ratio) == (2000, 2000, 0.5)
    assert resolve_config("gpi_pd", "MOHalfCheetahDR-v5").gpi_uncertainty_threshold == 10.0
    assert resolve_config("gpi_ls", "MOHumanoidDR-v5").gpi_iteration_frames == 25_000


@pytest.mark.slow
def test_continuous_gpi_pd_learns_rolls_out_and_iterates(tmp_path):
    torch.manual_seed(0)
    kw = {**TINY, "gpi_dynamics_rollout_len": 2, "gpi_uncertainty_threshold": 1e9, "hidden": (16, 16)}
    cfg = resolve_config("gpi_pd", "MOHopperDR-v5", **kw)
    env = make_training_env(cfg, torch.device("cpu"))
    agent = make_gpi_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
    buffer = make_replay_buffer(cfg, torch.device("cpu"))
    td = env.rollout(16, agent.explore_policy, break_when_any_done=False)
    before = [p.clone() for p in agent.loss.actor_network_params.values(True, True)]
    losses, n = on_batch(agent, td, buffer, 64)
    assert n == 2 and 50 <= len(agent.model_buffer) <= 100  # 50 observations x 2 model steps, less the terminated
    assert any(not torch.equal(a, b) for a, b in zip(before, agent.loss.actor_network_params.values(True, True)))
    assert agent.iteration == 1 and len(agent.linear_support.visited_weights) == 3  # M: the 3 extrema
    agent.begin_pending_iteration(buffer)  # (the loop's call after run.step: the next iteration)
    assert agent.iteration == 2


# ---------------------------------------------------------------------- the recipe's runs: counters, Dyna, resume
# 192 frames in batches of 32: iterations end at 64, 128 and 192 (the CCS grows, w and M change), updates from
# 64 frames; GPI-PD fits its model at 128 and rolls it out every 32 frames from 64 (the updates then mix in
# model transitions); checkpoints at 128 and 192, evaluations at 0 and 192
RUN = dict(frames=192, num_envs=4, frames_per_batch=32, init_random_frames=64, updates_per_batch=2, batch_size=16,
           hidden=(16, 16), buffer_size=1024, gpi_iteration_frames=64, gpi_front_episodes=1,
           gpi_dynamics_hidden=(16,), gpi_dynamics_train_freq=128, gpi_dynamics_rollout_freq=32,
           gpi_dynamics_rollout_starts=64, gpi_dynamics_rollout_batch=50, gpi_uncertainty_threshold=1e9,
           target_update_period=64, eval_interval=192, eval_weights=2, checkpoint_interval=128,
           eval_contexts=("MOLavaGridRoom-v0",), progress=False, eval_random_baseline=False)


def _recipe_run(tmp_path, monkeypatch, algo, env_id, **kw):
    """``morl-trl train``'s run of ``algo`` on ``env_id`` (RUN + ``kw``): its last checkpoint and the Dyna calls."""
    cfg = {k: v for k, v in {**RUN, **kw}.items() if k in valid_keys(algo)}
    # (report.md's figures take seconds to draw and are not checked)
    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    calls = {"fit_model": 0, "rollout_model": 0}

    def counted(name):
        method = getattr(GPIAgent, name)

        def wrapped(self, *args):
            calls[name] += 1
            return method(self, *args)
        monkeypatch.setattr(GPIAgent, name, wrapped)

    for name in calls:
        counted(name)
    train(resolve_config(algo, env_id, run_dir=str(tmp_path / algo), **cfg))
    return last_checkpoints(tmp_path / algo)[0], calls


@pytest.mark.parametrize("algo", ["gpi_ls", "gpi_pd"])
def test_the_recipes_iterations_updates_and_dyna_calls(tmp_path, monkeypatch, algo):
    state, calls = _recipe_run(tmp_path, monkeypatch, algo, "deep-sea-treasure-v0", eval_contexts=None)
    assert (state["frames"], state["updates"]) == (192, 10)  # 2 updates per batch from 64 frames on (5 batches)
    agent = state["agent"]
    # the iteration boundaries at 64, 128 and 192 each evaluated GPI over M at its 2 weights (added to the linear
    # support); those at 64 and 128 then, after the run's step, at the corner weights of the CCS (the next w): 5
    # evaluations; the run's last frame begins no 4th iteration (MB begins none after its last)
    assert (agent["iteration"], agent["iteration_end"], agent["frames"], agent["evaluations"]) == (3, 256, 192, 5)
    assert agent["begin_pending"]
    assert len(agent["linear_support"]["visited"]) == 6
    # GPI-PD: one model fit (at 128) and rollouts every 32 frames from 64 (5 batches)
    assert calls == ({"fit_model": 1, "rollout_model": 5} if algo == "gpi_pd" else {"fit_model": 0, "rollout_model": 0})
    assert (agent["dynamics"] is not None) == (algo == "gpi_pd")


@pytest.mark.parametrize("algo", ["gpi_ls", "gpi_pd"])
def test_the_continuous_recipes_iterations_updates_and_dyna_calls(tmp_path, monkeypatch, algo):
    pytest.importorskip("mujoco")
    state, calls = _recipe_run(tmp_path, monkeypatch, algo, "MOHopperDR-v5", num_envs=2, eval_weights=3,
                               eval_contexts=("MOHopperDefault-v5",), gpi_dynamics_rollout_len=2)
    assert (state["frames"], state["updates"]) == (192, 10)
    assert state["agent"]["updates"] == 10  # the continuous update count (the delayed actor's clock)
    assert (state["agent"]["iteration"], state["agent"]["iteration_end"]) == (3, 256)
    assert calls == ({"fit_model": 1, "rollout_model": 5} if algo == "gpi_pd" else {"fit_model": 0, "rollout_model": 0})


@pytest.mark.slow  # (~10 s)
def test_a_gpi_ls_run_interrupted_and_resumed_ends_as_the_uninterrupted_run(tmp_path, monkeypatch):
    """Ctrl-C after the batch at 64 frames (its updates and the first iteration's end: a checkpoint,
    RunInterrupted), then ``--resume``: MO-LavaGrid snapshots its simulator, so the run continues exactly
    (the CCS, w, M, the iteration and the CCS evaluations' seeds come back from the checkpoint)."""
    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    cfg = {k: v for k, v in RUN.items() if k in valid_keys("gpi_ls")} | dict(frames=128, eval_interval=128)
    whole, resumed = tmp_path / "whole", tmp_path / "resumed"
    train(resolve_config("gpi_ls", "MOLavaGridDR-v0", run_dir=str(whole), **cfg))
    interrupt_then_resume(monkeypatch, resolve_config("gpi_ls", "MOLavaGridDR-v0", run_dir=str(resumed), **cfg), at=64)
    log = (resumed / "log.txt").read_text()
    assert "resumed from frames_000000000064 at 64 frames" in log and "fresh episodes" not in log
    a, b = last_checkpoints(whole, resumed)
    assert (a["frames"], a["updates"], a["agent"]["iteration"]) == (128, 6, 2)  # (no iteration begins after the last frame)
    assert_checkpoints_equal(a, b)
    assert_logs_equal(whole, resumed)


@pytest.mark.parametrize("fused", [True, False])
def test_optimizer_follows_fused_optimizer(fused):
    _, _, agent = _agent("gpi_ls", fused_optimizer=fused)
    assert [g["fused"] for g in agent.optimizers["qvalue"].param_groups] == [fused]


# ---------------------------------------------------------------------- evaluation: the shared evaluator only
LAVA_SUITE = ("MOLavaGridCheckerBoard-v0", "MOLavaGridSmiley-v0", "MOLavaGridSnake-v0", "MOLavaGridIslands-v0",
              "MOLavaGridLabyrinth-v0", "MOLavaGridMaze-v0", "MOLavaGridCorridor-v0", "MOLavaGridRoom-v0")


class _Spy:
    """A GPI policy that records the contexts of the sub-envs it acts for."""

    def __init__(self, policy):
        self.policy, self.contexts = policy, []

    def set_support(self, support):
        self.policy.set_support(support)

    def __call__(self, td):
        self.contexts.append(td["context"].clone())
        return self.policy(td)


def test_gpi_run_is_evaluated_by_gpi_on_the_evaluation_suite_contexts():
    from morl_trl.envs import domain_of
    from morl_trl.recipes.off_policy import build

    cfg = resolve_config("gpi_ls", "MOLavaGridDR-v0", **{**_tiny("gpi_ls"), "eval_weights": 2})
    _, agent, _, evaluator = build(cfg, torch.device("cpu"))
    spy = _Spy(agent.eval_policy)
    evaluator.max_steps = 3  # (the first step is what is checked)
    with pytest.warns(UserWarning, match="still running"):
        result = evaluator.evaluate(spy)
    assert result.context_names == LAVA_SUITE and result.weights.shape == (2, 2)
    spec = domain_of("MOLavaGridDR-v0")
    suite = torch.stack([spec.context_of(name) for name in LAVA_SUITE])  # [8, 93]: each context's lava map
    # the first step: 8 contexts x 2 weights, in the evaluator's order, each context as the suite defines it
    torch.testing.assert_close(spy.contexts[0], suite.repeat_interleave(2, 0))
    assert float(suite[0].sum()) != float(suite[1].sum())  # (distinct maps: the check can fail)


def test_gpi_ccs_values_come_from_the_evaluator_on_contexts_the_training_sampler_draws():
    from morl_trl.envs import make_env
    from morl_trl.evaluation import MultiContextEvaluator, suite_contexts

    cfg, _, agent = _agent("gpi_ls", gpi_front_episodes=2)
    assert isinstance(agent.front_evaluator, MultiContextEvaluator) and agent.front_evaluator.episodes == 2
    spy = _Spy(agent.gpi_policy)
    agent.front_evaluator.max_steps = 3  # (the first step is what is checked)
    with pytest.warns(UserWarning, match="still running"):
        values = agent._evaluate(np.eye(2), agent.support, spy)  # 2 weights x 2 episodes
    assert values.shape == (2, 2) and agent.evaluations == 1
    # each episode's context: the training id's sampler at the evaluation's seed (seed + 10,000 x evaluations)
    drawn = make_env(cfg.env_id, num_envs=4, seed=cfg.seed + 10_000).reset()["context"]
    torch.testing.assert_close(spy.contexts[0], drawn)
    assert len({tuple(c.tolist()) for c in drawn}) == 4  # four fresh contexts
    suite = {tuple(c.tolist()) for c in suite_contexts("MOLavaGridDR-v0")[2]}
    assert not any(tuple(c.tolist()) in suite for c in drawn)  # never the evaluation suite's
    spy.contexts.clear()
    with pytest.warns(UserWarning, match="still running"):
        agent._evaluate(np.eye(2), agent.support, spy)
    torch.testing.assert_close(spy.contexts[0], make_env(cfg.env_id, num_envs=4, seed=cfg.seed + 20_000).reset()["context"])


def test_continuous_gpi_conditions_on_the_run_evaluators_contexts():
    pytest.importorskip("mujoco")
    from morl_trl.recipes.off_policy import build

    cfg = resolve_config("gpi_ls", "MOHopperDR-v5", hidden=(16,), num_envs=2, buffer_size=1024, progress=False,
                         eval_weights=3)
    _, agent, _, evaluator = build(cfg, torch.device("cpu"))
    assert evaluator.contexts.shape == (6, 8)
    torch.testing.assert_close(agent.eval_policy.context_table, evaluator.contexts)
