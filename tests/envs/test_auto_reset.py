"""``ContextualMOEnv.step_and_maybe_reset``'s lean path gives TorchRL's generic results.

Each env is run twice from the same seed: once through the override, once through
``EnvBase._step_and_maybe_reset`` (``step`` + ``step_mdp`` + ``maybe_reset``). Both
TensorDicts must be equal entry for entry at every step, across auto-resets, with extra
entries (a policy output) carried along and zeroed in the rows that reset.
"""

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import EnvBase

from morl_trl.envs import make_env
from morl_trl.envs import ContextSampler, ContextualMOEnv
from morl_trl.transforms import StateActionHistory
from tests.mocks import TOY_CONTEXT, ToyContextEnv
from tests._tensordicts import assert_same_tensordict


def _run_both(make, steps: int, *, nested: bool = False) -> int:
    lean, generic = make(), make()
    td_lean, td_generic = lean.reset(), generic.reset()
    assert_same_tensordict(td_lean, td_generic, "reset")
    gen = torch.Generator().manual_seed(0)
    spec = lean.action_spec
    resets = 0
    for t in range(steps):
        if spec.dtype == torch.long:
            action = torch.randint(0, spec.space.n, spec.shape, generator=gen)
        else:
            action = torch.rand(spec.shape, generator=gen) * 2 - 1
        extra = torch.randn(lean.num_envs, 3, generator=gen)
        for td in (td_lean, td_generic):
            td["action"] = action.clone()
            td["policy_output"] = extra.clone()
            if nested:
                td["policy", "hidden"] = extra[:, :1].clone()
        out_lean, td_lean = lean.step_and_maybe_reset(td_lean)
        out_generic, td_generic = EnvBase._step_and_maybe_reset(generic, td_generic)
        assert_same_tensordict(out_lean, out_generic, f"step {t}")
        assert_same_tensordict(td_lean, td_generic, f"step {t}, after the resets")
        resets += int(out_lean["next", "done"].sum())
    return resets


def test_toy_env_matches_torchrl_path_with_hand_checked_reset_rows():
    resets = _run_both(lambda: ToyContextEnv(num_envs=3, seed=0), steps=40)
    assert resets >= 10  # episodes last at most 6 steps
    env = ToyContextEnv(num_envs=2)
    td = env.reset()
    td["action"] = torch.tensor([1, 1])
    td["policy_output"] = torch.ones(2, 3)
    for _ in range(2):
        _, td = env.step_and_maybe_reset(td)
    td["action"] = torch.tensor([1, 0])
    out, td = env.step_and_maybe_reset(td)  # sub-env 0 reaches position 3 and terminates
    assert out["next", "done"].squeeze(-1).tolist() == [True, False]
    assert out["next", "observation"][0].tolist() == [3.0, 0.30000001192092896]  # the step's, kept
    assert td["observation"].tolist() == [[0.0, 0.0], [1.0, 0.30000001192092896]]
    assert td["done"].squeeze(-1).tolist() == [False, False]
    assert td["action"].tolist() == [0, 0] and td["policy_output"].tolist() == [[0.0] * 3, [1.0] * 3]


def test_lunar_lander_matches_torchrl_path():
    pytest.importorskip("Box2D")
    assert _run_both(lambda: make_env("MOLunarLanderDefault-v0", num_envs=4, seed=3), steps=300) >= 4


def test_continuous_lunar_lander_matches_torchrl_path():
    pytest.importorskip("Box2D")
    assert _run_both(lambda: make_env("MOLunarLanderContinuousDefault-v0", num_envs=3, seed=1), steps=200) >= 2


def test_domain_with_its_own_reset_matches_torchrl_path():
    # MO-LavaGrid with randomize=True draws new maps in its own _reset
    from morl_trl.envs.lava_grid import MOLavaGridEnv

    make = lambda: MOLavaGridEnv(num_envs=8, seed=0, randomize=True, max_episode_steps=15)  # noqa: E731
    assert _run_both(make, steps=40) >= 16


def test_nested_entries_take_torchrl_path_with_the_same_results():
    assert _run_both(lambda: ToyContextEnv(num_envs=3, seed=0), steps=20, nested=True) >= 5


def test_partial_step_takes_torchrl_path():
    env = ToyContextEnv(num_envs=2)
    td = env.reset()
    td["action"] = torch.tensor([1, 1])
    td["_step"] = torch.tensor([True, False])
    out, td = env.step_and_maybe_reset(td)
    assert out["next", "observation"][:, 0].tolist() == [1.0, 0.0]


@pytest.mark.parametrize("env_id", ["MOHopperDefault-v5"])
def test_mujoco_matches_torchrl_path(env_id):
    pytest.importorskip("mujoco")
    assert _run_both(lambda: make_env(env_id, num_envs=3, seed=0), steps=120) >= 1


# ---------------------------------------------------------------- domain randomization
def _toy_dr(seed=0, sampler_seed=5, num_envs=3):
    return ToyContextEnv(num_envs=num_envs, seed=seed, context_sampler=ContextSampler(TOY_CONTEXT, seed=sampler_seed))


def test_dr_env_matches_torchrl_path_and_draws_the_same_contexts():
    assert _run_both(_toy_dr, steps=40) >= 10
    # the lean path drew exactly the stream of ContextSampler(TOY_CONTEXT, seed=5)
    env, stream = _toy_dr(), torch.Generator().manual_seed(5)
    td = env.reset()
    torch.testing.assert_close(td["context"], TOY_CONTEXT.sample(3, generator=stream))
    td["action"] = torch.ones(3, dtype=torch.long)
    for _ in range(3):  # every sub-env reaches position 3 at the third step
        out, td = env.step_and_maybe_reset(td.set("action", torch.ones(3, dtype=torch.long)))
    assert out["next", "done"].all()
    torch.testing.assert_close(td["context"], TOY_CONTEXT.sample(3, generator=stream))
    torch.testing.assert_close(out["next", "context"], out["context"])  # the ended episodes' contexts


def test_dr_lunar_lander_matches_torchrl_path():
    pytest.importorskip("Box2D")
    env = make_env("MOLunarLanderDR-v0", num_envs=4, seed=2)
    assert isinstance(env, ContextualMOEnv) and env.context_sampler is not None
    assert _run_both(lambda: make_env("MOLunarLanderDR-v0", num_envs=4, seed=2), steps=300) >= 4


def test_dr_env_with_more_transforms_matches_torchrl_path():
    pytest.importorskip("Box2D")

    def make():
        return make_env("MOLunarLanderDR-v0", num_envs=2, seed=0).append_transform(StateActionHistory(2))

    assert _run_both(make, steps=150) >= 1


def test_dr_bad_draw_raises_and_resets_nothing():
    bad = torch.tensor([[3.0, 0.0]] * 2)
    sampler = ContextSampler(TOY_CONTEXT)
    env = ToyContextEnv(num_envs=2, context_sampler=sampler)
    td = env.reset()  # the first reset draws from the space
    sampler.sampler = lambda n, g: bad[:n]
    td["action"] = torch.ones(2, dtype=torch.long)
    for _ in range(2):
        _, td = env.step_and_maybe_reset(td)
    td["action"] = torch.ones(2, dtype=torch.long)
    context, pos = env.context, env._pos.clone()
    with pytest.raises(ValueError, match=r"'speed' is 3.0 \(row 0\), outside its range"):
        env.step_and_maybe_reset(td)  # third step: position 3, both done; the draw is rejected
    assert torch.equal(env.context, context)
    assert env._pos.tolist() == [3.0, 3.0] and env._step_count.tolist() == [3, 3]  # nothing reset
    assert torch.equal(pos + 1, env._pos)


@pytest.mark.parametrize("env_id, steps", [("MOLavaGridDR-v0", 300), ("MOHopperDR-v5", 120)])
def test_dr_ids_of_other_domains_match_torchrl_path(env_id, steps):
    if "Hopper" in env_id:
        pytest.importorskip("mujoco")
    make = lambda: make_env(env_id, num_envs=4, seed=1)  # noqa: E731
    assert isinstance(make(), ContextualMOEnv) and make().context_sampler is not None
    assert _run_both(make, steps=steps) >= 1


def test_lazy_stacked_input_takes_torchrl_path():
    env = ToyContextEnv(num_envs=2)
    td = env.reset()
    td["action"] = torch.tensor([1, 1])
    lazy = TensorDict.lazy_stack(list(td.unbind(0)), 0)
    assert not env._lean_step_applies(lazy)
    out, nxt = env.step_and_maybe_reset(lazy)
    assert out["next", "observation"][:, 0].tolist() == [1.0, 1.0]
