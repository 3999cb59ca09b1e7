import pickle

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import SerialEnv, TransformedEnv
from torchrl.envs.utils import check_env_specs

from morl_trl.envs import registry
from morl_trl.envs.context import ContextSpace
from morl_trl.envs.sampler import ContextSampler
from morl_trl.transforms import DomainRandomization
from tests.mocks import TOY_CONTEXT, ToyContextEnv
from tests.transforms.helpers import ScriptedPolicy, episode_starts


def first_draws(seed, n):
    return TOY_CONTEXT.sample(n, generator=torch.Generator().manual_seed(seed))


def test_reset_draws_the_seeded_uniform_stream():
    env = TransformedEnv(ToyContextEnv(num_envs=3), DomainRandomization(TOY_CONTEXT, seed=4))
    torch.testing.assert_close(env.reset()["context"], first_draws(4, 3))
    torch.testing.assert_close(env.base_env.context, first_draws(4, 3))


def test_partial_reset_redraws_only_the_reset_subenvs_and_passes_nothing_else():
    env = TransformedEnv(ToyContextEnv(num_envs=3), DomainRandomization(TOY_CONTEXT, seed=0))
    td = env.reset()
    before = td["context"].clone()
    td = env.reset(td.set("_reset", torch.tensor([[True], [False], [True]])))
    after = td["context"]
    assert torch.equal(after[1], before[1])
    assert not torch.equal(after[0], before[0]) and not torch.equal(after[2], before[2])
    g = torch.Generator().manual_seed(0)
    TOY_CONTEXT.sample(3, generator=g)
    torch.testing.assert_close(after[[0, 2]], TOY_CONTEXT.sample(2, generator=g))  # the stream continues
    torch.testing.assert_close(env.base_env.context, after)


def test_contexts_constant_within_episodes_and_new_at_each_reset():
    n, steps = 4, 20
    env = TransformedEnv(ToyContextEnv(num_envs=n), DomainRandomization(TOY_CONTEXT, seed=1))
    td = env.rollout(steps, ScriptedPolicy((n,), steps, seed=2), break_when_any_done=False)
    starts = episode_starts(td)
    ctx = td["context"]
    same = (ctx[:, 1:] == ctx[:, :-1]).all(-1)
    assert torch.equal(same, ~starts[:, 1:])  # changes exactly at episode starts
    assert TOY_CONTEXT.contains(ctx)


class RingSpace(ContextSpace):
    """A custom space whose draw depends on the previous context (like LavaGrid's goal exclusion)."""

    def sample(self, n, generator=None, device=None, previous=None):
        self.calls.append(None if previous is None else previous.clone())
        lo, hi = self.bounds()
        nxt = previous + torch.tensor([0.25, 0.5])
        return torch.where(nxt > hi, lo, nxt)


def test_custom_space_gets_previous_contexts_of_the_reset_subenvs():
    space = RingSpace(TOY_CONTEXT.names, TOY_CONTEXT.default, TOY_CONTEXT.low, TOY_CONTEXT.high)
    object.__setattr__(space, "calls", [])
    env = TransformedEnv(ToyContextEnv(num_envs=3), DomainRandomization(space, seed=0))
    td = env.reset()
    assert torch.equal(space.calls[0], torch.tensor([[1.0, 0.0]] * 3))  # the env's current (default) contexts
    assert td["context"].tolist() == [[1.25, 0.5]] * 3
    td = env.reset(td.set("_reset", torch.tensor([[False], [True], [False]])))
    assert space.calls[1].tolist() == [[1.25, 0.5]]
    assert td["context"].tolist() == [[1.25, 0.5], [1.5, 1.0], [1.25, 0.5]]


def test_user_sampler_with_and_without_previous():
    seen = []

    def shifted(n, generator, previous):
        seen.append(previous)
        return previous.clamp(max=1.9) + torch.tensor([0.1, 0.0])

    env = TransformedEnv(ToyContextEnv(num_envs=2), DomainRandomization(TOY_CONTEXT, sampler=shifted))
    torch.testing.assert_close(env.reset()["context"], torch.tensor([[1.1, 0.0]] * 2))

    def const(n, generator):
        return torch.tensor([[0.75, -0.5]]).expand(n, 2)

    env = TransformedEnv(ToyContextEnv(num_envs=2), DomainRandomization(TOY_CONTEXT, sampler=const))
    assert env.reset()["context"].tolist() == [[0.75, -0.5]] * 2


@pytest.mark.parametrize(
    "bad, match",
    [
        (torch.tensor([[3.0, 0.0]]), r"'speed' is 3.0 \(row 0\), outside its range \[0.5, 2.0\]"),
        (torch.tensor([[1.0, float("nan")]]), "'bias' is nan"),
        (torch.tensor([[1.0, 0.0, 0.0]]), r"returned shape \(1, 3\); expected \(1, 2\)"),
    ],
)
def test_sampler_outside_the_space_raises_and_resets_nothing(bad, match):
    env = TransformedEnv(ToyContextEnv(num_envs=1), DomainRandomization(TOY_CONTEXT, sampler=lambda n, g: bad))
    base = env.base_env
    base._step_count[:] = 4
    with pytest.raises(ValueError, match=match):
        env.reset()
    assert base._step_count.tolist() == [4] and base.context.tolist() == [[1.0, 0.0]]


def test_fixed_parameters_and_bad_fixed():
    env = TransformedEnv(ToyContextEnv(num_envs=6), DomainRandomization(TOY_CONTEXT, seed=0, fixed={"speed": 3.0}))
    ctx = env.reset()["context"]  # a fixed value may lie outside the DR range
    assert (ctx[:, 0] == 3.0).all() and ctx[:, 1].unique().numel() == 6
    with pytest.raises(ValueError, match="unknown context parameter 'mass'"):
        DomainRandomization(TOY_CONTEXT, fixed={"mass": 1.0})
    with pytest.raises(ValueError, match="'speed' is -1.0"):
        DomainRandomization(TOY_CONTEXT, fixed={"speed": -1.0})


def test_env_without_contexts_is_rejected():
    from torchrl.testing.mocking_classes import ContinuousActionVecMockEnv

    env = TransformedEnv(ContinuousActionVecMockEnv(), DomainRandomization(TOY_CONTEXT))
    with pytest.raises(ValueError, match="does not read that key at reset"):
        env.reset()


def test_seed_follows_the_env_seed_and_set_seed():
    env = TransformedEnv(ToyContextEnv(num_envs=3, seed=11), DomainRandomization(TOY_CONTEXT))
    torch.testing.assert_close(env.reset()["context"], first_draws(11, 3))  # no seed: the env's
    env.set_seed(5)  # re-seeding the env re-seeds the transform
    torch.testing.assert_close(env.reset()["context"], first_draws(5, 3))
    env.transform.set_seed(8)
    torch.testing.assert_close(env.reset()["context"], first_draws(8, 3))
    # an explicit seed wins over the env's construction seed
    env = TransformedEnv(ToyContextEnv(num_envs=3, seed=11), DomainRandomization(TOY_CONTEXT, seed=2))
    torch.testing.assert_close(env.reset()["context"], first_draws(2, 3))


def test_serial_env_workers_get_distinct_streams_after_set_seed():
    env = SerialEnv(2, lambda: TransformedEnv(ToyContextEnv(num_envs=2, seed=0), DomainRandomization(TOY_CONTEXT)))
    env.set_seed(20)
    ctx = env.reset()["context"]
    seeds = [w.base_env._seed for w in env._envs]  # TorchRL derives worker i's seed from worker i-1's
    assert seeds[0] == 20 and seeds[1] != 20
    torch.testing.assert_close(ctx[0], first_draws(seeds[0], 2))
    torch.testing.assert_close(ctx[1], first_draws(seeds[1], 2))


def test_outside_a_batched_env():
    env = TransformedEnv(SerialEnv(2, lambda: ToyContextEnv(num_envs=3)), DomainRandomization(TOY_CONTEXT, seed=3))
    ctx = env.reset()["context"]
    torch.testing.assert_close(ctx.reshape(6, 2), first_draws(3, 6))
    check_env_specs(env)
    td = env.reset(env.reset().set("_reset", torch.tensor([[True, False, False], [False, False, True]]).unsqueeze(-1)))
    assert td["context"].shape == (2, 3, 2)


def test_pickle_round_trip_keeps_the_stream():
    t = DomainRandomization(TOY_CONTEXT, seed=9, fixed={"bias": 0.5})
    t.sample(3)
    clone = pickle.loads(pickle.dumps(t))
    torch.testing.assert_close(clone.sample(4), t.sample(4))
    assert clone.fixed == {"bias": 0.5}


def test_make_env_of_a_dr_id_is_the_fixed_env_with_a_context_sampler(monkeypatch):
    registry._ensure_loaded()
    monkeypatch.setattr(registry, "_IDS", dict(registry._IDS))
    monkeypatch.setattr(registry, "_DOMAINS", dict(registry._DOMAINS))
    registry.register_domain(registry.DomainSpec(
        name="Toy", train_id="ToyTestDR-v0", env_class="tests.mocks:ToyContextEnv", context_space=TOY_CONTEXT,
        contexts={"ToyTestFast-v0": {"speed": 2.0}}, evaluation_ids=("ToyTestFast-v0",),
        objective_names=("progress", "time"),
    ))
    env = registry.make_env("ToyTestDR-v0", num_envs=3, seed=6, bias=0.25)
    assert type(env) is ToyContextEnv and isinstance(env.context_sampler, ContextSampler)
    assert env.context_sampler.fixed == {"bias": 0.25}
    expected = first_draws(6, 3)
    expected[:, 1] = 0.25
    torch.testing.assert_close(env.reset()["context"], expected)
    fixed = registry.make_env("ToyTestFast-v0", num_envs=2)
    assert type(fixed) is ToyContextEnv and fixed.context_sampler is None
    assert fixed.reset()["context"].tolist() == [[2.0, 0.0]] * 2


def test_explicit_context_in_reset_td_is_overridden_by_the_draw():
    env = TransformedEnv(ToyContextEnv(num_envs=2), DomainRandomization(TOY_CONTEXT, seed=0))
    td = env.reset(TensorDict(context=torch.tensor([[1.0, 0.0]] * 2), batch_size=[2]))
    torch.testing.assert_close(td["context"], first_draws(0, 2))


class BrokenSpace(ContextSpace):
    def sample(self, n, generator=None, device=None):
        return torch.tensor([[1.0, 1.5]]).expand(n, 2)


def test_custom_space_drawing_outside_its_ranges_raises():
    space = BrokenSpace(TOY_CONTEXT.names, TOY_CONTEXT.default, TOY_CONTEXT.low, TOY_CONTEXT.high)
    env = TransformedEnv(ToyContextEnv(num_envs=2), DomainRandomization(space))
    with pytest.raises(ValueError, match=r"'bias' is 1.5 \(row 0\), outside its range \[-1.0, 1.0\]"):
        env.reset()
