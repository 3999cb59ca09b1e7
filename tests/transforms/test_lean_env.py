"""``LeanTransformedEnv.step_and_maybe_reset``'s short path gives TorchRL's ``TransformedEnv`` results.

Each stack is built twice from the same seeds: once as a :class:`LeanTransformedEnv`, once as
TorchRL's ``TransformedEnv`` with the same transforms. Both are stepped with the same actions
(and an extra policy entry), and every TensorDict they return must be equal entry for entry at
every step, across full and partial auto-resets, so the preferences drawn at the resets are too.
"""

from __future__ import annotations

import pytest
import torch
from torchrl.envs import EnvBase, RewardSum, TransformedEnv

from morl_trl.envs import make_env
from morl_trl.transforms import (
    DiscountedVectorReturn,
    LeanTransformedEnv,
    LinearScalarization,
    PreferenceConditioning,
    StateActionHistory,
    compose_training_env,
)
from morl_trl.transforms.command import DesiredReturnConditioning
from tests.mocks import ToyContextEnv
from tests._tensordicts import assert_same_tensordict


def _transforms(history: int = 0, extra=()):
    out = [StateActionHistory(history)] if history else []
    return [*out, PreferenceConditioning(2, mode="gaussian", seed=7), *extra, DiscountedVectorReturn(0.9)]


def _run_both(make_base, steps: int, monkeypatch, *, history: int = 0, extra=lambda: (),
              transforms=None) -> tuple[int, int, int]:
    """(sub-env episodes ended, full resets, TorchRL calls of the lean env's step and in-step reset) over ``steps`` steps
    (``transforms``: a callable giving the stack, instead of the preference and the returns around ``extra``)."""
    transforms = transforms or (lambda: _transforms(history, extra()))
    lean = LeanTransformedEnv(make_base())
    for t in transforms():
        lean.append_transform(t)
    generic = TransformedEnv(make_base())
    for t in transforms():
        generic.append_transform(t)
    generic_calls = []
    original = TransformedEnv._step_and_maybe_reset

    def counted(self, tensordict):
        if self is lean:
            generic_calls.append(1)
        return original(self, tensordict)

    monkeypatch.setattr(TransformedEnv, "_step_and_maybe_reset", counted)
    original_reset = TransformedEnv._reset

    def counted_reset(self, tensordict=None, **kwargs):
        if self is lean and tensordict is not None:  # (a reset inside a step: the lean path, or TorchRL's)
            generic_calls.append(1)
        return original_reset(self, tensordict, **kwargs)

    monkeypatch.setattr(TransformedEnv, "_reset", counted_reset)
    td_lean, td_generic = lean.reset(), generic.reset()
    assert_same_tensordict(td_lean, td_generic, "reset")
    gen = torch.Generator().manual_seed(0)
    n = lean.batch_size[0]
    ended = full = 0
    for t in range(steps):
        action = torch.randint(0, lean.action_spec.space.n, (n,), generator=gen)
        extra_out = torch.randn(n, 3, generator=gen)
        for td in (td_lean, td_generic):
            td["action"] = action.clone()
            td["policy_output"] = extra_out.clone()
        out_lean, td_lean = lean.step_and_maybe_reset(td_lean)
        out_generic, td_generic = generic.step_and_maybe_reset(td_generic)
        assert_same_tensordict(out_lean, out_generic, f"step {t}")
        assert_same_tensordict(td_lean, td_generic, f"step {t}, after the resets")
        done = out_lean["next", "done"]
        ended += int(done.sum())
        full += int(done.all())
    return ended, full, len(generic_calls)


def test_one_mo_gymnasium_env_matches_torchrl_and_takes_the_short_path(monkeypatch):
    pytest.importorskip("mo_gymnasium")
    ended, full, torchrl_calls = _run_both(lambda: make_env("deep-sea-treasure-v0", num_envs=1, seed=0), 300,
                                           monkeypatch)
    assert torchrl_calls == 0
    assert ended == full >= 20  # (one env: every reset is a full one; DST's random episodes are short)


def test_partial_resets_and_history_match_torchrl(monkeypatch):
    ended, full, torchrl_calls = _run_both(lambda: ToyContextEnv(num_envs=3, seed=0), 60, monkeypatch, history=2)
    assert torchrl_calls == 0
    assert ended >= 20 and ended > 3 * full  # (mostly partial resets: some sub-envs reset, others not)


def _command(k: int = 2) -> DesiredReturnConditioning:
    t = DesiredReturnConditioning(k, max_return=[5.0] * k)
    t.set_command(torch.arange(1.0, k + 1.0), 4.0)
    return t


def test_pcns_command_takes_the_short_path_with_torchrls_results(monkeypatch):
    """PCN's stack (the return-and-horizon command, updated every step, taken afresh at each partial reset)."""
    ended, full, torchrl_calls = _run_both(lambda: ToyContextEnv(num_envs=3, seed=2), 60, monkeypatch,
                                           extra=lambda: (_command(),))
    assert torchrl_calls == 0
    assert ended >= 20 and ended > 3 * full


def test_pcns_one_env_stack_on_fruit_tree_takes_the_short_path_with_torchrls_results(monkeypatch):
    pytest.importorskip("mo_gymnasium")
    # (as make_pcn_training_env: the command, then the undiscounted returns)
    ended, full, torchrl_calls = _run_both(lambda: make_env("fruit-tree-v0", num_envs=1, seed=0), 60, monkeypatch,
                                           transforms=lambda: [_command(6), DiscountedVectorReturn(1.0)])
    assert torchrl_calls == 0
    assert ended == full == 10  # (fruit-tree's episodes: 6 steps, depth 6)


def test_another_transform_takes_torchrls_path_with_the_same_results(monkeypatch):
    ended, _, torchrl_calls = _run_both(lambda: ToyContextEnv(num_envs=2, seed=1), 30, monkeypatch,
                                        extra=lambda: (LinearScalarization(), RewardSum(in_keys=["scalar_reward"])))
    assert torchrl_calls > 30 and ended >= 5  # (every step, and the resets inside some: TorchRL's)


def test_training_stack_is_lean_and_a_given_transformed_env_is_kept():
    env = compose_training_env(make_env("MOLavaGridDR-v0", num_envs=2, seed=0), gamma=0.99, preference_seed=1)
    assert type(env) is LeanTransformedEnv and env.lean_step_applies(env.reset().set("action", torch.zeros(2)))
    mine = TransformedEnv(ToyContextEnv(num_envs=1))
    assert compose_training_env(mine, gamma=0.9) is mine and type(mine) is TransformedEnv


def test_partial_step_takes_torchrls_path():
    env = LeanTransformedEnv(ToyContextEnv(num_envs=2), DiscountedVectorReturn(0.5))
    td = env.reset()
    td["action"] = torch.tensor([1, 1])
    td["_step"] = torch.tensor([True, False])
    assert not env.lean_step_applies(td)
    out, _ = EnvBase.step_and_maybe_reset(env, td)
    assert out["next", "observation"][:, 0].tolist() == [1.0, 0.0]
