import pytest
import torch
from tensordict import TensorDict
from torchrl.data import Bounded, Composite, LazyTensorStorage, ReplayBuffer, Unbounded
from torchrl.envs import Compose, TransformedEnv
from torchrl.envs.utils import check_env_specs

from morl_trl.transforms import LinearScalarization, PreferenceConditioning
from tests.mocks import ToyContextEnv

# ToyContextEnv reward: [speed * move + bias, -1]; contexts below give
CTX = torch.tensor([[1.0, 0.0], [2.0, -1.0], [0.5, 0.5]])
RIGHT = torch.tensor([1, 1, 0])  # rewards [1, -1], [1, -1], [0, -1]


def test_fixed_weights_values_spec_and_vector_reward_kept():
    env = TransformedEnv(ToyContextEnv(num_envs=3, context=CTX), LinearScalarization([0.25, 0.75]))
    assert set(env.reward_keys) == {"reward", "scalar_reward"}
    assert env.full_reward_spec["scalar_reward"].shape == (3, 1)
    td = env.step(env.reset().set("action", RIGHT))
    assert td["next", "reward"].tolist() == [[1, -1], [1, -1], [0, -1]]
    assert td["next", "scalar_reward"].tolist() == [[-0.5], [-0.5], [-0.75]]
    check_env_specs(env)


def test_per_episode_preferences():
    env = TransformedEnv(ToyContextEnv(num_envs=3, context=CTX),
                         Compose(PreferenceConditioning(mode="given"), LinearScalarization()))
    w = torch.tensor([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]])
    td = env.step(env.reset(TensorDict(preference=w, batch_size=[3])).set("action", RIGHT))
    assert td["next", "scalar_reward"].tolist() == [[1.0], [0.0], [-1.0]]
    n, steps = 3, 12
    env = TransformedEnv(ToyContextEnv(num_envs=n), Compose(PreferenceConditioning(seed=0), LinearScalarization()))
    td = env.rollout(steps, lambda td: td.set("action", torch.ones(n, dtype=torch.long)), break_when_any_done=False)
    expected = (td["preference"] * td["next", "reward"]).sum(-1, keepdim=True)
    torch.testing.assert_close(td["next", "scalar_reward"], expected)
    check_env_specs(env)


def test_replace_the_vector_reward():
    env = TransformedEnv(ToyContextEnv(num_envs=3, context=CTX), LinearScalarization([1.0, 1.0], out_key="reward"))
    assert env.reward_keys == ["reward"] and env.reward_spec.shape == (3, 1)
    td = env.step(env.reset().set("action", RIGHT))
    assert td["next", "reward"].tolist() == [[0.0], [0.0], [-1.0]]
    check_env_specs(env)


def test_bounded_reward_spec():
    spec = Composite(reward=Bounded(low=torch.tensor([0.0, -2.0]), high=torch.tensor([1.0, 0.0]), shape=(2,)))
    out = LinearScalarization([1.0, -1.0]).transform_reward_spec(spec.clone())["scalar_reward"]
    assert out.space.low.tolist() == [0.0] and out.space.high.tolist() == [3.0]
    out = LinearScalarization().transform_reward_spec(spec.clone())["scalar_reward"]  # w on the simplex
    assert out.space.low.tolist() == [-2.0] and out.space.high.tolist() == [1.0]
    out = LinearScalarization().transform_reward_spec(Composite(reward=Unbounded(shape=(4, 3)), shape=(4,)))
    assert isinstance(out["scalar_reward"], Unbounded) and out["scalar_reward"].shape == (4, 1)


def test_replay_buffer_relabelling():
    env = TransformedEnv(ToyContextEnv(num_envs=2), PreferenceConditioning(seed=0))
    data = env.rollout(4, lambda td: td.set("action", torch.ones(2, dtype=torch.long))).reshape(-1)
    rb = ReplayBuffer(storage=LazyTensorStorage(16), transform=LinearScalarization(), batch_size=8)
    rb.extend(data)
    sample = rb.sample()
    torch.testing.assert_close(sample["next", "scalar_reward"],
                               (sample["preference"] * sample["next", "reward"]).sum(-1, keepdim=True))
    relabelled = LinearScalarization()(sample.set("preference", torch.tensor([[0.0, 1.0]] * 8)))
    assert relabelled["next", "scalar_reward"].tolist() == [[-1.0]] * 8


def test_bad_input():
    with pytest.raises(ValueError, match=r"weights must be a finite \[k\] vector, got \[nan, 1.0\]"):
        LinearScalarization([float("nan"), 1.0])
    with pytest.raises(ValueError, match=r"2 objectives in 'reward' but 3 weights: \[0.2, 0.3, 0.5\]"):
        TransformedEnv(ToyContextEnv(num_envs=1), LinearScalarization([0.2, 0.3, 0.5])).reward_spec
    env = TransformedEnv(ToyContextEnv(num_envs=1), LinearScalarization())
    with pytest.raises(KeyError, match="put a PreferenceConditioning transform before it"):
        env.step(env.reset().set("action", torch.tensor([1])))
