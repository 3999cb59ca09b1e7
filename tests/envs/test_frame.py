"""The frame: context spaces, the registry and the batched contextual base env (on a toy domain)."""

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs

from morl_trl.envs import ContextSpace, context_space, domain_of, evaluation_suite, list_envs, make_env
from morl_trl.transforms import DomainRandomization
from tests.mocks import TOY_CONTEXT, ToyContextEnv


# ---------------------------------------------------------------- ContextSpace
def test_context_space_make_and_names():
    space = context_space("MOLunarLanderDR-v0")
    assert space.names[:2] == ("gravity", "wind_power")
    ctx = space.make(gravity=-12.0)
    assert ctx.tolist() == pytest.approx([-12.0, 15.0, 1.5, 13.0, 0.6, 0.5, 1.0])
    assert space.as_dict(ctx)["gravity"] == -12.0


def test_context_space_sampling_is_seeded_and_in_range():
    space = context_space("MOHumanoidDR-v5")
    a = space.sample(500, generator=torch.Generator().manual_seed(3))
    b = space.sample(500, generator=torch.Generator().manual_seed(3))
    assert torch.equal(a, b)
    lo, hi = space.bounds()
    assert (a >= lo).all() and (a <= hi).all()
    # every parameter is actually randomized over most of its range
    assert ((a.max(0).values - a.min(0).values) > 0.9 * (hi - lo)).all()


@pytest.mark.parametrize(
    "bad, match",
    [
        (torch.zeros(3), r"expected \[\.\.\., 2\]"),
        (torch.tensor([float("nan"), 0.0]), "'speed' is nan"),
        (torch.tensor([1.0, float("inf")]), "'bias' is inf"),
        (torch.tensor([-1.0, 0.0]), "'speed' is -1.0.*strictly positive"),
    ],
)
def test_context_space_rejects_bad_contexts(bad, match):
    with pytest.raises(ValueError, match=match):
        TOY_CONTEXT.validate(bad)


def test_context_space_range_check_and_unknown_name():
    with pytest.raises(ValueError, match="outside its range"):
        TOY_CONTEXT.validate(torch.tensor([3.0, 0.0]), check_range=True)
    with pytest.raises(ValueError, match="unknown context parameter 'sped'"):
        TOY_CONTEXT.make(sped=1.0)
    with pytest.raises(ValueError, match="low 2.0 > high 1.0"):
        ContextSpace(("a",), (1.0,), (2.0,), (1.0,))


# ---------------------------------------------------------------- registry
def test_registry_lists_the_papers_suites():
    ids = list_envs()
    for env_id in ("MOLunarLanderDR-v0", "MOLunarLanderHard-v0", "MOLunarLanderContinuousWindy-v0",
                   "MOHopperSlippery-v5", "MOHalfCheetahHard-v5", "MOHumanoidLowDamping-v5"):
        assert env_id in ids
    assert evaluation_suite("MOLunarLanderDR-v0") == [
        f"MOLunarLander{n}-v0" for n in
        ("Default", "HighGravity", "Windy", "Turbulent", "Hard", "LowMainEngine", "LowSideEngine", "StartRight")
    ]
    assert len(evaluation_suite("MOHopperDR-v5")) == 6
    assert len(evaluation_suite("MOHalfCheetahDR-v5")) == 5
    assert len(evaluation_suite("MOHumanoidDR-v5")) == 5
    # the suite can be asked for from any id of the domain
    assert evaluation_suite("MOHopperHeavy-v5") == evaluation_suite("MOHopperDR-v5")


def test_registry_contexts_are_the_papers():
    hard = domain_of("MOLunarLanderHard-v0").context_of("MOLunarLanderHard-v0")
    assert hard.tolist() == pytest.approx([-12.0, 17.0, 2.5, 12.0, 0.4, 0.4, 1.0])
    heavy = domain_of("MOHopperHeavy-v5")
    assert heavy.context_of("MOHopperHeavy-v5")[:4].tolist() == [9.0, 9.0, 8.5, 10.0]
    hum = domain_of("MOHumanoidHard-v5").context_of("MOHumanoidHard-v5")
    assert hum[9].item() == pytest.approx(0.1)  # right upper arm, below the DR minimum (SPEC §5.10)
    assert hum[13 + 6].item() == pytest.approx(0.2)  # right knee damping of LowDamping


def test_unknown_id_lists_close_matches():
    with pytest.raises(ValueError, match=r"unknown env id 'MOHoperHeavy-v5'.*MOHopperHeavy-v5"):
        make_env("MOHoperHeavy-v5")


# ---------------------------------------------------------------- base env on a toy domain
def test_toy_env_specs_and_hand_computed_rewards():
    env = ToyContextEnv(num_envs=2, context=torch.tensor([[2.0, 0.5], [1.0, 0.0]]))
    check_env_specs(env)
    td = env.reset()
    td["action"] = torch.tensor([1, 0])
    out = env.step(td)["next"]
    assert out["reward"].tolist() == [[2.5, -1.0], [-1.0, -1.0]]
    assert out["original_reward"].squeeze(-1).tolist() == [1.5, -2.0]
    assert out["context"].tolist() == [[2.0, 0.5], [1.0, 0.0]]


def test_truncation_and_termination():
    env = ToyContextEnv(num_envs=2, max_episode_steps=4)
    td = env.reset()
    dones = []
    # sub-env 0 walks right and reaches |pos| = 3 at step 3; sub-env 1 oscillates until truncation
    for action in ([1, 1], [1, 0], [1, 1], [1, 0]):
        td["action"] = torch.tensor(action)
        td = env.step(td)
        dones.append((td["next", "terminated"].squeeze(-1).tolist(), td["next", "truncated"].squeeze(-1).tolist()))
        td = td["next"]
    assert dones[:2] == [([False, False], [False, False])] * 2
    assert dones[2] == ([True, False], [False, False])
    assert dones[3][1] == [False, True]  # sub-env 0 is done already; only 1 truncates


def test_reset_sets_contexts_and_partial_reset_leaves_others_alone():
    env = ToyContextEnv(num_envs=3)
    env.reset(TensorDict(context=torch.tensor([[1.5, 0.1], [0.7, 0.2], [1.9, -0.3]]), batch_size=[3]))
    assert env.context[:, 0].tolist() == pytest.approx([1.5, 0.7, 1.9])
    td = env.reset()
    td["action"] = torch.ones(3, dtype=torch.long)
    td = env.step(td)["next"]
    td["_reset"] = torch.tensor([[False], [True], [False]])
    td["context"] = torch.full((3, 2), 0.9)
    out = env.reset(td)
    assert env.context[:, 0].tolist() == pytest.approx([1.5, 0.9, 1.9])
    assert out["observation"][:, 0].tolist() == [1.0, 0.0, 1.0]  # only sub-env 1 went back to 0


def test_bad_context_at_reset_changes_nothing():
    env = ToyContextEnv(num_envs=2)
    before = env.context
    with pytest.raises(ValueError, match="'speed' is -2.0"):
        env.reset(TensorDict(context=torch.tensor([[1.0, 0.0], [-2.0, 0.0]]), batch_size=[2]))
    with pytest.raises(ValueError, match=r"expected \[\.\.\., 2\]"):
        env.reset(TensorDict(context=torch.zeros(2, 5), batch_size=[2]))
    assert torch.equal(env.context, before)


@pytest.mark.parametrize(
    "action, match",
    [(torch.tensor([0, 2]), "out of the action space"), (torch.tensor([[0, 1], [1, 0]]), "shape"), (torch.tensor([0.5, 1.0]), "integers")],
)
def test_bad_actions_raise(action, match):
    env = ToyContextEnv(num_envs=2)
    td = env.reset()
    td["action"] = action
    with pytest.raises(ValueError, match=match):
        env.step(td)


def oscillate(td):
    """Step right from 0, left from 1: never terminates, so episodes last exactly 6 steps."""
    return td.set("action", (td["observation"][:, 0] <= 0).long())


def test_domain_randomization_per_subenv_and_episode_and_seeded():
    def contexts(seed):
        env = TransformedEnv(ToyContextEnv(num_envs=4), DomainRandomization(TOY_CONTEXT, seed=seed))
        return env.rollout(13, oscillate, break_when_any_done=False)["context"]

    a, b = contexts(0), contexts(0)
    assert torch.equal(a, b)
    first = a[:, 0]
    assert len({tuple(r) for r in first.tolist()}) == 4  # different per sub-env
    assert not torch.equal(a[:, 0], a[:, 12])  # episodes of 6 steps: resampled by step 12
    assert torch.equal(a[:, 0], a[:, 5])  # constant within an episode
    assert not torch.equal(contexts(1), a)
    assert TOY_CONTEXT.contains(a)


def test_domain_randomization_fixed_parameter():
    env = TransformedEnv(ToyContextEnv(num_envs=8), DomainRandomization(TOY_CONTEXT, seed=0, fixed={"bias": 0.25}))
    ctx = env.reset()["context"]
    assert (ctx[:, 1] == 0.25).all() and ctx[:, 0].unique().numel() == 8


def test_partial_steps_advance_only_the_selected_subenvs():
    env = ToyContextEnv(num_envs=3)
    td = env.reset()
    td["action"] = torch.ones(3, dtype=torch.long)
    td["_step"] = torch.tensor([True, False, True])
    out = env.step(td)["next"]
    assert out["observation"][[0, 2]].flatten().tolist() == pytest.approx([1.0, 0.1, 1.0, 0.1])
    td = out.clone()
    td["action"] = torch.ones(3, dtype=torch.long)
    out = env.step(td)["next"]
    # sub-env 1 was skipped once: one step behind
    assert out["observation"].flatten().tolist() == pytest.approx([2.0, 0.2, 1.0, 0.1, 2.0, 0.2])
