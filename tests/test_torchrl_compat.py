"""Each TorchRL / tensordict private name morl_trl uses (all in ``morl_trl._torchrl_compat``)
still exists and does what we rely on; a TorchRL release that changes one fails here, by name."""

import inspect
import re

import pytest
import torch
from tensordict import TensorDict
from torchrl.collectors import Collector
from torchrl.data.replay_buffers.samplers import PrioritizedSampler
from torchrl.envs import EnvBase, TransformedEnv

from morl_trl import _torchrl_compat as compat
from morl_trl.envs import make_env
from morl_trl.transforms import DiscountedVectorReturn


def test_collector_state_round_trips_the_carried_step():
    env = make_env("MOLavaGridDR-v0", num_envs=2, seed=0)
    first = Collector(env, None, frames_per_batch=4, total_frames=8)
    next(iter(first))
    state = compat.collector_state(first)
    assert isinstance(state["carrier"], TensorDict) and state["carrier"].batch_size == torch.Size([2])
    second = Collector(make_env("MOLavaGridDR-v0", num_envs=2, seed=1), None, frames_per_batch=4, total_frames=8)
    compat.load_collector_state(second, state, "cpu")
    assert torch.equal(second._carrier["observation"], first._carrier["observation"])
    assert second._traj_pool.state_dict() == first._traj_pool.state_dict()
    first.shutdown()
    second.shutdown()


def test_transform_reset_and_step_run_a_transform_outside_its_env():
    env = TransformedEnv(make_env("MOLavaGridDR-v0", num_envs=2, seed=0), DiscountedVectorReturn(0.5))
    returns = env.transform
    td = env.reset()
    td.set("episode_return", torch.full((2, 2), 7.0))
    reset = compat.transform_reset(returns, td.clone(), td.clone())  # a reset without "_reset": every sub-env
    assert reset["episode_return"].tolist() == [[0.0, 0.0], [0.0, 0.0]]
    nxt = TensorDict({"reward": torch.tensor([[1.0, 2.0], [3.0, 4.0]]), "done": torch.zeros(2, 1, dtype=torch.bool)},
                     [2])
    nxt = compat.transform_step(returns, reset, nxt)
    assert nxt["episode_return"].tolist() == [[1.0, 2.0], [3.0, 4.0]]


def test_loss_helpers_exist_with_their_signatures():
    assert list(inspect.signature(compat.cache_values).parameters) == ["func"]
    assert list(inspect.signature(compat.vmap_func).parameters)[:2] == ["module", "args"]
    assert "randomness" not in inspect.signature(compat.vmap_func).parameters  # (passed on through **kwargs)


def test_new_tensordict_unsafe_builds_a_tensordict():
    td = compat.new_tensordict_unsafe({"a": torch.zeros(3, 2)}, batch_size=torch.Size([3]), device=None)
    assert isinstance(td, TensorDict) and td.batch_size == torch.Size([3]) and td["a"].shape == (3, 2)


def test_prioritized_sampler_internals_exist():
    missing = [n for n in compat.PRIORITIZED_SAMPLER_INTERNALS if not callable(getattr(PrioritizedSampler, n, None))]
    assert not missing, f"TorchRL's PrioritizedSampler no longer has {missing} (morl_trl.data.prioritized overrides them)"
    source = "".join(inspect.getsource(f) for f in vars(PrioritizedSampler).values() if inspect.isfunction(f))
    gone = [n for n in compat.PRIORITIZED_SAMPLER_STATE if f"self.{n}" not in source]
    assert not gone, f"TorchRL's PrioritizedSampler no longer reads {gone} (morl_trl.data.prioritized sets them)"


def test_env_base_internals_exist():
    missing = [n for n in compat.ENV_BASE_INTERNALS if n not in vars(EnvBase)]
    assert not missing, f"TorchRL's EnvBase no longer has {missing} (morl_trl.envs.ContextualMOEnv overrides them)"
    assert callable(EnvBase._step_and_maybe_reset) and EnvBase._post_step_mdp_hooks is None
    assert isinstance(vars(EnvBase)["_step_mdp"], property)  # (a cached step_mdp callable, read by ContextualMOEnv)


def _defines(cls: type, name: str) -> bool:
    """Whether TorchRL's ``cls`` (or a TorchRL / tensordict base of it) has ``name`` as a class
    attribute or sets it on ``self`` in one of its methods."""
    for base in cls.__mro__:
        if base.__module__.split(".")[0] not in ("torchrl", "tensordict"):
            continue
        if name in vars(base):
            return True
        for value in vars(base).values():
            funcs = [getattr(value, a, None) for a in ("fget", "fset", "__func__")] + [value]
            if any(inspect.isfunction(f) and re.search(rf"self\.{name}\s*(:[^=\n]*)?=(?!=)", inspect.getsource(f))
                   for f in funcs):
                return True
    return False


@pytest.mark.parametrize("cls", list(compat.SUBCLASS_INTERNALS), ids=lambda c: c.__name__)
def test_every_declared_subclass_hook_is_one_torchrl_defines(cls):
    missing = [n for n in compat.SUBCLASS_INTERNALS[cls] if not _defines(cls, n)]
    assert not missing, (f"TorchRL's {cls.__name__} no longer defines {missing}: the morl_trl subclasses that "
                         "override or read them (tests/test_layers.py lists where) must follow its new names")


def test_the_hook_check_tells_a_torchrl_name_from_a_missing_one():
    from torchrl.objectives import LossModule, SACLoss

    assert _defines(SACLoss, "_vmap_qnetworkN0")  # set in SACLoss._make_vmap
    assert _defines(LossModule, "_value_estimator") and _defines(LossModule, "_AcceptedKeys")
    assert not _defines(LossModule, "_not_a_torchrl_name") and not _defines(SACLoss, "_vmap_qnetwork")


# ---------------------------------------------------------------------- replay buffers (the captured update's sampling)
def _buffer(sampler=None):
    from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

    kw = {} if sampler is None else {"sampler": sampler}
    return TensorDictReplayBuffer(storage=LazyTensorStorage(8), batch_size=2, **kw)


def test_replay_sample_unit_is_the_buffers_sample_unit():
    buffer = _buffer()
    assert "_sample_unit" in vars(buffer), "TorchRL's ReplayBuffer no longer sets _sample_unit (recipes.capture reads it)"
    assert compat.replay_sample_unit(buffer) is None  # a buffer built without one: one row per sampled index
    buffer._sample_unit = marker = object()
    assert compat.replay_sample_unit(buffer) is marker


def test_storage_data_holds_the_rows_written_at_full_capacity():
    buffer = _buffer()
    buffer.extend(TensorDict({"x": torch.tensor([[1.0], [2.0], [3.0]])}, [3]))
    data = compat.storage_data(buffer.storage)
    assert isinstance(data, TensorDict), "TorchRL's LazyTensorStorage no longer keeps its rows in _storage"
    assert data.batch_size == torch.Size([8]) and data["x"][:3].flatten().tolist() == [1.0, 2.0, 3.0]
    assert data["x"][torch.tensor([2, 0])].flatten().tolist() == [3.0, 1.0]  # (indexed as the captured update does)


def test_sampler_generator_is_the_generator_the_buffer_gives_its_sampler():
    from morl_trl.data import prioritized_sampler

    buffer = _buffer(prioritized_sampler(8, alpha=0.6, beta=0.4))  # (a subclass of TorchRL's PrioritizedSampler)
    assert compat.sampler_generator(buffer.sampler) is None  # torch's global generator
    generator = torch.Generator().manual_seed(0)
    buffer.set_rng(generator)
    assert compat.sampler_generator(buffer.sampler) is generator, "TorchRL's samplers no longer keep set_rng's in _rng"


def test_module_kwargs_says_which_in_keys_go_by_keyword():
    from tensordict.nn import TensorDictModule

    positional = TensorDictModule(torch.nn.Identity(), in_keys=["x"], out_keys=["y"])
    keyword = TensorDictModule(lambda a: a, in_keys={"x": "a"}, out_keys=["y"])
    assert hasattr(positional, "_kwargs"), "tensordict's TensorDictModule no longer sets _kwargs (objectives.fast_path)"
    assert not compat.module_kwargs(positional)  # the fast paths call its module on the tensors directly
    assert list(compat.module_kwargs(keyword)) == ["x"]  # (tensordict keeps the in_key names)


def test_vecnorm_non_negative_var_gives_eps_not_nan_for_a_feature_equal_in_every_sample():
    from tensordict import TensorDict
    from torchrl.envs.transforms.vecnorm import VecNormV2

    from morl_trl._torchrl_compat import VecNormNonNegativeVar

    # running E[x] = 0.5 and E[x^2] rounded just below 0.25 (a feature equal in every sample so far)
    loc = TensorDict(observation=torch.tensor([0.5, 0.0]), batch_size=[])
    var = TensorDict(observation=torch.tensor([0.25 - 1e-7, 1.0]), batch_size=[])
    count = TensorDict(observation=torch.tensor(3), batch_size=[])
    data = TensorDict(observation=torch.tensor([[0.5, 2.0]]), batch_size=[1])
    kw = dict(in_keys=["observation"], decay=1.0, eps=1e-8, reduce_batch_dims=True)
    plain = VecNormV2(**kw)._norm(data.clone(), loc, var, count)["observation"]
    ours = VecNormNonNegativeVar(**kw)._norm(data.clone(), loc, var, count)["observation"]
    assert bool(plain[0, 0].isnan()) and plain[0, 1] == 2.0  # TorchRL's: sqrt of a negative
    assert ours.tolist() == [[0.0, 2.0]]


def test_reset_collector_restarts_every_episode_without_touching_the_envs_live_context():
    from torchrl.collectors import Collector

    from morl_trl._torchrl_compat import reset_collector
    from morl_trl.envs import make_env

    env = make_env("MOLavaGridDR-v0", num_envs=2, seed=0)
    collector = Collector(env, None, frames_per_batch=8, total_frames=16, auto_register_policy_transforms=False)
    first = next(iter(collector))
    reset_collector(collector)  # (collector.reset() alone zeroes the carrier, which shares the env's context)
    assert bool((env._context[:, :2] != 0).any())
    second = next(iter(collector))
    assert first.shape == second.shape == (2, 4)
    collector.shutdown()


# ---------------------------------------------------------------------- LossModule helpers
def test_priority_weight_and_reduce_loss_give_the_weighted_mean():
    loss = _sac_loss()
    td = TensorDict({"priority_weight": torch.tensor([1.0, 3.0])}, [2])
    weights = compat.priority_weight(loss, td)
    assert weights.tolist() == [1.0, 3.0], "TorchRL's LossModule._maybe_get_priority_weight no longer reads priority_weight"
    assert compat.priority_weight(loss, TensorDict({}, [2])) is None
    value = compat.reduce_loss(loss, torch.tensor([2.0, 4.0]), td, weights)
    assert value.item() == (2.0 * 1.0 + 4.0 * 3.0) / (1.0 + 3.0), \
        "TorchRL's LossModule._reduce_loss no longer gives the weighted mean sum(w loss) / sum(w)"
    assert compat.reduce_loss(loss, torch.tensor([2.0, 4.0]), td, None).item() == 3.0


def test_clear_weakrefs_and_default_device_exist_on_every_loss():
    from torchrl.objectives import LossModule

    assert list(inspect.signature(LossModule._clear_weakrefs).parameters) == ["self", "tds"]
    sac = _sac_loss()
    compat.clear_weakrefs(sac, TensorDict({}, []), "actor_network_params")  # (a no-op outside torch.compile)
    assert compat.default_device(sac) == torch.device("cpu")


def test_target_updater_params_pairs_the_online_and_target_parameters():
    from torchrl.objectives import SoftUpdate

    sac = _sac_loss()
    names, sources, targets = compat.target_updater_params(SoftUpdate(sac, tau=0.5))
    assert names == ["target_qvalue_network_params"]
    assert list(sources.keys()) == ["qvalue_network_params"] and list(targets.keys()) == names
    leaf = ("module", "mlp", "0", "weight")
    assert torch.equal(sources["qvalue_network_params"][leaf], sac.qvalue_network_params[leaf])
    assert torch.equal(targets["target_qvalue_network_params"][leaf], sac.target_qvalue_network_params[leaf])


# ---------------------------------------------------------------------- SACLoss (the SAC baseline)
def _sac_loss(**kw):
    from torchrl.data import Bounded
    from torchrl.objectives import SACLoss

    from morl_trl.objectives.networks import make_gaussian_actor, make_vector_critic

    torch.manual_seed(0)
    spec = Bounded(-1.0, 1.0, (2,))
    return SACLoss(make_gaussian_actor(5, spec, 1, num_cells=(8,), preference_key=None),
                   make_vector_critic(5, 2, 1, num_cells=(8,), preference_key=None), action_spec=spec, **kw)


def test_sac_alpha_is_the_clamped_temperature():
    loss = _sac_loss(alpha_init=4.0, max_alpha=2.0)
    assert abs(compat.sac_alpha(loss).item() - 2.0) < 1e-6, "TorchRL's SACLoss._alpha no longer clamps to max_alpha"
    assert abs(loss.log_alpha.item() - torch.log(torch.tensor(2.0)).item()) < 1e-6  # (clamped in place)
    assert not compat.sac_alpha(loss).requires_grad


def test_sac_vmap_qvalue_runs_every_critic_on_the_detached_parameters():
    loss = _sac_loss()
    params = compat.sac_detached_qvalue_params(loss)
    assert params.batch_size[0] == 2 and not any(p.requires_grad for p in params.values(True, True))
    td = TensorDict({"observation": torch.randn(3, 5), "action": torch.zeros(3, 2)}, [3])
    q = compat.sac_vmap_qvalue(loss)(td, params)["state_action_value"]
    assert q.shape == (2, 3, 1), "TorchRL's SACLoss._vmap_qnetworkN0 no longer stacks the critics first"
    with params[0].to_module(loss.qvalue_network):
        assert torch.allclose(q[0], loss.qvalue_network(td.clone())["state_action_value"])


def test_hook_first_steps_sees_every_sub_env_step_of_a_serial_env_then_removes_itself():
    from torchrl.envs import SerialEnv
    from torchrl.testing.mocking_classes import ContinuousActionVecMockEnv

    from morl_trl._torchrl_compat import drop_step_hook, hook_first_steps

    seen = []

    def make():
        return hook_first_steps(ContinuousActionVecMockEnv(), lambda out, step: seen.append(step), steps=2)

    env = SerialEnv(2, make)
    env.rollout(4)
    assert sorted(seen) == [1, 1, 2, 2]  # (each sub-env's first two steps, through SerialEnv's _step calls)
    hooked = make()
    assert "_step" in hooked.__dict__ and "_step" not in drop_step_hook(hooked).__dict__
