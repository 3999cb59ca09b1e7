"""The one batched linear / layer norm / MLP (``morl_trl.objectives.batched``): member by member what
``nn.Linear`` / ``nn.LayerNorm`` compute, the initialisations the populations and ensembles used
before (same random draws), and the fast GPI block equal to the plain composition it replaces."""

import copy
import math

import pytest
import torch
from tensordict import TensorDict
from torch import nn
from torch.nn import functional as F

from morl_trl.objectives import GPILoss, GPIQNetwork
from morl_trl.objectives.batched import (
    BatchedLayerNorm,
    BatchedLinear,
    BatchedMLP,
    batched_dropout,
    dropped_positions,
    linear_dropout_norm_relu,
)


def test_linear_is_per_member_linear_with_concrete_values():
    lin = BatchedLinear(2, 2, 3)
    with torch.no_grad():
        lin.weight.copy_(torch.tensor([[[1.0, 0.0, 2.0], [0.0, 1.0, -1.0]],     # member 0: [in=2, out=3]
                                       [[0.5, 0.5, 0.5], [1.0, -1.0, 0.0]]]))   # member 1
        lin.bias.copy_(torch.tensor([[[0.0, 0.0, 1.0]], [[1.0, 2.0, 3.0]]]))
    x = torch.tensor([[[1.0, 2.0]], [[2.0, 4.0]]])  # [E=2, B=1, in=2]
    assert lin(x).tolist() == [[[1.0, 2.0, 1.0]], [[6.0, -1.0, 4.0]]]
    assert lin(x.reshape(2, 2)).tolist() == [[1.0, 2.0, 1.0], [6.0, -1.0, 4.0]]  # member-major rows
    for e in range(2):  # the reference: member e as nn.Linear
        torch.testing.assert_close(lin(x)[e], lin.member_linear(e)(x[e]), rtol=0, atol=0)
    assert lin(x[1:], members=slice(1, 2)).tolist() == [[[6.0, -1.0, 4.0]]]


def test_linear_matches_nn_linear_on_random_inputs_and_gradients():
    torch.manual_seed(0)
    lin = BatchedLinear(3, 5, 4, init="torch")
    refs = [lin.member_linear(e) for e in range(3)]
    x = torch.randn(3, 6, 2, 5)
    out = lin(x)
    torch.testing.assert_close(out, torch.stack([refs[e](x[e]) for e in range(3)]), rtol=1e-6, atol=1e-6)
    out.pow(2).sum().backward()
    for e in range(3):
        refs[e](x[e]).pow(2).sum().backward()
        torch.testing.assert_close(lin.weight.grad[e], refs[e].weight.grad.T, rtol=1e-5, atol=1e-5)
        torch.testing.assert_close(lin.bias.grad[e, 0], refs[e].bias.grad, rtol=1e-5, atol=1e-5)


def test_orthogonal_init_draws_as_the_ensembles_and_populations_did():
    """Each member's [out, in] matrix drawn in member order (EnsembleLinear's, PGMORL's PopulationMLP's)."""
    torch.manual_seed(3)
    lin = BatchedLinear(2, 4, 3, gain=math.sqrt(2))
    torch.manual_seed(3)
    ref = [nn.init.orthogonal_(torch.empty(3, 4), math.sqrt(2)) for _ in range(2)]
    assert torch.equal(lin.weight, torch.stack(ref).transpose(1, 2))
    assert not lin.bias.any()
    w = lin.weight[1]
    torch.testing.assert_close(w.T @ w, 2 * torch.eye(3), rtol=0, atol=1e-5)


def test_torch_init_draws_as_morld_population_linear_did():
    """Every member's kaiming-uniform [out, in] weight, then all the biases (MORL/D's PopulationLinear)."""
    torch.manual_seed(4)
    lin = BatchedLinear(3, 5, 2, init="torch")
    torch.manual_seed(4)
    ref = []
    for _ in range(3):
        w = torch.empty(2, 5)
        nn.init.kaiming_uniform_(w, a=math.sqrt(5))
        ref.append(w)
    bias = torch.empty(3, 2).uniform_(-1 / math.sqrt(5), 1 / math.sqrt(5))
    assert torch.equal(lin.weight, torch.stack(ref).transpose(1, 2))
    assert torch.equal(lin.bias, bias.unsqueeze(1))
    with pytest.raises(ValueError, match="init='xavier'; valid"):
        BatchedLinear(1, 2, 2, init="xavier")


def test_linear_takes_member_major_rows_in_any_leading_shape():
    """``[E * N, B, in]`` (a population's sub-envs x steps, member-major) is member e's rows e*N..(e+1)*N-1."""
    torch.manual_seed(12)
    lin = BatchedLinear(2, 3, 4)
    x = torch.randn(6, 5, 3)  # 2 members x 3 sub-envs, 5 steps
    out = lin(x)
    assert out.shape == (6, 5, 4)
    for e in range(2):
        torch.testing.assert_close(out[3 * e: 3 * e + 3], lin.member_linear(e)(x[3 * e: 3 * e + 3]), rtol=1e-6, atol=1e-6)


def test_layer_norm_is_per_member_layer_norm():
    torch.manual_seed(1)
    norm = BatchedLayerNorm(2, 4)
    with torch.no_grad():
        norm.weight.uniform_(0.5, 1.5)
        norm.bias.normal_()
    x = torch.randn(2, 3, 4)
    for e in range(2):
        ref = nn.LayerNorm(4)
        with torch.no_grad():
            ref.weight.copy_(norm.weight[e, 0])
            ref.bias.copy_(norm.bias[e, 0])
        torch.testing.assert_close(norm(x)[e], ref(x[e]), rtol=1e-6, atol=1e-6)
    x = torch.tensor([[[1.0, 3.0]], [[0.0, 0.0]]])
    assert torch.allclose(BatchedLayerNorm(2, 2)(x), torch.tensor([[[-1.0, 1.0]], [[0.0, 0.0]]]), atol=1e-4)


def _reference_mask(h, p):
    """The dropout mask the fast code draws on the CPU (the same positions), built plainly: ones, zeros at
    :func:`dropped_positions`, times ``1 / (1 - p)``."""
    keep = torch.ones(h.numel() + 1)
    keep[dropped_positions(h.numel(), p)] = 0.0
    return keep[:-1].reshape(h.shape) * (1.0 / (1.0 - p))


def _reference_block(x, lin, norm, p, training):
    """The GPI block as the networks computed it before (the plain composition, out of place)."""
    h = lin(x)
    if training and p > 0:
        h = h * _reference_mask(h, p)
    h = F.layer_norm(h, h.shape[-1:], eps=norm.eps) * norm.weight + norm.bias
    return F.relu(h)


@pytest.mark.parametrize("grad", [True, False])
def test_fast_block_equals_the_plain_composition(grad):
    torch.manual_seed(2)
    lin, norm = BatchedLinear(2, 6, 8), BatchedLayerNorm(2, 8)
    with torch.no_grad():
        norm.weight.uniform_(0.5, 1.5)
        norm.bias.normal_()
    x = torch.randn(2, 50, 6)
    with torch.set_grad_enabled(grad):
        torch.manual_seed(9)
        fast = linear_dropout_norm_relu(x, lin, norm, 0.2, True)
        torch.manual_seed(9)
        ref = _reference_block(x, lin, norm, 0.2, True)
    assert torch.equal(fast, ref)
    assert (fast == 0).float().mean() > 0.2  # (dropout and ReLU zeroed some)
    if grad:
        grads = torch.autograd.grad(fast.pow(2).sum(), [lin.weight, lin.bias, norm.weight, norm.bias])
        refs = torch.autograd.grad(ref.pow(2).sum(), [lin.weight, lin.bias, norm.weight, norm.bias])
        for g, r in zip(grads, refs):
            assert torch.equal(g, r)


def test_dropout_masks_and_values():
    torch.manual_seed(5)
    x = torch.arange(1.0, 9.0)
    y = batched_dropout(x, 0.5, True)
    torch.manual_seed(5)
    keep = torch.ones(9).index_fill_(0, dropped_positions(8, 0.5), 0.0)[:8].bool()
    assert y.tolist() == torch.where(keep, x * 2, 0.0).tolist()
    assert 0 < int(keep.sum()) < 8
    with torch.no_grad():  # in place on a fresh mask: the same values
        torch.manual_seed(5)
        assert batched_dropout(x, 0.5, True).tolist() == y.tolist()
    assert batched_dropout(x, 0.5, False) is x


def test_dropped_positions_are_the_cumulative_geometric_gaps():
    """The stream: drop j sits at G_1 + ... + G_j - 1 with G_i torch's geometric draws (in chunks); positions
    past the end are returned as n."""
    torch.manual_seed(3)
    pos = dropped_positions(1000, 0.05)
    torch.manual_seed(3)
    gaps = torch.empty(len(pos), dtype=torch.float64).geometric_(0.05)
    want = (gaps.cumsum(0) - 1).clamp(max=1000).long()
    assert torch.equal(pos, want)
    assert int(pos[-1]) == 1000 and int(pos[0]) == int(gaps[0]) - 1
    # drawn in chunks of 3 gaps (the loop that runs when n p + 6 sigma gaps do not reach n): the same drops
    torch.manual_seed(3)
    small = dropped_positions(1000, 0.05, chunk=3)
    assert torch.equal(small[small < 1000], pos[pos < 1000]) and int(small[-1]) == 1000


@pytest.mark.parametrize("p", [0.01, 0.5])
def test_dropped_positions_are_independent_bernoulli(p):
    """Every position dropped with probability p, independently of its neighbour (pairs dropped at p^2)."""
    torch.manual_seed(7)
    n = 400_000
    dropped = torch.zeros(n + 1).index_fill_(0, dropped_positions(n, p), 1.0)[:n]
    sigma = math.sqrt(p * (1 - p) / n)
    assert abs(float(dropped.mean()) - p) < 5 * sigma
    both = float((dropped[:-1] * dropped[1:]).mean())
    assert abs(both - p * p) < 5 * math.sqrt(p * p * (1 - p * p) / n)
    blocks = dropped.reshape(400, 1000).sum(1)  # counts in disjoint blocks: binomial(1000, p) variance
    assert 0.7 < float(blocks.var()) / (1000 * p * (1 - p)) < 1.3


def test_mlp_member_is_a_plain_mlp():
    torch.manual_seed(6)
    net = BatchedMLP(3, 4, (2, 2), num_cells=(5,), activation=nn.Tanh, init="orthogonal", gain=math.sqrt(2),
                     out_gain=0.01)
    x = torch.randn(3, 7, 4)
    for e in range(3):
        ref = nn.Sequential(net.mlp[0].member_linear(e), nn.Tanh(), net.mlp[2].member_linear(e))
        torch.testing.assert_close(net(x)[e], ref(x[e]).reshape(7, 2, 2), rtol=1e-6, atol=1e-6)
    assert net(x.reshape(21, 4)).shape == (21, 2, 2)
    a, b = torch.randn(3, 7, 1), torch.randn(3, 7, 3)
    assert torch.equal(net(a, b), net(torch.cat([a, b], -1)))
    net.load_member_state(2, net.member_state(0))
    assert torch.equal(net(x[:1].expand(3, 7, 4))[2], net(x[:1].expand(3, 7, 4))[0])


class _ReferenceGPIQNetwork(GPIQNetwork):
    """GPIQNetwork's forward as written before the fast block (the plain composition); the loss runs it
    (not :meth:`GPIQNetwork.forward_with`), on every row it computes (no first-rows-only GPI target)."""

    supports_forward_with = False

    def forward(self, observation, preference, members=None):
        lead = preference.shape[:-1]
        e = self.num_nets if members is None else len(range(self.num_nets)[members])
        s = observation.reshape(1, -1, observation.shape[-1]).expand(e, -1, -1)
        w = preference.reshape(1, -1, preference.shape[-1]).expand(e, -1, -1)
        x = F.relu(self.state_features(s, members)) * F.relu(self.weight_features(w, members))
        for i, layer in enumerate(self.hidden):
            h = layer(x, members)
            if self.training:
                h = h * _reference_mask(h, self.dropout)
            norm = self.norms[i]
            nw, nb = (norm.weight, norm.bias) if members is None else (norm.weight[members], norm.bias[members])
            x = F.relu(F.layer_norm(h, h.shape[-1:]) * nw + nb)
        return self.out(x, members).reshape(e, *lead, self.num_actions, self.num_objectives)


def test_gpi_pd_update_equals_the_reference_update():
    """One GPI-PD update (targets, GPI target, loss, backward, Adam) with the fast network and with the
    plain one from the same state and seed: the same parameters."""
    torch.manual_seed(0)
    fast = GPIQNetwork(6, 3, 2, hidden=(16, 16, 16), dropout=0.1)
    slow = _ReferenceGPIQNetwork(6, 3, 2, hidden=(16, 16, 16), dropout=0.1)
    slow.load_state_dict(fast.state_dict())
    B = 32
    data = TensorDict({"observation": torch.randn(B, 6), "action": torch.randint(3, (B,)),
                       ("next", "observation"): torch.randn(B, 6), ("next", "reward"): torch.randn(B, 2),
                       ("next", "done"): torch.zeros(B, 1, dtype=torch.bool),
                       ("next", "terminated"): torch.zeros(B, 1, dtype=torch.bool)}, [B])
    support = torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5], [0.2, 0.8], [0.7, 0.3], [0.9, 0.1]])
    params, priorities = [], []
    for net in (fast, slow):
        loss = GPILoss(net, gpi_pd=True)
        loss.make_value_estimator(gamma=0.99)
        loss.set_weights(torch.tensor([0.3, 0.7]), support)
        opt = torch.optim.Adam(loss.parameters(), lr=1e-2)
        torch.manual_seed(11)
        for _ in range(2):
            batch = data.clone()
            out = loss(batch)
            opt.zero_grad()
            out["loss_qvalue"].backward()
            opt.step()
        params.append(copy.deepcopy(loss.value_network_params.data))
        priorities.append(batch["td_error"])
    for key, value in params[0].items(True, True):
        assert torch.equal(value, params[1][key]), key
    assert torch.equal(priorities[0], priorities[1])


def test_gpi_target_of_the_first_rows_is_the_whole_ones_first_rows():
    """GPI-PD's GPI target computed for the real batch's rows alone (what the priorities read) equals those
    rows of the target over the whole doubled batch, dropout included (the same draws), and leaves the
    generator where the whole run leaves it."""
    torch.manual_seed(4)
    loss = GPILoss(GPIQNetwork(6, 3, 2, hidden=(16, 16, 16), dropout=0.2), gpi_pd=True)
    next_obs, w = torch.randn(20, 6), torch.softmax(torch.randn(20, 2), -1)
    sampled = torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]])
    torch.manual_seed(8)
    whole = loss.gpi_target_value(next_obs, w, sampled)
    after_whole = torch.rand(3)
    torch.manual_seed(8)
    first = loss.gpi_target_value(next_obs, w, sampled, rows=7)
    assert first.shape == (7, 2) and torch.equal(first, whole[:7])
    assert torch.equal(torch.rand(3), after_whole)
    loss.value_network.module.eval()  # without dropout too
    assert torch.equal(loss.gpi_target_value(next_obs, w, sampled, rows=7), loss.gpi_target_value(next_obs, w, sampled)[:7])


def test_argmin_along_is_argmin_on_ties_and_nans():
    """argmin_along (the critic / member with the lowest w . Q) reads torch.min's indices: argmin's index
    exactly, the first of tied minima and a NaN's position, over a leading or a trailing dim."""
    from morl_trl.objectives.common import argmin_along

    g = torch.Generator().manual_seed(0)
    x = torch.randint(0, 3, (3, 64, 4), generator=g).float()  # many ties
    x.view(-1)[::17] = float("nan")
    for dim in (0, 1, -1):
        for keepdim in (False, True):
            assert torch.equal(argmin_along(x, dim, keepdim), x.argmin(dim, keepdim=keepdim))
    assert argmin_along(torch.tensor([[2.0, 1.0], [1.0, 1.0]]), 0).tolist() == [1, 0]
