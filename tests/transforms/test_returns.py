import pytest
import torch
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs, step_mdp

from morl_trl.transforms import DiscountedVectorReturn
from tests.mocks import ToyContextEnv
from tests.transforms.helpers import ScriptedPolicy, episode_starts, returns_reference


def test_hand_values_over_a_terminating_episode():
    # always right from 0: rewards [1, -1] at each step, terminates after 3 steps (position 3)
    env = TransformedEnv(ToyContextEnv(num_envs=1), DiscountedVectorReturn(gamma=0.5))
    td = env.rollout(3, lambda td: td.set("action", torch.tensor([1])))
    assert td["next", "terminated"][0, :, 0].tolist() == [False, False, True]
    assert td["next", "episode_return"][0].tolist() == [[1, -1], [2, -2], [3, -3]]
    assert td["next", "episode_discounted_return"][0].tolist() == [[1, -1], [1.5, -1.5], [1.75, -1.75]]
    assert td["next", "episode_discount"][0].tolist() == [[0.5], [0.25], [0.125]]
    assert td["episode_return"][0, 0].tolist() == [0, 0] and td["episode_discount"][0, 0].tolist() == [1.0]


def test_rollout_with_auto_resets_matches_reference():
    n, steps, gamma = 4, 24, 0.9
    env = TransformedEnv(ToyContextEnv(num_envs=n, context=torch.tensor([[1.5, 0.25]])), DiscountedVectorReturn(gamma))
    td = env.rollout(steps, ScriptedPolicy((n,), steps, seed=5), break_when_any_done=False)
    starts = episode_starts(td)
    assert starts[:, 1:].sum() >= 4
    ret, disc = returns_reference(td["next", "reward"], starts, gamma)
    torch.testing.assert_close(td["next", "episode_return"], ret)
    torch.testing.assert_close(td["next", "episode_discounted_return"], disc)
    check_env_specs(env)


def test_partial_reset_zeroes_only_the_reset_subenvs():
    env = TransformedEnv(ToyContextEnv(num_envs=2), DiscountedVectorReturn(0.5))
    td = step_mdp(env.step(env.reset().set("action", torch.tensor([1, 1]))))
    td = env.reset(td.set("_reset", torch.tensor([[True], [False]])))
    assert td["episode_return"].tolist() == [[0, 0], [1, -1]]
    assert td["episode_discount"].tolist() == [[1.0], [0.5]]
    td = env.step(td.set("action", torch.tensor([1, 1])))
    assert td["next", "episode_discounted_return"].tolist() == [[1, -1], [1.5, -1.5]]


@pytest.mark.parametrize("gamma", [-0.1, 1.5, float("nan"), "0.9x"])
def test_bad_gamma(gamma):
    with pytest.raises(ValueError, match="gamma must be a number in"):
        DiscountedVectorReturn(gamma)


def test_offline_use_is_refused_with_a_message():
    with pytest.raises(NotImplementedError, match="inside a TransformedEnv"):
        DiscountedVectorReturn()(ToyContextEnv().reset())
