"""LeanSequential computes what TensorDictSequential computes: same entries, same random draws."""

from __future__ import annotations

import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.data import Categorical, Composite
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import EGreedyModule

from morl_trl.objectives import GPIPolicy, GPIQNetwork, LeanSequential, MOQValueModule, make_vector_q_network


def _obs(g, n=3):
    return TensorDict(observation=torch.randn(n, 4, generator=g), preference=torch.rand(n, 2, generator=g),
                      batch_size=[n])


def _egreedy(n=3):
    spec = Composite(action=Categorical(5, shape=(n,)), shape=(n,))
    return EGreedyModule(spec, eps_init=0.5, eps_end=0.5, annealing_num_steps=1)


def test_lean_sequential_is_tensordict_sequential_for_epsilon_greedy_policies():
    torch.manual_seed(0)
    qnet = make_vector_q_network(4, num_actions=5, num_objectives=2, num_cells=(8, 8))
    gpi_net = GPIQNetwork(4, 5, 2, hidden=(8,), num_nets=2, dropout=0.1, layer_norm=True)
    egreedy = _egreedy()
    pairs = [
        (TensorDictSequential(TensorDictSequential(qnet, MOQValueModule()), egreedy),
         LeanSequential(LeanSequential(qnet, MOQValueModule()), egreedy)),
        (TensorDictSequential(GPIPolicy(gpi_net, include_preference=True), egreedy),
         LeanSequential(GPIPolicy(gpi_net, include_preference=True), egreedy)),
    ]
    g = torch.Generator().manual_seed(1)
    explored = 0
    for reference, lean in pairs:
        assert lean.lean_call_applies()
        for step in range(30):
            td = _obs(g)
            with set_exploration_type(ExplorationType.RANDOM):
                torch.manual_seed(step)
                expected = reference(td.clone())
                state = torch.get_rng_state()
                torch.manual_seed(step)
                got = lean(td.clone())
            assert torch.equal(torch.get_rng_state(), state)  # (the same draws, in number and order)
            assert sorted(map(str, got.keys(True, True))) == sorted(map(str, expected.keys(True, True)))
            assert (got == expected).all(), step
            greedy = reference[0](td.clone())["action"]
            explored += int((got["action"] != greedy).sum())
    assert explored > 20  # (ε = 0.5: the random draws were part of what was compared)


def test_lean_sequential_takes_tensordict_path_when_asked_for_more():
    calls = []
    double = TensorDictModule(lambda x: 2 * x, in_keys=["x"], out_keys=["y"])
    seq = LeanSequential(double, TensorDictModule(lambda y: y + 1, in_keys=["y"], out_keys=["z"]))
    td = TensorDict(x=torch.ones(2), batch_size=[2])
    assert seq.lean_call_applies()
    handle = seq.register_forward_hook(lambda *args: calls.append(1))
    assert not seq.lean_call_applies()
    assert torch.equal(seq(td)["z"], torch.full((2,), 3.0)) and calls == [1]  # (the hook ran: TorchRL's call)
    handle.remove()
    out = seq(td, tensordict_out=TensorDict(batch_size=[2]))  # (an output tensordict: TensorDict's path)
    assert torch.equal(out["z"], torch.full((2,), 3.0)) and "x" not in out.keys()
    assert torch.equal(seq(TensorDict(x=torch.zeros(2), batch_size=[2]))["z"], torch.ones(2))
