"""Contexts are env data: every id is a ``ContextualMOEnv``; DR ids draw with the env's own
``ContextSampler``; an explicit reset context is used on every id."""

import re
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import SerialEnv, TransformedEnv

from morl_trl.envs import ContextSampler, ContextualMOEnv, context_space, domain_of, list_envs, make_env
from morl_trl.transforms import DomainRandomization
from tests.mocks import TOY_CONTEXT, ToyContextEnv

ROOT = Path(__file__).resolve().parents[2]
_SIMULATOR = {"LunarLander": "Box2D", "Hopper": "mujoco", "HalfCheetah": "mujoco", "Humanoid": "mujoco",
              "SuperMario": "nes_py"}


def _needs(env_id: str) -> None:
    for name, module in _SIMULATOR.items():
        if name in env_id:
            pytest.importorskip(module)


def _stream(seed: int, space=None):
    space = TOY_CONTEXT if space is None else space
    gen = torch.Generator().manual_seed(seed)
    return lambda n: space.sample(n, generator=gen)


# ---------------------------------------------------------------- every id, one kind of object
def test_every_id_is_a_contextual_env_with_a_sampler_only_under_dr():
    built = 0
    for env_id in list_envs():
        if domain_of(env_id).foreign:  # (an MO-Gymnasium id another test trained on: one env, no contexts)
            continue
        try:
            _needs(env_id)
        except pytest.skip.Exception:
            continue
        env = make_env(env_id, num_envs=1, seed=0)
        assert isinstance(env, ContextualMOEnv) and not isinstance(env, TransformedEnv), env_id
        assert (env.context_sampler is not None) == (env_id == domain_of(env_id).train_id), env_id
        assert type(env.append_transform(DomainRandomization(env.context_space))) is TransformedEnv
        env.close()
        built += 1
    assert built >= 9  # LavaGrid's 9 need no extra; LunarLander adds 20, MuJoCo 19, Mario 33


def test_docs_transforms_snippet_on_a_fixed_and_a_dr_id():
    page = (ROOT / "docs" / "tutorials" / "compose-transforms.md").read_text()  # (was the README's)
    code = re.search(r"```python\n(.*?)```", page, re.S).group(1)
    assert 'make_env("MOHopperDR-v5", num_envs=16, seed=0).append_transform(Compose(' in code
    for env_id, k in (("MOLunarLanderHard-v0", 4), ("MOHopperDR-v5", 3)):
        _needs(env_id)
        src = code.replace('"MOHopperDR-v5", num_envs=16', f'"{env_id}", num_envs=2')
        src = src.replace("PreferenceConditioning(3)", f"PreferenceConditioning({k})")
        scope = {}
        exec("from morl_trl.envs import make_env\n" + src, scope)
        env = scope["env"]
        assert isinstance(env, TransformedEnv) and isinstance(env.base_env, ContextualMOEnv)
        td = env.rollout(5, break_when_any_done=False)
        assert "preference" in td.keys() and td["preference"].shape == (2, 5, k)
        torch.testing.assert_close(td["preference"].sum(-1), torch.ones(2, 5))


def test_importing_the_registry_loads_no_simulator():
    code = (
        "import sys, torchrl.envs\n"
        "before = set(sys.modules)\n"  # (torchrl itself may import mujoco for its own envs)
        "import morl_trl.envs\n"
        "ids = morl_trl.envs.list_envs()\n"
        "import morl_trl.envs.lunar_lander.spec, morl_trl.envs.mujoco.spec, morl_trl.envs.mario.spec\n"
        "new = set(sys.modules) - before\n"
        "bad = sorted(m for m in new if m.split('.')[0] in ('Box2D', 'mujoco', 'nes_py', 'gym')\n"
        "             or m in ('morl_trl.envs.lunar_lander.env', 'morl_trl.envs.mujoco.base', 'morl_trl.envs.mario.env'))\n"
        "print(len(ids), bad)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    count, bad = out.stdout.strip().split(" ", 1)
    assert int(count) >= 60 and bad == "[]", out.stdout + out.stderr


def test_spec_modules_do_not_import_the_registry():
    for domain in ("lunar_lander", "lava_grid", "mario", "mujoco"):
        text = (ROOT / "morl_trl" / "envs" / domain / "spec.py").read_text()
        assert "registry" not in text.replace("not the registry", ""), domain
    assert not (ROOT / "morl_trl" / "envs" / "specs").exists()


# ---------------------------------------------------------------- seeding: the old stream
@pytest.mark.parametrize("env_id", ["MOLunarLanderDR-v0", "MOHopperDR-v5"])
def test_dr_first_reset_draws_exactly_the_seeded_stream(env_id):
    _needs(env_id)
    space = context_space(env_id)
    env = make_env(env_id, num_envs=5, seed=13)
    expected = space.sample(5, generator=torch.Generator().manual_seed(13))
    assert torch.equal(env.reset()["context"], expected)
    env.set_seed(21)  # re-seeding the env re-seeds the context stream
    assert torch.equal(env.reset()["context"], space.sample(5, generator=torch.Generator().manual_seed(21)))


def test_dr_id_gives_the_same_rollout_as_the_old_transform_layout():
    pytest.importorskip("Box2D")
    from morl_trl.envs.lunar_lander import MOLunarLanderEnv

    space = context_space("MOLunarLanderDR-v0")
    new = make_env("MOLunarLanderDR-v0", num_envs=4, seed=3, wind_power=2.0)
    old = TransformedEnv(
        MOLunarLanderEnv(num_envs=4, seed=3, context=space.make(wind_power=2.0)),
        DomainRandomization(space, seed=3, fixed={"wind_power": 2.0}),
    )
    rollouts = []
    for env in (new, old):
        torch.manual_seed(0)
        rollouts.append(env.rollout(250, break_when_any_done=False))
    a, b = rollouts
    assert int(a["next", "done"].sum()) >= 4  # auto-resets happened
    for key in ("context", ("next", "reward"), ("next", "observation"), ("next", "done")):
        assert torch.equal(a[key], b[key]), key
    assert (a["context"][..., 1] == 2.0).all()


def test_env_seed_seeds_an_unseeded_sampler_and_a_seeded_one_keeps_its_seed():
    env = ToyContextEnv(num_envs=3, seed=11, context_sampler=ContextSampler(TOY_CONTEXT))
    assert env.context_sampler.seed == 11
    assert torch.equal(env.reset()["context"], _stream(11)(3))
    env = ToyContextEnv(num_envs=3, seed=11, context_sampler=ContextSampler(TOY_CONTEXT, seed=2))
    assert torch.equal(env.reset()["context"], _stream(2)(3))
    env.set_seed(5)
    assert torch.equal(env.reset()["context"], _stream(5)(3))


def test_serial_env_workers_follow_their_seeds():
    env = SerialEnv(2, lambda: ToyContextEnv(num_envs=2, seed=0, context_sampler=ContextSampler(TOY_CONTEXT)))
    env.set_seed(20)
    ctx = env.reset()["context"]
    seeds = [w._seed for w in env._envs]
    assert seeds[0] == 20 and seeds[1] != 20
    assert torch.equal(ctx[0], _stream(seeds[0])(2)) and torch.equal(ctx[1], _stream(seeds[1])(2))


# ---------------------------------------------------------------- the reset-context rule
def test_explicit_reset_context_is_used_exactly_under_a_dr_id():
    pytest.importorskip("Box2D")
    env = make_env("MOLunarLanderDR-v0", num_envs=2, seed=0)
    given = torch.tensor([[-11.5, 3.0, 0.5, 12.5, 0.45, 0.55, 0.8], [-8.0, 0.0, 0.0, 15.0, 0.7, 0.3, 0.9]])
    td = env.reset(TensorDict(context=given, batch_size=[2]))
    assert torch.equal(td["context"], given) and torch.equal(env.context, given)
    env.reset()  # without one, the sampler draws again
    assert not torch.equal(env.context, given)


def test_explicit_reset_context_on_a_domain_with_its_own_reset():
    from morl_trl.envs.lava_grid import evaluation_maps

    env = make_env("MOLavaGridDR-v0", num_envs=2, seed=0)
    room = evaluation_maps()["Room"]
    td = env.reset(TensorDict(context=room.expand(2, -1), batch_size=[2]))
    assert torch.equal(td["context"], room.expand(2, -1))
    assert not torch.equal(env.reset()["context"][0], room)


@pytest.mark.parametrize("bad", [torch.zeros(2, 6), torch.ones(2, 8)])
def test_wrong_width_context_raises_the_same_error_on_dr_and_fixed_ids(bad):
    pytest.importorskip("Box2D")
    messages = []
    for env_id in ("MOLunarLanderDR-v0", "MOLunarLanderHard-v0"):
        env = make_env(env_id, num_envs=2, seed=0)
        env.reset()
        before = env.context
        with pytest.raises(ValueError, match=r"expected \[\.\.\., 7\] with parameters \['gravity'") as err:
            env.reset(TensorDict(context=bad, batch_size=[2]))
        messages.append(str(err.value))
        assert torch.equal(env.context, before)
    assert messages[0] == messages[1]


def test_bad_context_value_leaves_a_dr_env_unchanged():
    pytest.importorskip("Box2D")
    env = make_env("MOLunarLanderDR-v0", num_envs=2, seed=0)
    env.reset()
    before, state = env.context, env.context_sampler.get_state()
    bad = before.clone()
    bad[1, 3] = -1.0  # main_engine_power must be positive
    with pytest.raises(ValueError, match=r"'main_engine_power' is -1.0 \(row 1\)"):
        env.reset(TensorDict(context=bad, batch_size=[2]))
    assert torch.equal(env.context, before)
    assert torch.equal(env.context_sampler.get_state()["generator"], state["generator"])  # nothing drawn


def test_partial_reset_draws_only_for_the_selected_subenvs():
    env = ToyContextEnv(num_envs=4, seed=0, context_sampler=ContextSampler(TOY_CONTEXT, seed=8))
    stream = _stream(8)
    first = env.reset()["context"]
    assert torch.equal(first, stream(4))
    env._pos[:] = 2.0
    mask = torch.tensor([True, False, True, False])
    env.reset(TensorDict(_reset=mask[:, None], batch_size=[4]))
    after = env.context
    assert torch.equal(after[~mask], first[~mask]) and torch.equal(after[mask], stream(2))
    assert env._pos.tolist() == [0.0, 2.0, 0.0, 2.0]


def test_torchrl_maybe_reset_draws_although_the_td_carries_the_old_context():
    env = ToyContextEnv(num_envs=3, seed=0, context_sampler=ContextSampler(TOY_CONTEXT, seed=4))
    stream = _stream(4)
    td = env.reset()
    assert torch.equal(td["context"], stream(3))
    old = td["context"].clone()
    td["done"] = torch.tensor([[False], [True], [False]])
    out = env.maybe_reset(td)  # the reset TD TorchRL builds holds only "_reset"
    new = stream(1)
    assert torch.equal(out["context"][1], new[0]) and torch.equal(env.context[1], new[0])
    assert torch.equal(out["context"][[0, 2]], old[[0, 2]])


# ---------------------------------------------------------------- the sampler itself
def test_sampler_custom_draws_fixed_values_previous_and_state():
    seen = []

    def shifted(n, generator, previous):
        seen.append(previous.clone())
        return previous + torch.tensor([0.25, 0.0])

    sampler = ContextSampler(TOY_CONTEXT, sampler=shifted, fixed={"bias": 5.0}, seed=0)
    assert sampler.takes_previous
    out = sampler.draw(2, previous=torch.tensor([[1.0, 0.0], [1.5, 0.5]]))
    assert out.dtype == torch.float32 and out.tolist() == [[1.25, 5.0], [1.75, 5.0]]  # fixed may lie outside
    assert sampler.draw(1).tolist() == [[1.25, 5.0]] and seen[-1].tolist() == [[1.0, 0.0]]  # default previous
    sampler.sampler = lambda n, g: torch.tensor([[2.5, 0.0]]).expand(n, 2)
    with pytest.raises(ValueError, match=r"invalid context: context parameter 'speed' is 2.5 \(row 0\)"):
        sampler.draw(2)
    with pytest.raises(ValueError, match="unknown context parameter 'mass'"):
        ContextSampler(TOY_CONTEXT, fixed={"mass": 1.0})
    plain = ContextSampler(TOY_CONTEXT, seed=3)
    state = plain.get_state()
    a = plain.draw(4)
    assert torch.equal(a, _stream(3)(4))
    plain.set_state(state)
    assert torch.equal(plain.draw(4), a)


def test_writing_into_an_output_in_place_does_not_change_the_env():
    """TorchRL's ``Collector.reset()`` zeroes its carrier in place; the outputs used to share the env's own context
    tensor, so a reset zeroed MO-LavaGrid's goals and reward weights (found when GPI-LS began resetting its
    collector at each iteration) and the next draw failed on the zeroed goals."""
    from torchrl.collectors import Collector

    env, twin = make_env("MOLavaGridDR-v0", num_envs=2, seed=3), make_env("MOLavaGridDR-v0", num_envs=2, seed=3)
    out, ref = env.reset(), twin.reset()
    context = env.context.clone()
    out["context"].zero_()
    action = twin.full_action_spec.zero()["action"]
    step = env.step(out.clone().set("action", action))
    step["next", "context"].zero_()
    assert torch.equal(env.context, context) and not torch.equal(context, torch.zeros_like(context))
    ref = twin.step(ref.set("action", action))
    assert torch.equal(step["next", "reward"], ref["next", "reward"])
    collector = Collector(env, None, frames_per_batch=4, total_frames=8)
    next(iter(collector))
    collector.reset()  # (raised "index -12 is out of bounds" before)
    assert (env.context != 0).any(dim=-1).all()
