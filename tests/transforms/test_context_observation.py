import pytest
import torch
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import SerialEnv, TransformedEnv
from torchrl.envs.utils import check_env_specs

from morl_trl.envs.context import ContextSpace
from morl_trl.transforms import ContextObservation, DomainRandomization
from tests.mocks import TOY_CONTEXT, ToyContextEnv

# TOY_CONTEXT: speed in [0.5, 2] (default 1), bias in [-1, 1] (default 0)
CTX = torch.tensor([[1.0, 0.0], [2.0, -1.0], [0.5, 0.5]])


@pytest.mark.parametrize(
    "normalize, expected",
    [
        (None, [[1.0, 0.0], [2.0, -1.0], [0.5, 0.5]]),
        ("unit", [[1 / 3, 0.5], [1.0, 0.0], [0.0, 0.75]]),
        ("symmetric", [[-1 / 3, 0.0], [1.0, -1.0], [-1.0, 0.5]]),
    ],
)
def test_appends_normalized_context_at_reset_and_step(normalize, expected):
    env = TransformedEnv(ToyContextEnv(num_envs=3, context=CTX), ContextObservation(normalize=normalize))
    td = env.reset()
    obs = td["observation"]
    assert obs.shape == (3, 4) and env.observation_spec["observation"].shape == (3, 4)
    torch.testing.assert_close(obs[:, :2], torch.zeros(3, 2))
    torch.testing.assert_close(obs[:, 2:], torch.tensor(expected))
    td = env.step(td.set("action", torch.tensor([1, 1, 0])))
    torch.testing.assert_close(td["next", "observation"][:, :2], torch.tensor([[1, 0.1], [1, 0.1], [-1, 0.1]]))
    torch.testing.assert_close(td["next", "observation"][:, 2:], torch.tensor(expected))
    check_env_specs(env)


def test_separate_key_and_context_alone():
    env = TransformedEnv(ToyContextEnv(num_envs=3, context=CTX),
                         ContextObservation(normalize="unit", out_key="obs_ctx"))
    td = env.reset()
    assert td["observation"].shape == (3, 2) and td["obs_ctx"].shape == (3, 4)
    env = TransformedEnv(ToyContextEnv(num_envs=3, context=CTX),
                         ContextObservation(normalize="unit", in_key=None, out_key="context_features"))
    td = env.reset()
    torch.testing.assert_close(td["context_features"], torch.tensor([[1 / 3, 0.5], [1.0, 0.0], [0.0, 0.75]]))
    check_env_specs(env)
    with pytest.raises(ValueError, match="needs an out_key"):
        ContextObservation(in_key=None)


def test_degenerate_range_maps_to_the_middle_and_out_of_range_is_not_clipped():
    space = ContextSpace(("speed", "bias"), (1.0, 0.0), (1.0, -1.0), (1.0, 1.0))  # speed not randomized
    t = ContextObservation(space, normalize="symmetric", in_key=None, out_key="c")
    out = t(TensorDict(context=torch.tensor([[1.0, 3.0]]), batch_size=[1]))["c"]
    torch.testing.assert_close(out, torch.tensor([[0.0, 3.0]]))


def test_follows_domain_randomization_in_compose():
    env = TransformedEnv(ToyContextEnv(num_envs=4), DomainRandomization(TOY_CONTEXT, seed=0))
    env.append_transform(ContextObservation())
    td = env.rollout(8, lambda td: td.set("action", torch.ones(4, dtype=torch.long)), break_when_any_done=False)
    torch.testing.assert_close(td["observation"][..., 2:], td["context"])
    torch.testing.assert_close(td["next", "observation"][..., 2:], td["next", "context"])


def test_offline_forward_as_replay_buffer_transform():
    env = ToyContextEnv(num_envs=2, context=CTX[:2])
    data = env.rollout(3, lambda td: td.set("action", torch.ones(2, dtype=torch.long))).reshape(-1)
    rb = ReplayBuffer(storage=LazyTensorStorage(10), transform=ContextObservation(TOY_CONTEXT, normalize="unit"),
                      batch_size=6)
    rb.extend(data)
    sample = rb.sample()
    assert sample["observation"].shape == (6, 4) and sample["next", "observation"].shape == (6, 4)
    torch.testing.assert_close(sample["observation"][:, 2:], (sample["context"] - torch.tensor([0.5, -1.0]))
                               / torch.tensor([1.5, 2.0]))
    assert rb.storage[0]["observation"].shape == (2,)  # stored raw, transformed on the way out


def test_needs_a_space_to_normalize_outside_a_contextual_env():
    env = TransformedEnv(SerialEnv(2, lambda: ToyContextEnv(num_envs=2)), ContextObservation(normalize="unit"))
    with pytest.raises(ValueError, match="pass context_space="):
        env.reset()
    env = TransformedEnv(SerialEnv(2, lambda: ToyContextEnv(num_envs=2)),
                         ContextObservation(TOY_CONTEXT, normalize="unit"))
    assert env.reset()["observation"].shape == (2, 2, 4)
    with pytest.raises(ValueError, match="normalize must be one of"):
        ContextObservation(normalize="minmax")
    wrong = ContextSpace(("a",), (0.0,), (0.0,), (1.0,))
    with pytest.raises(ValueError, match="the context space has 1"):
        TransformedEnv(ToyContextEnv(num_envs=2), ContextObservation(wrong)).observation_spec
