"""The losses' fast network path gives what TorchRL's generic (parameter-swapping) path gives."""

import copy

import pytest
import torch
from torchrl.data import Bounded
from torchrl.objectives import SoftUpdate

from morl_trl.objectives import CAPQLLoss, MOSACLoss, PolyakUpdate, make_gaussian_actor, make_vector_critic
from morl_trl.objectives.fast_path import FunctionalNetwork, GaussianActorPlan
from morl_trl.objectives.networks import NatureCNN, PreferenceConditionedMLP
from tests.objectives._helpers import random_batch

pytestmark = pytest.mark.filterwarnings("ignore:No target network updater")

OBS, ACT, K, B = 7, 3, 3, 16
SPEC = Bounded(-1.0, 1.0, (ACT,))


def make(cls=CAPQLLoss, scale="clamped_log_std", **kwargs):
    torch.manual_seed(0)
    loss = cls(make_gaussian_actor(OBS, SPEC, K, num_cells=(32, 32), scale=scale),
               make_vector_critic(OBS, ACT, K, num_cells=(32, 32)), **kwargs)
    loss.make_value_estimator(gamma=0.99)
    return loss


def run(loss, data, seed, steps=3):
    """``steps`` Adam updates with Polyak targets; the losses and every parameter afterwards."""
    torch.manual_seed(seed)
    opt = torch.optim.Adam(loss.parameters(), lr=1e-3)
    updater = SoftUpdate(loss, tau=0.05)
    outs = []
    for _ in range(steps):
        out = loss(data)
        opt.zero_grad()
        sum(out[k] for k in out.keys() if k.startswith("loss_")).backward()
        opt.step()
        updater.step()
        outs.append(out.detach())
    return outs, {k: v.detach().clone() for k, v in loss.state_dict().items()}


@pytest.mark.parametrize("cls, scale, kwargs", [
    (CAPQLLoss, "clamped_log_std", {}),
    (CAPQLLoss, "softplus", {"resample_preferences": True}),
    (MOSACLoss, "softplus", {"action_spec": SPEC}),
    (MOSACLoss, "softplus", {"preference": torch.tensor([0.2, 0.3, 0.5]), "action_spec": SPEC}),
], ids=["capql", "capql-softplus-resampled", "mosac-learned-alpha", "mosac-fixed-preference"])
def test_fast_path_is_bit_identical_to_the_generic_path(cls, scale, kwargs):
    fast, generic = make(cls, scale, **kwargs), make(cls, scale, **kwargs)
    generic.fast_networks = False
    assert fast._fast_plans() is not None and generic._fast_plans() is None
    data = random_batch(B, OBS, K, action_dim=ACT)
    outs_f, params_f = run(fast, data.clone(), seed=3)
    outs_g, params_g = run(generic, data.clone(), seed=3)
    for a, b in zip(outs_f, outs_g):
        for key in a.keys():
            assert torch.equal(a[key], b[key]), key
    assert params_f.keys() == params_g.keys()
    for key in params_f:
        assert torch.equal(params_f[key], params_g[key]), key
    assert not torch.equal(params_f["actor_network_params.module.0.module.net.mlp.0.weight"],
                           make(cls, scale, **kwargs).state_dict()["actor_network_params.module.0.module.net.mlp.0.weight"])


def test_fast_path_writes_the_same_priority():
    fast, generic = make(), make()
    generic.fast_networks = False
    data_f, data_g = random_batch(B, OBS, K, action_dim=ACT), random_batch(B, OBS, K, action_dim=ACT)
    torch.manual_seed(1)
    fast(data_f)
    torch.manual_seed(1)
    generic(data_g)
    assert torch.equal(data_f["td_error"], data_g["td_error"]) and data_f["td_error"].shape == (B,)


def test_vmapped_fast_ensemble_matches_the_loop():
    loss = make()
    data = random_batch(B, OBS, K, action_dim=ACT)
    outs = {}
    for mode in ("loop", "vmap"):
        loss.critic_ensemble_mode = mode
        torch.manual_seed(2)
        outs[mode] = loss(data.clone())
    for key in ("loss_qvalue", "loss_actor"):
        torch.testing.assert_close(outs["loop"][key], outs["vmap"][key], rtol=1e-5, atol=1e-6)


def test_other_networks_take_the_generic_path():
    loss = make()
    cnn = copy.deepcopy(loss.qvalue_network)
    cnn.module.encoder = NatureCNN((3, 36, 36), 8)
    assert FunctionalNetwork.of(cnn, loss.qvalue_network_params) is None  # an encoder in front
    custom = copy.deepcopy(loss.qvalue_network)
    custom.module = torch.nn.Linear(OBS + ACT + K, K)
    assert FunctionalNetwork.of(custom, loss.qvalue_network_params) is None  # not our MLP
    assert GaussianActorPlan.of(loss.qvalue_network, loss.actor_network_params) is None  # not an actor


def test_forward_with_rejects_an_encoder():
    net = PreferenceConditionedMLP(8 + 2, 3, num_cells=(8,), encoder=torch.nn.Identity())
    net.encoder = NatureCNN((3, 36, 36), 8)
    with pytest.raises(ValueError, match="without encoder"):
        net.forward_with([p.detach() for p in net.parameters()], torch.zeros(1, 3, 36, 36), torch.zeros(1, 2))


def test_polyak_update_is_bit_identical_to_soft_update():
    ours, torchrl_ = make(), make()
    a, b = PolyakUpdate(ours, tau=0.005), SoftUpdate(torchrl_, tau=0.005)  # targets := online
    for loss in (ours, torchrl_):  # then move the online critics away from the targets
        for p in loss.qvalue_network_params.values(True, True):
            p.data.add_(torch.randn(p.shape, generator=torch.Generator().manual_seed(p.numel())))
    start = ours.target_qvalue_network_params.clone()
    for _ in range(3):
        a.step()
        b.step()
    for key, value in ours.target_qvalue_network_params.items(True, True):
        assert torch.equal(value, torchrl_.target_qvalue_network_params.get(key)), key
        assert not torch.equal(value, start.get(key)), key
    assert not any(t.requires_grad for t in a.leaves()[1])


def test_the_critic_loop_unbinds_the_ensemble_exactly_as_selecting_each_member():
    """Issue 31: the CPU critic loop takes the members with one ``unbind`` per leaf (its backward stacks the
    members' gradients) instead of ``leaf[i]`` (each scattered into a zero-filled ensemble, then summed):
    the same values and the same gradients, bit for bit."""
    loss = make()
    critic = loss._fast_plans()[1]
    torch.manual_seed(1)
    x, a, w = torch.randn(B, OBS), torch.rand(B, ACT) * 2 - 1, torch.softmax(torch.randn(B, K), -1)
    leaves = critic.leaves(loss.qvalue_network_params)
    assert loss._ensemble_mode(leaves[0].device) == "loop" and leaves[0].shape[0] == 2
    weights = torch.arange(1.0, 1.0 + 2 * K).reshape(2, 1, K)

    def grads(q):
        (q * weights).sum().backward()
        out = [leaf.grad.clone() for leaf in leaves]
        for leaf in leaves:
            leaf.grad = None
        return out

    fast = loss._fast_critics(critic, leaves, [x, a, w])
    fast_grads = grads(fast)
    ref = torch.stack([critic([leaf[i] for leaf in leaves], [x, a, w]) for i in range(2)])  # the former loop
    ref_grads = grads(ref)
    assert torch.equal(fast, ref) and fast.shape == (2, B, K)
    assert all(torch.equal(f, r) and f.abs().sum() > 0 for f, r in zip(fast_grads, ref_grads))


@pytest.mark.parametrize("preference_layer", [0, 1])
def test_envelope_fast_path_is_bit_identical_to_the_generic_path(preference_layer):
    """EnvelopeQLoss evaluates its Q-network (online, detached online, target) from the parameter
    leaves: the same losses, priorities and parameters after Adam and hard target updates."""
    from torchrl.objectives import HardUpdate

    from morl_trl.objectives import EnvelopeQLoss, make_vector_q_network

    def envelope():
        torch.manual_seed(0)
        q = make_vector_q_network(OBS, 4, K, num_cells=(32, 32), preference_layer=preference_layer)
        loss = EnvelopeQLoss(q, num_preference_samples=4, homotopy_lambda=0.3)
        loss.make_value_estimator(gamma=0.99)
        return loss

    fast, generic = envelope(), envelope()
    generic.fast_networks = False
    assert fast._fast_plan() is not None and generic._fast_plan() is None
    data = random_batch(B, OBS, K, num_actions=4)
    results = []
    for loss in (fast, generic):
        torch.manual_seed(3)
        opt = torch.optim.Adam(loss.parameters(), lr=1e-2)
        updater = HardUpdate(loss, value_network_update_interval=2)
        outs, priorities = [], []
        for _ in range(4):
            batch = data.clone()
            out = loss(batch)
            opt.zero_grad()
            out["loss_qvalue"].backward()
            opt.step()
            updater.step()
            outs.append(out.detach())
            priorities.append(batch["td_error"])
        results.append((outs, priorities, {k: v.detach().clone() for k, v in loss.state_dict().items()}))
    (outs_f, prio_f, params_f), (outs_g, prio_g, params_g) = results
    for a, b in zip(outs_f, outs_g):
        for key in a.keys():
            assert torch.equal(a[key], b[key]), key
    assert all(torch.equal(a, b) for a, b in zip(prio_f, prio_g))
    assert params_f.keys() == params_g.keys() and all(torch.equal(params_f[k], params_g[k]) for k in params_f)
    assert not torch.equal(params_f["target_value_network_params.module.mlp.0.weight"],
                           envelope().state_dict()["target_value_network_params.module.mlp.0.weight"])
