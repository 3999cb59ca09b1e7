"""One rule for every domain: declared context bounds (and ``allow_extrapolation``), non-finite
steps, actions, seeds, ``num_envs`` and batch sizes each fail with a ``ValueError`` naming
what is valid."""

from __future__ import annotations

import importlib.util
import math

import pytest
import torch
from tensordict import TensorDict
from torchrl.data import Categorical

from morl_trl.envs import ContextSampler, context_space, domain_of, list_domains, make_env
from morl_trl.envs.base import NonFiniteStepError
from morl_trl.transforms import DomainRandomization

_MODULE = {"LunarLander": "Box2D", "Hopper": "mujoco", "HalfCheetah": "mujoco", "Humanoid": "mujoco", "DMC": "dm_control",
           "SuperMario": "nes_py"}
# one id per domain: the training id (its env has a context sampler)
DOMAIN_IDS = [spec.train_id for spec in list_domains()]


def _needs(env_id: str) -> None:
    for name, module in _MODULE.items():
        if name in env_id and importlib.util.find_spec(module) is None:
            pytest.skip(f"{env_id} needs {module}, which is not installed")


def _env(env_id: str, num_envs: int = 2, **kwargs):
    _needs(env_id)
    return make_env(env_id, num_envs=num_envs, seed=0, **kwargs)


def _is_discrete(env) -> bool:
    return isinstance(env.action_spec, Categorical)


# ---------------------------------------------------------------- 7. declared bounds
@pytest.mark.parametrize("spec", list_domains(), ids=lambda s: s.train_id)
def test_bounds_contain_default_dr_range_and_every_registered_context(spec):
    space = spec.context_space
    for name, d, lo, hi, vlo, vhi in zip(space.names, space.default, space.low, space.high,
                                         space.valid_low, space.valid_high):
        assert math.isfinite(vlo) and math.isfinite(vhi), f"{spec.name}: {name} has no declared bounds"
        assert vlo <= min(lo, d) and max(hi, d) <= vhi, name
    for env_id in spec.contexts:  # each registered context (evaluation or not) is inside
        ctx = spec.context_of(env_id)
        space.validate(ctx)  # raises if outside
        lo, hi = space.valid_bounds()
        assert bool(((ctx >= lo) & (ctx <= hi)).all()), env_id


def test_registered_contexts_outside_the_dr_range_are_inside_the_bounds():
    ll = context_space("MOLunarLanderDR-v0")
    assert ll.valid_low[0] <= -3.0 <= ll.valid_high[0] and not ll.low[0] <= -3.0 <= ll.high[0]  # LowGravity g=-3
    domain_of("MOLunarLanderLowGravity-v0").context_of("MOLunarLanderLowGravity-v0")
    hum = context_space("MOHumanoidDR-v5")
    light = domain_of("MOHumanoidLight-v5").context_of("MOHumanoidLight-v5")
    assert float(light[:13].min()) == pytest.approx(0.1) and hum.low[0] == 0.5  # below the DR minimum
    assert hum.valid_low[0] <= 0.1


def test_out_of_bounds_context_raises_at_make_env():
    pytest.importorskip("mujoco")
    with pytest.raises(ValueError, match=r"mass_torso.*1000000\.0.*declared bounds \[0\.01, 100\.0\].*allow_extrapolation"):
        make_env("MOHopperDefault-v5", mass_torso=1e6)
    with pytest.raises(ValueError, match=r"mass_torso.*declared bounds"):  # a fixed DR value too
        make_env("MOHopperDR-v5", mass_torso=1e6)
    pytest.importorskip("Box2D")
    with pytest.raises(ValueError, match=r"'gravity' is 3\.0.*\[-20\.0, -0\.5\]"):
        make_env("MOLunarLanderDefault-v0", gravity=3.0)


def test_out_of_bounds_context_raises_at_reset_and_leaves_the_env_unchanged():
    pytest.importorskip("mujoco")
    env = make_env("MOHopperDefault-v5", num_envs=2, seed=0)
    env.reset()
    before = env.context
    bad = before.clone()
    bad[1, 0] = 1e6
    with pytest.raises(ValueError, match=r"mass_torso.*\(row 1\).*declared bounds"):
        env.reset(TensorDict(context=bad, batch_size=[2]))
    assert torch.equal(env.context, before)


def test_out_of_bounds_raises_in_samplers_and_domain_randomization():
    space = context_space("MOLunarLanderDR-v0")
    with pytest.raises(ValueError, match=r"wind_power.*31\.0.*\[0\.0, 30\.0\]"):
        ContextSampler(space, fixed={"wind_power": 31.0})
    with pytest.raises(ValueError, match=r"wind_power.*declared bounds"):
        DomainRandomization(space, fixed={"wind_power": 31.0})
    sampler = ContextSampler(space, fixed={"wind_power": 31.0}, seed=0, allow_extrapolation=True)
    assert sampler.draw(3)[:, 1].tolist() == [31.0] * 3
    DomainRandomization(space, fixed={"wind_power": 31.0}, allow_extrapolation=True)
    # nan and non-positive values are refused even with extrapolation
    with pytest.raises(ValueError, match="finite"):
        ContextSampler(space, fixed={"gravity": float("nan")}, allow_extrapolation=True)
    with pytest.raises(ValueError, match="strictly positive"):
        ContextSampler(space, fixed={"main_engine_power": 0.0}, allow_extrapolation=True)


def test_allow_extrapolation_accepts_out_of_bounds_contexts():
    pytest.importorskip("Box2D")
    env = make_env("MOLunarLanderDefault-v0", num_envs=2, seed=0, allow_extrapolation=True, gravity=-25.0)
    assert env.allow_extrapolation and env.context[:, 0].tolist() == [-25.0, -25.0]
    env.rollout(5)
    ctx = env.context.clone()
    ctx[:, 1] = 40.0  # wind beyond its bounds: accepted at reset too
    assert env.reset(TensorDict(context=ctx, batch_size=[2]))["context"][:, 1].tolist() == [40.0, 40.0]
    assert env.context_dict(0)["gravity"] == -25.0
    with pytest.raises(ValueError, match="strictly positive"):  # still positive where needed
        make_env("MOLunarLanderDefault-v0", allow_extrapolation=True, main_engine_power=-1.0)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_first_non_finite_step_raises_naming_the_sub_env():
    """A 1e6 kg Hopper torso diverges (NaN) within ~50 steps: with extrapolation allowed, the
    first non-finite step raises, naming the sub-env and its context."""
    pytest.importorskip("mujoco")
    torch.manual_seed(0)
    env = make_env("MOHopperDefault-v5", num_envs=2, seed=0, allow_extrapolation=True)
    ctx = env.context.clone()
    ctx[1, 0] = 1e6  # only sub-env 1
    td = env.reset(TensorDict(context=ctx, batch_size=[2]))
    with pytest.raises(NonFiniteStepError, match=r"sub-env 1 produced a non-finite .*'mass_torso': 1000000\.0"):
        for _ in range(300):
            td["action"] = torch.zeros(2, 3)
            _, td = env.step_and_maybe_reset(td)
    assert issubclass(NonFiniteStepError, FloatingPointError) and issubclass(NonFiniteStepError, ValueError)


@pytest.mark.parametrize("env_id", DOMAIN_IDS)
def test_non_finite_check_on_every_domain(env_id, monkeypatch):
    env = _env(env_id)
    td = env.reset()
    td["action"] = env.action_spec.zero()
    step = type(env)._step_subenvs

    def nan_step(self, action):
        obs, reward, original, terminated = step(self, action)
        reward = reward.clone()
        reward[1, 0] = float("nan")
        return obs, reward, original, terminated

    monkeypatch.setattr(type(env), "_step_subenvs", nan_step)
    with pytest.raises(NonFiniteStepError, match=r"sub-env 1 produced a non-finite 'reward'.*its context"):
        env.step(td)
    monkeypatch.setattr(env, "check_finite", False)
    env.step(td)  # the opt-out


# ---------------------------------------------------------------- 8. actions
def _bad_discrete_actions(n: int):
    return {
        "inf": (torch.tensor([0.0, math.inf]), r"integers in \[0, \d+\); got inf"),
        "-inf": (torch.tensor([-math.inf, 0.0]), r"got -inf"),
        "nan": (torch.tensor([0.0, math.nan]), r"got nan"),
        "fraction": (torch.tensor([0.5, 0.0]), r"got 0\.5"),
        "bool": (torch.tensor([True, False]), r"integers in \[0, \d+\); got a torch\.bool tensor"),
        "negative": (torch.tensor([-1, 0]), r"action -1 is out of the action space \[0, \d+\)"),
        "too large": (torch.tensor([0, n]), rf"action {n} is out of the action space \[0, {n}\)"),
    }


@pytest.mark.parametrize("case", list(_bad_discrete_actions(3)))
@pytest.mark.parametrize("env_id", [i for i in DOMAIN_IDS if "Continuous" not in i and "Hopper" not in i
                                    and "Cheetah" not in i and "Humanoid" not in i and "Walker" not in i])
def test_bad_discrete_actions_raise_the_same_way(env_id, case):
    env = _env(env_id)
    n = env.action_spec.space.n
    action, message = _bad_discrete_actions(n)[case]
    td = env.reset()
    td["action"] = action
    with pytest.raises(ValueError, match=message):
        env.step(td)


@pytest.mark.parametrize("env_id", [i for i in DOMAIN_IDS if "Continuous" not in i and "Hopper" not in i
                                    and "Cheetah" not in i and "Humanoid" not in i and "Walker" not in i])
def test_integral_float_discrete_actions_are_accepted(env_id):
    env = _env(env_id)
    td = env.reset()
    td["action"] = torch.tensor([1.0, 0.0])
    env.step(td)


@pytest.mark.parametrize("env_id", [i for i in DOMAIN_IDS if i.startswith(("MOLunarLanderContinuous", "MOHopper",
                                                                           "MOHalfCheetah", "MOHumanoid", "DMC"))])
def test_bad_continuous_actions_raise_the_same_way(env_id):
    env = _env(env_id)
    td = env.reset()
    zero = env.action_spec.zero()
    high = float(env.action_spec.space.high.max())
    for value, message in ((math.nan, "NaN or inf"), (math.inf, "NaN or inf"),
                           (high + 1.0, r"out of its bounds \[-?[\d.]+, [\d.]+\]: min .*max")):
        bad = zero.clone()
        bad[1, 0] = value
        td["action"] = bad
        with pytest.raises(ValueError, match=message):
            env.step(td)
    td["action"] = torch.zeros(2, zero.shape[-1], dtype=torch.bool)
    with pytest.raises(ValueError, match="real numbers; got a torch.bool tensor"):
        env.step(td)
    td["action"] = torch.zeros(2, zero.shape[-1], dtype=torch.long)  # integers: converted exactly
    env.step(td)


# ---------------------------------------------------------------- 8. num_envs, seeds, batch size
@pytest.mark.parametrize("env_id", DOMAIN_IDS)
def test_num_envs_seed_and_batch_size_rules(env_id):
    _needs(env_id)
    for bad in (True, 0, -1, 2.0, "2"):
        with pytest.raises(ValueError, match="num_envs must be a positive int"):
            make_env(env_id, num_envs=bad)
    for bad in (-1, 2**63, 2**64, 1.5, True, "0"):
        with pytest.raises(ValueError, match=r"seed must be an int in \[0, 2\*\*63 - 1\]"):
            make_env(env_id, num_envs=1, seed=bad)
    env = make_env(env_id, num_envs=2, seed=2**63 - 1)  # the largest seed works on every domain
    env.set_seed(0)
    for bad in (-1, 2**64):
        with pytest.raises(ValueError, match=r"seed must be an int in \[0, 2\*\*63 - 1\]"):
            env.set_seed(bad)
    td = env.reset()
    td["action"] = env.action_spec.zero()
    wrong = td[:1]
    for call in (env.step, env.reset, env.step_and_maybe_reset):
        with pytest.raises(ValueError, match=r"batch size \[1\]; this env has batch size \[2\]"):
            call(wrong)
    env.step(td)  # unchanged by the refused calls


def test_sampler_seed_rule():
    space = context_space("MOLunarLanderDR-v0")
    for bad in (-1, 2**63, True):
        with pytest.raises(ValueError, match=r"seed must be an int in \[0, 2\*\*63 - 1\]"):
            ContextSampler(space, seed=bad)
    ContextSampler(space, seed=2**63 - 1).draw(1)
