"""PGMORL's reseed at every iteration: the authors' member train() starts with envs.reset(seed=member.seed)
(mo_ppo.py:628), the seed being the run's for the first members and 42 for the copies the task
selection makes (their MOPPO is built without a seed, mo_ppo.py:355-377)."""

import numpy as np
import pytest
import torch

from morl_trl.recipes import resolve_config

CPU = torch.device("cpu")


def _run(reseed, batches=3):
    from morl_trl.recipes.off_policy import make_collector
    from morl_trl.algorithms.pgmorl import recipe as pgmorl
    from morl_trl.algorithms.pgmorl.recipe import make_pgmorl_agent, make_pgmorl_training_env

    cfg = resolve_config("pgmorl", "MOHopperDR-v5", pgmorl_pop=2, num_envs=4, pgmorl_envs_per_member=2,
                         frames_per_batch=64, frames=64 * batches, hidden=(8,), progress=False, pgmorl_epochs=1,
                         pgmorl_minibatches=2, seed=3, pgmorl_reseed_each_iteration=reseed)
    torch.manual_seed(0)
    env = make_pgmorl_training_env(cfg, CPU)
    agent = make_pgmorl_agent(cfg, env, gamma=0.99, device=CPU)
    sim = _simulators(env)
    first = []  # the simulators' (qpos, qvel) after each reset of all 4 sub-envs (each iteration's start)
    reset = sim._reset_subenvs

    def recording(idx, context):
        reset(idx, context)
        if len(idx) == sim.num_envs:
            first.append(torch.as_tensor(np.concatenate([sim._fields["qpos"], sim._fields["qvel"]], -1)).clone())

    sim._reset_subenvs = recording
    collector = make_collector(cfg, env, agent.explore_policy, CPU, frames_to_go=64 * batches)
    agent.reseed_env()  # (train_pgmorl's calls: before the first iteration, then after each)
    frames = 0
    for batch in collector:
        frames += pgmorl.counted_frames(agent, batch)
        pgmorl.on_batch(agent, batch, None, frames)
        agent.reseed_env()
    collector.shutdown()

    return cfg, env, agent, first[1:]  # (the first: the collector's own reset at its creation)


def _simulators(env):
    while hasattr(env, "base_env"):
        env = env.base_env
    return env


def test_pgmorl_reseeds_each_members_sub_envs_at_every_iteration_as_the_authors():
    pytest.importorskip("mujoco")
    assert resolve_config("pgmorl", "MOHopperDR-v5").pgmorl_reseed_each_iteration is True
    cfg, env, agent, first = _run(True)
    # every iteration starts from the same initial states (seed + i for member p's sub-env p * E + i) ...
    assert len(first) == 3 and all(torch.equal(f, first[0]) for f in first[1:])
    # ... member 0's and member 1's copy i share them (both seeded 3 + i), copies 0 and 1 differ
    assert torch.equal(first[0][0], first[0][2]) and torch.equal(first[0][1], first[0][3])
    assert not torch.equal(first[0][0], first[0][1])
    assert agent.member_seeds == [3, 3]
    # without the reseed the streams go on: the next iterations start elsewhere
    _, _, _, go_on = _run(False)
    assert len(go_on) == 3 and not torch.equal(go_on[1], go_on[0]) and not torch.equal(go_on[2], go_on[1])


def test_a_member_the_task_selection_copied_is_reseeded_with_42(monkeypatch):
    pytest.importorskip("mujoco")
    import morl_trl.algorithms.pgmorl.recipe as pgmorl

    cfg, env, agent, _ = _run(True, batches=1)
    agent.performance[:] = [[1.0, 2.0, 3.0], [2.0, 1.0, 3.0]]
    agent.evaluate_members(add_to_prediction=False)
    agent.predictor.after = [np.array([i, 0.0, 0.0]) for i in range(4)]
    monkeypatch.setattr(pgmorl, "select_tasks", lambda *a, **k: [(0, [0.0, 0.5, 0.5], None), (1, [0.5, 0.5, 0.0], None)])
    agent.select_tasks()
    assert agent.member_seeds == [42, 42] and agent.generation == 1
    agent.reseed_env()
    sim = _simulators(env)
    want = [np.random.default_rng(42 + i).bit_generator.state for i in (0, 1, 0, 1)]
    assert [g.bit_generator.state for g in sim._rngs] == want
    state = agent.state_dict()
    assert state["member_seeds"] == [42, 42]
    state.pop("member_seeds")  # (an older state: the copies' seed once a task selection ran)
    agent.member_seeds = [0, 0]
    agent.load_state_dict(state)
    assert agent.member_seeds == [42, 42]
