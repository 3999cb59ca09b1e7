"""TorchRL's transform-test pattern for every transform.

Each transform runs on a single batched env, inside and outside ``SerialEnv`` (and, for the
composition of all of them, inside and outside ``ParallelEnv``), in a ``Compose`` with
TorchRL's own stateful transforms, and through a replay buffer. Every layout passes
``check_env_specs`` and a rollout with auto-resets at different times in different sub-envs,
whose data is checked against hand-built references.
"""

import functools

import pytest
import torch
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import Compose, InitTracker, ParallelEnv, RewardSum, SerialEnv, StepCounter, TransformedEnv
from torchrl.envs.utils import check_env_specs

from morl_trl.transforms import (
    ContextObservation,
    DiscountedVectorReturn,
    DomainRandomization,
    LinearScalarization,
    PreferenceConditioning,
    StateActionHistory,
)
from tests.mocks import TOY_CONTEXT, ToyContextEnv
from tests.transforms.helpers import ScriptedPolicy, episode_starts, history_reference, returns_reference

STEPS = 16


def flat(td):
    """``[*B, T]`` rollout data as ``[R, T]``."""
    return td.reshape(-1, td.shape[-1])


def constant_within_episodes(value, starts):
    same = (value[:, 1:] == value[:, :-1]).flatten(2).all(-1)
    return torch.equal(same, ~starts[:, 1:])


def check_domain_randomization(td):
    starts = episode_starts(td)
    assert TOY_CONTEXT.contains(td["context"])
    assert constant_within_episodes(td["context"], starts)


def check_history(td):
    root, nxt = history_reference(td["observation"], td["next", "observation"],
                                  td["action"].float().unsqueeze(-1), episode_starts(td), 2)
    torch.testing.assert_close(td["history"], root, rtol=0, atol=0)
    torch.testing.assert_close(td["next", "history"], nxt, rtol=0, atol=0)


def check_context_observation(td):
    for sub in (td, td["next"]):
        ctx = (sub["context"] - torch.tensor([1.25, 0.0])) / torch.tensor([0.75, 1.0])
        torch.testing.assert_close(sub["obs_ctx"], torch.cat([sub["observation"], ctx], -1))


def check_preference(td):
    w = td["preference"]
    assert (w >= 0).all() and torch.allclose(w.sum(-1), torch.ones(w.shape[:-1]))
    assert torch.equal(td["next", "preference"], w)
    assert constant_within_episodes(w, episode_starts(td))


def check_scalarization(td):
    check_preference(td)
    expected = (td["preference"] * td["next", "reward"]).sum(-1, keepdim=True)
    torch.testing.assert_close(td["next", "scalar_reward"], expected)


def check_returns(td):
    ret, disc = returns_reference(td["next", "reward"], episode_starts(td), 0.9)
    torch.testing.assert_close(td["next", "episode_return"], ret)
    torch.testing.assert_close(td["next", "episode_discounted_return"], disc)


CASES = {
    "domain_randomization": (lambda: DomainRandomization(TOY_CONTEXT), check_domain_randomization),
    "history": (lambda: StateActionHistory(2, out_key="history"), check_history),
    "context_observation": (
        lambda: ContextObservation(TOY_CONTEXT, normalize="symmetric", out_key="obs_ctx"), check_context_observation
    ),
    "preference": (lambda: PreferenceConditioning(), check_preference),
    "scalarization": (lambda: Compose(PreferenceConditioning(), LinearScalarization()), check_scalarization),
    "returns": (lambda: DiscountedVectorReturn(0.9), check_returns),
}


def all_transforms():
    return Compose(*(make() for make, _ in CASES.values() if make is not CASES["preference"][0]))


def check_all(td):
    for _, check in CASES.values():
        check(td)


def worker(make_transform, num_envs=2):
    return TransformedEnv(ToyContextEnv(num_envs=num_envs, seed=0), make_transform())


def build(layout, make_transform):
    if layout == "single":
        return worker(make_transform, num_envs=4)
    if layout == "serial_inside":
        return SerialEnv(2, functools.partial(worker, make_transform))
    if layout == "serial_outside":
        return TransformedEnv(SerialEnv(2, functools.partial(ToyContextEnv, num_envs=2, seed=0)), make_transform())
    if layout == "compose_with_torchrl":
        return TransformedEnv(
            ToyContextEnv(num_envs=4, seed=0),
            Compose(InitTracker(), StepCounter(), make_transform(), RewardSum(in_keys=["reward"])),
        )
    raise ValueError(layout)


def run(env, seed=0):
    env.set_seed(seed)
    check_env_specs(env)
    td = env.rollout(STEPS, ScriptedPolicy(env.batch_size, STEPS, seed=seed), break_when_any_done=False)
    td = flat(td)
    starts = episode_starts(td)
    assert starts[:, 1:].any(-1).all() and not starts[:, 1:].all(0).any()  # partial auto-resets in every row
    return td


@pytest.mark.parametrize("layout", ["single", "serial_inside", "serial_outside", "compose_with_torchrl"])
@pytest.mark.parametrize("name", list(CASES))
def test_transform_in_every_layout(name, layout):
    make_transform, check = CASES[name]
    td = run(build(layout, make_transform))
    check(td)
    if layout == "compose_with_torchrl":  # TorchRL's own stateful transforms still work alongside
        torch.testing.assert_close(td["next", "episode_reward"],
                                   returns_reference(td["next", "reward"], episode_starts(td), 1.0)[0])
        assert torch.equal(td["is_init"].squeeze(-1), episode_starts(td))


@pytest.mark.parametrize("name", list(CASES))
def test_replay_buffer_round_trip(name):
    make_transform, check = CASES[name]
    td = run(build("single", make_transform))
    rb = ReplayBuffer(storage=LazyTensorStorage(4 * STEPS), batch_size=16)
    rb.extend(td.reshape(-1))
    stored = rb[:].reshape(td.shape)
    check(stored)
    assert rb.sample().batch_size == (16,)


def test_all_transforms_composed_serial_inside_and_outside():
    for layout in ("serial_inside", "serial_outside"):
        check_all(run(build(layout, all_transforms), seed=1))


@pytest.mark.parametrize("where", ["inside", "outside"])
def test_all_transforms_composed_in_parallel_env(where):
    if where == "inside":
        env = ParallelEnv(2, functools.partial(worker, all_transforms), mp_start_method="fork")
    else:
        env = TransformedEnv(
            ParallelEnv(2, functools.partial(ToyContextEnv, num_envs=2, seed=0), mp_start_method="fork"),
            all_transforms(),
        )
    try:
        td = run(env, seed=3)
        check_all(td)
        if where == "inside":  # ParallelEnv.set_seed gave each worker its own seed, so its own contexts
            assert not torch.equal(td["context"][:2, 0], td["context"][2:, 0])
    finally:
        env.close()


@pytest.mark.parametrize("name", list(CASES))
def test_pickle_and_clone_after_use(name):
    import pickle

    make_transform, check = CASES[name]
    env = build("single", make_transform)
    env.rollout(5, ScriptedPolicy(env.batch_size, 5), break_when_any_done=False)
    transform = env.transform.clone()
    restored = pickle.loads(pickle.dumps(transform))
    assert type(restored) is type(transform) and restored.parent is None
    td = run(TransformedEnv(ToyContextEnv(num_envs=4, seed=0), restored))
    check(td)


def test_clone_copies_the_random_stream():
    t = DomainRandomization(TOY_CONTEXT, seed=0)
    c = t.clone()
    torch.testing.assert_close(c.sample(3), t.sample(3))


@pytest.mark.slow
def test_all_transforms_in_parallel_env_with_spawned_workers():
    """The default start method pickles everything a worker needs (slow: each worker imports torch)."""
    env = ParallelEnv(2, functools.partial(worker, all_transforms))
    try:
        check_all(run(env, seed=5))
    finally:
        env.close()


def test_all_transforms_with_a_torchrl_collector():
    from torchrl.collectors import Collector

    env = worker(all_transforms, num_envs=4)
    env.set_seed(0)
    collector = Collector(env, policy=None, frames_per_batch=64, total_frames=192)
    try:
        batches = [batch.clone() for batch in collector]
    finally:
        collector.shutdown()
    assert [b.shape for b in batches] == [(4, 16)] * 3
    data = torch.cat(batches, 1)  # episodes run on from one batch into the next
    assert episode_starts(data)[:, 1:].sum() >= 8
    check_all(data)
