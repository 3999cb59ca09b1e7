"""Foreign envs (MO-Gymnasium ids, a user's TorchRL env) as domains: specs, stepping, resets, errors."""

import pytest
import torch

pytest.importorskip("mo_gymnasium")

from morl_trl.envs import domain_of, make_env, register_env  # noqa: E402
from morl_trl.envs.foreign import MO_GYMNASIUM_REF_POINTS, foreign_domain  # noqa: E402

DOWN = 1  # MO-Gymnasium's Deep Sea Treasure: 0 up, 1 down, 2 left, 3 right


def test_dst_specs_and_first_treasure():
    env = make_env("deep-sea-treasure-v0", num_envs=3, seed=0)
    assert env.batch_size == torch.Size([3])
    assert env.action_spec.space.n == 4 and env.action_spec.dtype == torch.long
    assert env.observation_spec["observation"].shape == (3, 2)
    assert env.objective_names == ("treasure", "time_penalty")
    td = env.reset()
    assert td["observation"].tolist() == [[0.0, 0.0]] * 3
    td.set("action", torch.tensor([DOWN, 3, 3]))
    nxt = env.step(td)["next"]
    # down from the start reaches the first treasure (0.7) and ends the episode; right does not
    assert torch.equal(nxt["reward"], torch.tensor([[0.7, -1.0], [0.0, -1.0], [0.0, -1.0]]))
    assert nxt["terminated"].view(-1).tolist() == [True, False, False]
    assert "original_reward" not in nxt.keys()  # no scalar reward: no f_SORL for foreign envs
    assert nxt["context"].shape == (3, 0)


def test_dst_partial_reset_resets_only_the_finished_sub_env():
    env = make_env("deep-sea-treasure-v0", num_envs=2, seed=0)
    td = env.reset()
    td.set("action", torch.tensor([3, 3]))  # both move right
    td = env.step_mdp(env.step(td))
    assert td["observation"].tolist() == [[0.0, 1.0], [0.0, 1.0]]
    td.set("_reset", torch.tensor([[True], [False]]))
    td = env.reset(td)
    assert td["observation"].tolist() == [[0.0, 0.0], [0.0, 1.0]]


def test_auto_reset_in_a_rollout_restarts_finished_episodes():
    env = make_env("deep-sea-treasure-v0", num_envs=1, seed=0)
    roll = env.rollout(3, policy=lambda td: td.set("action", torch.tensor([DOWN])), break_when_any_done=False)
    # every step finds the first treasure from the start: the env restarted after each
    assert torch.equal(roll["next", "reward"][0], torch.tensor([[0.7, -1.0]] * 3))
    assert roll["observation"][0].tolist() == [[0.0, 0.0]] * 3


def test_continuous_env_has_a_bounded_action_and_its_own_time_limit():
    env = make_env("mo-mountaincarcontinuous-v0", num_envs=2, seed=1)
    assert env.action_spec.domain == "continuous"
    assert env.action_spec.space.low.tolist() == [[-1.0], [-1.0]]
    assert env.max_episode_steps == 999
    roll = env.rollout(4, policy=lambda td: td.set("action", torch.zeros(2, 1)))
    assert roll["next", "reward"].shape == (2, 4, 2)


def test_a_torchrl_callable_with_one_hot_actions_steps_like_the_gym_id():
    from torchrl.envs import MOGymEnv

    env_id = register_env(lambda: MOGymEnv("deep-sea-treasure-v0"), name="test-dst-callable", ref_point=(0, -25))
    env = make_env(env_id, num_envs=2, seed=0)
    assert env.action_spec.space.n == 4  # one-hot in the wrapped env, one index here
    td = env.reset()
    td.set("action", torch.tensor([DOWN, 3]))
    assert torch.equal(env.step(td)["next", "reward"], torch.tensor([[0.7, -1.0], [0.0, -1.0]]))
    spec = domain_of(env_id)
    assert spec.foreign and spec.hv_ref_point == (0.0, -25.0) and spec.objective_names == ("objective_0", "objective_1")


def test_an_env_instance_is_copied_for_further_sub_envs():
    from torchrl.envs import MOGymEnv

    env_id = register_env(MOGymEnv("deep-sea-treasure-v0", categorical_action_encoding=True), name="test-dst-instance",
                          ref_point=(0, -25))
    env = make_env(env_id, num_envs=2, seed=0)
    td = env.reset()
    td.set("action", torch.tensor([DOWN, DOWN]))
    assert torch.equal(env.step(td)["next", "reward"], torch.tensor([[0.7, -1.0], [0.7, -1.0]]))


def test_scalar_reward_and_bad_inputs_are_refused_with_what_is_valid():
    with pytest.raises(ValueError, match="vector reward"):
        make_env("CartPole-v1")
    with pytest.raises(ValueError, match="unknown env id 'deep-sea-treasur-v0'.*did you mean"):
        make_env("deep-sea-treasur-v0")
    with pytest.raises(ValueError, match="needs a name"):
        register_env(lambda: None)
    with pytest.raises(ValueError, match="must return a TorchRL EnvBase"):
        register_env(lambda: 3, name="test-not-an-env")
    with pytest.raises(ValueError, match=r"ref_point \[0.0\] must be 2 finite numbers"):
        foreign_domain("deep-sea-treasure-v0", ref_point=[0.0])


def test_foreign_domain_reads_the_reference_point_table_and_the_true_front():
    spec = foreign_domain("deep-sea-treasure-v0")
    assert spec.hv_ref_point == MO_GYMNASIUM_REF_POINTS["deep-sea-treasure-v0"][0] == (0.0, -25.0)
    assert spec.evaluation_ids == ("deep-sea-treasure-v0",) and spec.context_space.dim == 0
    front = spec.true_front(1.0)  # undiscounted: the ten treasures and their distances
    assert front.shape == (10, 2)
    assert front[0].tolist() == [0.7, -1.0] and front[-1].tolist() == [23.7, -19.0]
    assert foreign_domain("mo-mountaincarcontinuous-v0").true_front is None  # MO-Gymnasium knows none


def test_same_seed_same_start_and_sub_envs_seeded_apart():
    def start(seed):  # MountainCar starts at a random position in [-0.6, -0.4]
        return make_env("mo-mountaincarcontinuous-v0", num_envs=2, seed=seed).reset()["observation"]

    assert torch.equal(start(3), start(3))
    assert not torch.equal(start(3), start(4))
    first = start(3)
    assert first[0, 0] != first[1, 0]  # sub-env i is seeded with seed + i
    assert torch.equal(start(4)[0], first[1])


def test_the_report_names_a_users_reference_point_and_where_an_envs_comes_from():
    from torchrl.envs import MOGymEnv

    from morl_trl.reporting.report import foreign_nhgr_note

    spec = foreign_domain("deep-sea-treasure-v0")
    assert "reference point [0.0, -25.0] (MORL-Baselines examples/pql_dst.py and tests/test_algos.py " \
           "(mp_mo_q_learning))" in foreign_nhgr_note(spec)
    mine = foreign_domain(lambda: MOGymEnv("deep-sea-treasure-v0"), name="test-dst-no-point")
    assert mine.hv_ref_point is None  # (a callable's: none unless given)
    assert "reference point [-1.0, -30.0] (given with --ref-point / ref_point=)" in foreign_nhgr_note(mine, (-1, -30))
