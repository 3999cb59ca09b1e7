"""PCN: the episode replay's ranking and commands on a hand-made episode set, the agent's episode
assembly, warm-up and rounds (pcn.on_batch), resume state, and short runs from the CLI's entry point (their
counters, an interrupted run resumed exactly)."""


import pytest
import torch
from tensordict import TensorDict

from morl_trl.data.episode_replay import EpisodeReplay, crowding_distance
from morl_trl.recipes import resolve_config, train
from morl_trl.algorithms.pcn import recipe as pcn
from morl_trl.algorithms.registry import REGISTRY
from morl_trl.recipes.config import valid_keys
from morl_trl.algorithms.pcn.recipe import make_pcn_agent, make_pcn_training_env
from tests.recipes._helpers import (assert_checkpoints_equal, assert_logs_equal, interrupt_then_resume,
                                    last_checkpoints)


def _episode(first_reward, length, k=2):
    """An episode whose whole return is earned at its first step (gamma 1: return = first_reward)."""
    r = torch.zeros(length, k)
    r[0] = torch.tensor(first_reward)
    return torch.zeros(length, 3), torch.zeros(length, dtype=torch.long), r


# A(10,0) len 5, B(0,10) len 6, C(5,5) len 7, D(4,4) len 8 (dominated by C), E(5,5) len 9 (a copy of C)
HAND_MADE = [((10.0, 0.0), 5), ((0.0, 10.0), 6), ((5.0, 5.0), 7), ((4.0, 4.0), 8), ((5.0, 5.0), 9)]


def _replay(capacity=10):
    rb = EpisodeReplay(capacity, gamma=1.0)
    for ret, length in HAND_MADE:
        rb.add(*_episode(ret, length))
    return rb


def test_returns_to_go_and_horizons_are_stored_per_step():
    rb = EpisodeReplay(4, gamma=0.5)
    rb.add(torch.arange(3.0).unsqueeze(-1), torch.tensor([0, 1, 2]), torch.tensor([[1.0, 0.0], [2.0, 4.0], [4.0, 8.0]]))
    obs, action, rtg, horizon = rb.sample(64, generator=torch.Generator().manual_seed(0))
    expected = {0: ([3.0, 4.0], 3.0), 1: ([4.0, 8.0], 2.0), 2: ([4.0, 8.0], 1.0)}  # R_t = r_t + 0.5 R_{t+1}
    for o, a, r, h in zip(obs[:, 0].long().tolist(), action.tolist(), rtg.tolist(), horizon[:, 0].tolist()):
        assert o == a and (r, h) == expected[o]
    assert set(obs[:, 0].long().tolist()) == {0, 1, 2}


def test_crowding_distance_is_the_authors():
    # normalised x = (1, 0, .5, .4, .5), y = (0, 1, .5, .4, .5): neighbours' gaps summed, extremes 1 per objective
    d = crowding_distance(torch.tensor([r for r, _ in HAND_MADE]))
    assert torch.allclose(d, torch.tensor([2.0, 2.0, 0.2, 1.0, 1.0], dtype=torch.float64), atol=1e-6)


def test_ranking_on_a_hand_made_episode_set():
    rb = _replay()
    best = rb.nlargest(3)
    assert best.tolist() == [0, 1, 2]  # A, B and the first copy of (5, 5), from the 3rd best to the best
    # non-dominated first copies: 0; D: -|D - C| - 1e-5; E (a copy): -1e-5; C's crowding 0.2 <= 0.2 doubles its 0
    assert torch.allclose(rb.priority, torch.tensor([0.0, 0.0, 0.0, -(2 ** 0.5) - 1e-5, -1e-5], dtype=torch.float64))
    assert rb.nlargest(4).tolist() == [4, 0, 1, 2]
    returns, horizons = rb.top_commands(7)  # the 5 episodes ranked, repeated to 7
    assert horizons.tolist() == [8.0, 9.0, 5.0, 6.0, 7.0, 8.0, 9.0]
    assert returns[0].tolist() == [4.0, 4.0] and returns[2].tolist() == [10.0, 0.0]


def test_commands_come_from_the_non_dominated_best_episodes():
    rb = _replay()
    std = torch.tensor([10.0, 0.0, 5.0]).std(unbiased=False).item()  # of E, A, B per objective (symmetric): 4.08
    seen = set()
    for seed in range(60):
        desired, horizon = rb.choose_command(4, generator=torch.Generator().manual_seed(seed))
        # among the 4 best (E, A, B, C) the non-dominated first copies are E, A and B: C (len 7) never
        base = {7.0: (5.0, 5.0), 3.0: (10.0, 0.0), 4.0: (0.0, 10.0)}[horizon]  # horizon = length - 2
        raised = desired - torch.tensor(base)
        assert (raised >= 0).all() and int((raised > 0).sum()) <= 1 and float(raised.max()) < std
        seen.add(horizon)
    assert seen == {7.0, 3.0, 4.0}


def test_a_full_replay_drops_the_lowest_ranked_episode():
    rb = _replay(capacity=5)
    rb.nlargest(5)
    rb.add(*_episode((1.0, 1.0), 4))  # full: D (the lowest priority) leaves, the new one (priority 1) stays
    assert sorted(rb.episode_lengths.tolist()) == [4, 5, 6, 7, 9]
    assert rb.priority[-1].item() == 1.0
    rb.add(*_episode((2.0, 2.0), 3))  # next lowest: E (-1e-5)
    assert sorted(rb.episode_lengths.tolist()) == [3, 4, 5, 6, 7]
    state = rb.state_dict()
    other = EpisodeReplay(5, gamma=1.0)
    other.load_state_dict(state)
    assert torch.equal(other.episode_returns, rb.episode_returns) and torch.equal(other.priority, rb.priority)


def test_the_evaluations_ranking_is_stored_as_the_priorities_as_mbs_evaluate():
    # MB's PCN.evaluate ranks with _nlargest, which re-prices the replay in place (pcn.py:363, 250-266): an
    # evaluation between two adds decides which episode the next add evicts. Ours' top_commands does the same
    rb = _replay(capacity=5)
    rb.add(*_episode((1.0, 1.0), 4))  # full: the first (priority 1, oldest) leaves; the new one has priority 1
    assert rb.priority.tolist() == [1.0] * 5
    rb.top_commands(3)
    assert rb.priority.tolist() != [1.0] * 5 and float(rb.priority.min()) < 0  # ranked: a dominated one is below 0
    dropped = int(torch.argmin(rb.priority))
    kept = rb.episode_lengths.tolist()
    rb.add(*_episode((2.0, 2.0), 3))
    assert sorted(rb.episode_lengths.tolist()) == sorted(kept[:dropped] + kept[dropped + 1:] + [3])


def _agent(**kw):
    cfg = resolve_config("pcn", "MOLavaGridDR-v0", quick=True, num_envs=2, pcn_er_episodes=2, pcn_step_episodes=2,
                         pcn_model_updates=3, batch_size=8, **kw)
    env = make_pcn_training_env(cfg, torch.device("cpu"))
    return cfg, env, make_pcn_agent(cfg, env, gamma=0.995, device=torch.device("cpu"))


def _batch(done_at, T=6, k=2):
    """A collected batch [2, T]: sub-env i's episodes end where done_at[i] says; reward (1, 0) per step."""
    done = torch.zeros(2, T, 1, dtype=torch.bool)
    for i, steps in enumerate(done_at):
        for t in steps:
            done[i, t] = True
    obs = torch.zeros(2, T, 125)
    return TensorDict({"observation": obs, "action": torch.zeros(2, T, dtype=torch.long),
                       "next": {"reward": torch.tensor([1.0, 0.0]).expand(2, T, k).clone(), "done": done}}, [2, T])


def test_agent_assembles_episodes_across_batches_then_warms_up_and_runs_rounds():
    cfg, env, agent = _agent()
    assert agent.explore_policy.random_actions
    losses, n = pcn.on_batch(agent, _batch([[2], []]), None, 12)  # sub-env 0: one episode of 3 steps; sub-env 1 runs on
    assert (len(agent.replay), n, losses) == (1, 0, None) and agent.explore_policy.random_actions
    losses, n = pcn.on_batch(agent, _batch([[], [1]]), None, 24)  # sub-env 1's episode: 6 + 2 steps
    assert sorted(agent.replay.episode_lengths.tolist()) == [3, 8]
    assert n == 3 and losses is not None and not agent.explore_policy.random_actions  # warm-up over: one round
    # the return of the 8-step episode with reward (1, 0) per step and gamma 0.995
    assert agent.replay.episode_returns[1, 0].item() == pytest.approx(sum(0.995 ** t for t in range(8)), rel=1e-5)
    desired, horizon = agent.command.command_return, agent.command.command_horizon
    assert horizon.item() in (1.0, 6.0)  # a best episode's length - 2
    losses, n = pcn.on_batch(agent, _batch([[5], []]), None, 36)  # 1 more episode: no round yet (every 2)
    assert n == 0
    state = agent.state_dict()
    _, _, other = _agent()
    other.load_state_dict(state)
    assert other.episodes == 3 and other.next_round == 4 and torch.equal(other.command.command_return, desired)
    assert sorted(other.replay.episode_lengths.tolist()) == [3, 8, 15]  # sub-env 0: 3 + 6 + 6 steps
    assert sorted(other._pending) == [1] and other._pending[1]["reward"].shape[0] == 10  # 4 + 6 steps so far


def test_episodes_spanning_batches_survive_a_collector_that_reuses_the_batch():
    """The collector writes every batch into the same TensorDict (return_same_td): an episode still running at
    the end of a batch must keep its own copy of the steps so far, not a view the next batch overwrites."""
    batches = [_batch([[], []]), _batch([[1], [3]])]
    for i, b in enumerate(batches):  # distinct observations per batch, step and sub-env
        b["observation"] += torch.arange(2 * 6, dtype=torch.float32).reshape(2, 6, 1) + 100 * i
    _, _, fresh = _agent()
    for i, b in enumerate(batches):
        fresh.store_episodes(b.clone(), 12 * (i + 1))
    _, _, reused = _agent()
    buffer = batches[0].clone()
    for i, b in enumerate(batches):
        buffer.update_(b)  # (in place, as the collector's own buffer)
        reused.store_episodes(buffer, 12 * (i + 1))
    assert sorted(reused.replay.episode_lengths.tolist()) == sorted(fresh.replay.episode_lengths.tolist()) == [8, 10]
    for key in ("observation", "return_to_go"):
        a, b = reused.replay._steps[key][: reused.replay._size], fresh.replay._steps[key][: fresh.replay._size]
        assert torch.equal(a, b)
    first = fresh.replay._steps["observation"][: fresh.replay._size, 0]
    assert first[:6].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]  # sub-env 0's first batch, then its second
    assert first[6:8].tolist() == [100.0, 101.0]


def test_eval_policy_acts_on_the_command_of_the_nearest_weight():
    cfg, env, agent = _agent(eval_weights=3)
    for ret, length in HAND_MADE:
        agent.replay.add(torch.zeros(length, 125), torch.zeros(length, dtype=torch.long), _episode(ret, length)[2])
    seen = {}
    net = agent.eval_policy.network.module
    orig = net.forward
    net.forward = lambda obs, d, h: (seen.update(d=d.clone(), h=h.clone()), orig(obs, d, h))[1]
    w = agent.eval_policy.weights
    td = TensorDict({"observation": torch.zeros(3, 125), "preference": w[[2, 0, 1]] + 1e-3}, [3])
    agent.eval_policy(td)
    # the 3 best (A, B, C) in the authors' order; weight i gets command i
    assert seen["h"][:, 0].tolist() == [7.0, 5.0, 6.0]
    assert seen["d"].tolist() == [[5.0, 5.0], [10.0, 0.0], [0.0, 10.0]]


def test_a_short_pcn_run_learns_and_resumes(tmp_path):
    cfg = resolve_config("pcn", "MOLavaGridDR-v0", frames=1024, num_envs=4, frames_per_batch=256, pcn_er_episodes=2,
                         pcn_step_episodes=2, pcn_model_updates=5, eval_interval=1024, eval_weights=3,
                         checkpoint_interval=512, eval_contexts=("MOLavaGridRoom-v0",), progress=False,
                         eval_random_baseline=False, run_dir=str(tmp_path / "run"))
    summary = train(cfg)
    assert summary["frames"] == 1024 and 0.0 <= summary["nhgr_mean"] <= 1.0
    cfg.frames = 1536
    summary = train(cfg, resume=tmp_path / "run")
    assert summary["frames"] == 1536


def test_pcn_network_takes_images_through_the_nature_cnn():
    from morl_trl.objectives.pcn import PCNNetwork

    net = PCNNetwork((4, 84, 84), 7, 3, [0.1] * 4, hidden=16)
    logp = net(torch.zeros(2, 4, 84, 84, dtype=torch.uint8), torch.zeros(2, 3), torch.ones(2, 1))
    assert logp.shape == (2, 7) and torch.allclose(logp.exp().sum(-1), torch.ones(2))
    with pytest.raises(ValueError, match="scaling_factor needs num_objectives \\+ 1 = 4 values"):
        PCNNetwork(8, 4, 3, [0.1] * 3)


@pytest.mark.parametrize("fused", [True, False])
def test_optimizer_follows_fused_optimizer(fused):
    _, _, agent = _agent(fused_optimizer=fused)
    assert [g["fused"] for g in agent.optimizers["policy"].param_groups] == [fused]


def test_every_episode_starts_on_the_same_command_until_it_is_changed():
    # SPEC §6 PCN (pcn.py:505-544): one command, then num_step_episodes (10) episodes with it
    from torchrl.envs import TransformedEnv

    from morl_trl.envs.toy import ToyContextEnv
    from morl_trl.transforms.command import DesiredReturnConditioning

    t = DesiredReturnConditioning(2, max_return=[5.0, 5.0])
    t.set_command(torch.tensor([3.0, 1.0]), 4.0)
    env = TransformedEnv(ToyContextEnv(num_envs=2), t)
    policy = lambda td: td.set("action", torch.tensor([1, 1]))  # noqa: E731
    for _ in range(3):  # each episode moves the command (rewards [1, -1] a step), the next starts on it again
        steps = env.rollout(3, policy)
        assert steps["desired_return"][:, -1].tolist() == [[1.0, 3.0]] * 2
        td = env.reset()
        assert td["desired_return"].tolist() == [[3.0, 1.0]] * 2 and td["desired_horizon"].tolist() == [[4.0]] * 2
    t.set_command(torch.tensor([0.0, 2.0]), 7.0)
    td = env.reset()
    assert td["desired_return"].tolist() == [[0.0, 2.0]] * 2 and td["desired_horizon"].tolist() == [[7.0]] * 2


# batches of 64 frames from 4 sub-envs; the warm-up is the first 2 finished episodes, then a round of 3 updates
# (and a new command) after every 2 more; checkpoints every 128 frames, evaluations at 0 and at the end
TINY = dict(num_envs=4, frames_per_batch=64, pcn_er_episodes=2, pcn_step_episodes=2, pcn_model_updates=3,
            batch_size=16, hidden=(16, 16), eval_weights=2, checkpoint_interval=128, progress=False,
            eval_random_baseline=False)


def _tiny_run(tmp_path, monkeypatch, env_id, **kw) -> dict:
    """The CLI's training of PCN on ``env_id`` (TINY + ``kw``); returns its last checkpoint."""
    cfg = {k: v for k, v in {**TINY, **kw}.items() if k in valid_keys("pcn")}
    # (report.md's figures take seconds to draw and are not read)
    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    assert REGISTRY["pcn"].train is pcn.train_pcn
    train(resolve_config("pcn", env_id, run_dir=str(tmp_path / "run"), **cfg))
    return last_checkpoints(tmp_path / "run")[0]


def test_a_tiny_pcn_run_warms_up_then_runs_rounds(tmp_path, monkeypatch):
    state = _tiny_run(tmp_path, monkeypatch, "MOLavaGridDR-v0", num_envs=2, frames_per_batch=128, frames=1024,
                      eval_interval=1024, checkpoint_interval=512, eval_contexts=("MOLavaGridRoom-v0",))
    agent = state["agent"]
    # the 2 sub-envs' random episodes are truncated at 256 steps (512 frames): the warm-up's 2 episodes, a round
    # (3 updates, a command); the next 2 (acting on the command) end at 1024 frames: the second round
    assert (state["frames"], state["updates"]) == (1024, 6)
    assert (agent["episodes"], agent["rounds"], agent["next_round"]) == (4, 2, 6)
    assert agent["random_actions"] is False and agent["pending"] == {}
    assert agent["command"][1].item() == 254.0  # the chosen episode's length - 2
    assert sorted(agent["replay"]["length"].tolist()) == [256] * 4


def test_a_tiny_continuous_pcn_run_keeps_the_unfinished_episode(tmp_path, monkeypatch):
    pytest.importorskip("mujoco")
    state = _tiny_run(tmp_path, monkeypatch, "MOHopperDR-v5", num_envs=2, frames=512, eval_interval=512,
                      eval_weights=3, eval_contexts=("MOHopperDefault-v5",))
    agent = state["agent"]
    # Hopper's episodes are short (it falls): 40 episodes in 512 frames, a round every 2 after the warm-up's 2
    assert (state["frames"], state["updates"]) == (512, 24)
    assert (agent["episodes"], agent["rounds"], agent["next_round"]) == (40, 8, 42)
    assert agent["random_actions"] is False
    # sub-env 1's unfinished episode: 9 steps so far
    assert {i: piece["reward"].shape for i, piece in agent["pending"].items()} == {1: (9, 3)}


@pytest.mark.slow  # (three short runs)
def test_a_pcn_run_interrupted_and_resumed_ends_as_the_uninterrupted_run(tmp_path, monkeypatch):
    """Ctrl-C after the batch at 512 frames (the warm-up's episodes and the first round: a checkpoint,
    RunInterrupted), then ``--resume``: MO-LavaGrid snapshots its simulator, so the run continues exactly (the
    replay, the unfinished episodes, the command and the generator come back from the checkpoint)."""
    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    cfg = {k: v for k, v in TINY.items() if k in valid_keys("pcn")} | dict(
        num_envs=2, frames_per_batch=128, frames=1024, eval_interval=1024, checkpoint_interval=512,
        eval_contexts=("MOLavaGridRoom-v0",))
    whole, resumed = tmp_path / "whole", tmp_path / "resumed"
    train(resolve_config("pcn", "MOLavaGridDR-v0", run_dir=str(whole), **cfg))
    interrupt_then_resume(monkeypatch, resolve_config("pcn", "MOLavaGridDR-v0", run_dir=str(resumed), **cfg), at=512)
    log = (resumed / "log.txt").read_text()
    assert "resumed from frames_000000000512 at 512 frames" in log and "fresh episodes" not in log
    a, b = last_checkpoints(whole, resumed)
    assert (a["frames"], a["updates"], a["agent"]["rounds"]) == (1024, 6, 2)
    assert_checkpoints_equal(a, b)
    assert_logs_equal(whole, resumed)
