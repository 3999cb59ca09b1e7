"""A user env's reward of another width than its spec declares is an error naming the env and
both shapes, on the first steps (issue 44, finding 6): never a broadcasting traceback, never a
silent broadcast of one value to every objective."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from torchrl.data import Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from morl_trl.envs import make_env, register_env
from morl_trl.envs.foreign import REWARD_CHECK_STEPS, RewardShapeError


class TwoObjectives(EnvBase):
    """Declares a reward of shape (2,); returns ``reward`` (a tensor) from ``_step``."""

    def __init__(self, reward=(1.0, 2.0)):
        super().__init__()
        self.value = torch.tensor(reward)
        self.observation_spec = Composite(observation=Unbounded(shape=(3,)))
        self.action_spec = Categorical(2, shape=())
        self.reward_spec = Unbounded(shape=(2,))

    def _reset(self, td):
        return TensorDict(observation=torch.zeros(3), done=torch.zeros(1, dtype=torch.bool),
                          terminated=torch.zeros(1, dtype=torch.bool))

    def _step(self, td):
        return TensorDict(observation=torch.zeros(3), reward=self.value.clone(), done=torch.zeros(1, dtype=torch.bool),
                          terminated=torch.zeros(1, dtype=torch.bool))

    def _set_seed(self, seed):
        return seed


@pytest.mark.parametrize("reward, got", [((1.0, 2.0, 3.0), (3,)), ((1.0,), (1,)), (1.0, ())],
                         ids=["three values", "one value", "a scalar"])
def test_a_reward_of_another_width_is_an_error_naming_the_env_and_both_shapes(reward, got):
    env_id = register_env(lambda: TwoObjectives(reward), name="test-wrong-width", ref_point=(0, 0))
    env = make_env(env_id, num_envs=2, seed=0)
    with pytest.raises(RewardShapeError) as err:
        env.rollout(3)
    assert str(err.value) == (
        f"the env 'test-wrong-width' returned a reward of shape {got} at step 1, but its reward spec declares shape "
        f"(2,) (one value per objective): return a reward of shape (2,) (a scalar or a vector of another width is "
        f"never broadcast to the objectives)")


def test_a_right_reward_is_stepped_as_it_is_and_checked_only_on_the_first_steps():
    env_id = register_env(TwoObjectives(), name="test-right-width", ref_point=(0, 0))  # (an instance: copied)
    env = make_env(env_id, num_envs=2, seed=0)
    roll = env.rollout(REWARD_CHECK_STEPS + 2, break_when_any_done=False)
    assert roll["next", "reward"][:, -1].tolist() == [[1.0, 2.0], [1.0, 2.0]]
    subs = env._batch.env._envs  # (TorchRL's SerialEnv's sub-envs)
    assert len(subs) == 2 and all("_step" not in e.__dict__ for e in subs)  # (the check removed itself)
