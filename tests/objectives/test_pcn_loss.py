"""PCNLoss runs its network as it is when the module holds the loss's own parameters (no swap), with
the same loss and gradients as TorchRL's swap path, and swaps whenever other tensors were put in."""

from __future__ import annotations

import torch
from tensordict import TensorDict

from morl_trl.objectives.common import module_output
from morl_trl.objectives.pcn import PCNLoss, make_pcn_network


def _batch(n=16, seed=0):
    g = torch.Generator().manual_seed(seed)
    return TensorDict({"observation": torch.randn(n, 6, generator=g), "action": torch.randint(3, (n,), generator=g),
                       "desired_return": torch.randn(n, 2, generator=g), "desired_horizon": torch.rand(n, 1, generator=g)},
                      [n])


def _swapped_loss(loss, td):
    """The reference: TorchRL's generic path (the functional parameters swapped into the module)."""
    with loss.policy_network_params.to_module(loss.policy_network, preserve_module_state=False):
        logp = module_output(loss.policy_network, td, "log_probs")
    return -logp.gather(-1, td["action"].unsqueeze(-1)).squeeze(-1).mean()


def test_direct_path_equals_the_swap_path_bit_for_bit():
    torch.manual_seed(0)
    loss = PCNLoss(make_pcn_network(6, 3, 2, [0.1, 0.2, 0.3], (8, 8, 8)))
    td = _batch()
    assert loss._module_holds_params()
    fast = loss(td)["loss_pcn"]
    fast.backward()
    grads = [p.grad.clone() for p in loss.parameters()]
    loss.zero_grad(set_to_none=True)
    ref = _swapped_loss(loss, td)
    ref.backward()
    assert torch.equal(fast, ref)
    assert len(grads) == 10 and all(torch.equal(g, p.grad) for g, p in zip(grads, loss.parameters()))


def test_loaded_state_keeps_the_direct_path_and_is_used():
    torch.manual_seed(0)
    loss = PCNLoss(make_pcn_network(6, 3, 2, [0.1, 0.2, 0.3], (8, 8)))
    td = _batch()
    before = loss(td)["loss_pcn"].item()
    state = {k: torch.zeros_like(v) if k.endswith("fc.2.weight") else v for k, v in loss.state_dict().items()}
    loss.load_state_dict(state)
    assert loss._module_holds_params()
    # the last layer's weights are zero: every action gets the same log-probability from its bias
    bias = loss.policy_network.module.fc[2].bias.detach()
    expected = -torch.log_softmax(bias, -1)[td["action"]].mean()
    assert loss(td)["loss_pcn"].item() != before
    torch.testing.assert_close(loss(td)["loss_pcn"], expected)


def test_other_tensors_in_the_parameters_are_swapped_in():
    torch.manual_seed(0)
    loss = PCNLoss(make_pcn_network(6, 3, 2, [0.1, 0.2, 0.3], (8, 8)))
    td = _batch()
    key = ("module", "fc", "2", "weight")
    loss.policy_network_params.set(key, torch.nn.Parameter(torch.zeros(3, 8)))
    assert not loss._module_holds_params()
    out = loss(td)["loss_pcn"]
    bias = loss.policy_network_params.get(("module", "fc", "2", "bias")).detach()
    torch.testing.assert_close(out, -torch.log_softmax(bias, -1)[td["action"]].mean())


def test_in_place_relu_forward_equals_the_sequential_bit_for_bit():
    """PCNNetwork.forward's in-place ReLUs give nn.Sequential's values and gradients exactly (issue 31)."""
    torch.manual_seed(0)
    net = make_pcn_network(6, 3, 2, [0.1, 0.2, 0.3], (16, 16, 16)).module
    td = _batch(32)
    obs, ret, hor = td["observation"], td["desired_return"], td["desired_horizon"]
    fast = net(obs, ret, hor)
    (fast * torch.arange(3.0)).sum().backward()
    fast_grads = [p.grad.clone() for p in net.parameters()]
    net.zero_grad(set_to_none=True)
    c = torch.cat([ret, hor], -1) * net.scaling_factor
    ref = net.fc(net.s_emb(obs) * net.c_emb(c))  # the previous formulation: nn.ReLU out of place
    (ref * torch.arange(3.0)).sum().backward()
    assert torch.equal(fast, ref) and fast.abs().sum() > 0
    assert len(fast_grads) == 10 and all(torch.equal(g, p.grad) for g, p in zip(fast_grads, net.parameters()))


def test_losses_of_equals_forward_on_the_tensordict_bit_for_bit():
    torch.manual_seed(0)
    loss = PCNLoss(make_pcn_network(6, 3, 2, [0.1, 0.2, 0.3], (8, 8, 8)))
    td = _batch()
    ref = loss(td)
    ref["loss_pcn"].backward()
    ref_grads = [p.grad.clone() for p in loss.parameters()]
    loss.zero_grad(set_to_none=True)
    fast = loss.losses_of(td["observation"], td["action"], td["desired_return"], td["desired_horizon"])
    fast["loss_pcn"].backward()
    assert sorted(fast.keys()) == ["entropy", "loss_pcn"]
    assert torch.equal(fast["loss_pcn"], ref["loss_pcn"]) and torch.equal(fast["entropy"], ref["entropy"])
    assert all(torch.equal(g, p.grad) for g, p in zip(ref_grads, loss.parameters()))
    # other tensors in the functional parameters: no direct path (the caller runs forward)
    loss.policy_network_params.set(("module", "fc", "2", "weight"), torch.nn.Parameter(torch.zeros(8, 8)))
    assert loss.losses_of(td["observation"], td["action"], td["desired_return"], td["desired_horizon"]) is None
