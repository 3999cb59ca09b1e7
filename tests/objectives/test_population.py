"""The batched MORL/D population: one update equals P separate MOSAC updates from the same state."""

import pytest
import torch
import torch.distributions.normal as normal_mod
from tensordict import TensorDict
from torchrl.data import Bounded
from torchrl.objectives import HardUpdate, SoftUpdate

from morl_trl.objectives import (
    DiscreteMOSACLoss,
    MOSACLoss,
    make_categorical_actor,
    make_gaussian_actor,
    make_vector_critic,
    make_vector_q_network,
)
from morl_trl.objectives.population import (
    PopulationMOSACLoss,
    make_population_categorical_actor,
    make_population_critic,
    make_population_gaussian_actor,
    make_population_q_network,
    nearest_member,
    population_policies,
)

P, B, OBS, K = 3, 8, 5, 2
W = torch.tensor([[1.0, 0.0], [0.3, 0.7], [0.0, 1.0]])


@pytest.fixture
def fixed_noise(monkeypatch):
    """Reparameterised Gaussian noise that depends only on (sample, action dim): the same per
    member whether a member samples alone ([B, d]) or within the population ([P, B, d])."""
    def noise(shape, dtype, device):
        b, d = shape[-2], shape[-1]
        grid = torch.arange(b, dtype=dtype, device=device).view(b, 1) * 7 + torch.arange(d, dtype=dtype, device=device)
        return torch.sin(grid).expand(shape).clone()

    monkeypatch.setattr(normal_mod, "_standard_normal", noise)


def _batch(action):
    g = torch.Generator().manual_seed(3)
    return TensorDict({
        "observation": torch.randn(P, B, OBS, generator=g), "action": action,
        ("next", "observation"): torch.randn(P, B, OBS, generator=g),
        ("next", "reward"): torch.randn(P, B, K, generator=g),
        ("next", "done"): torch.rand(P, B, 1, generator=g) < 0.2,
        ("next", "terminated"): torch.zeros(P, B, 1, dtype=torch.bool)}, [P, B])


def _opts(loss):
    return [torch.optim.Adam(loss.actor_network_params.values(True, True), lr=1e-2),
            torch.optim.Adam(loss.qvalue_network_params.values(True, True), lr=1e-2),
            torch.optim.Adam([loss.log_alpha], lr=1e-2)]


def _step(loss, data, opts, updater):
    out = loss(data)
    for o in opts:
        o.zero_grad()
    (out["loss_actor"] + out["loss_qvalue"] + out["loss_alpha"]).backward()
    for o in opts:
        o.step()
    updater.step()
    return out


def _check_equal_after_update(singles, pop, data, make_updater):
    for s in singles:
        s.make_value_estimator(gamma=0.9)
    pop.make_value_estimator(gamma=0.9)
    pop.load_members(singles)
    outs = [_step(s, data[p], _opts(s), make_updater(s)) for p, s in enumerate(singles)]
    out = _step(pop, data.clone(), _opts(pop), make_updater(pop))
    for key in ("loss_actor", "loss_qvalue", "loss_alpha"):
        torch.testing.assert_close(out[key], sum(o[key] for o in outs), rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(out["alpha"], torch.stack([o["alpha"] for o in outs]))
    for name, dim in (("actor_network_params", 0), ("qvalue_network_params", 1), ("target_qvalue_network_params", 1)):
        for key, value in getattr(pop, name).items(True, True):
            expected = torch.stack([getattr(s, name).get(key) for s in singles], dim)
            # nn.Linear's [out, in] weight and [out] bias are BatchedLinear's [in, out] and [1, out]
            expected = expected.transpose(-1, -2) if key[-1] == "weight" else expected.unsqueeze(-2)
            torch.testing.assert_close(value.data, expected.data, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(pop.log_alpha.data, torch.stack([s.log_alpha.data for s in singles]))


def test_continuous_population_update_equals_separate_mosac_updates(fixed_noise):
    torch.manual_seed(0)
    spec = Bounded(-1.0, 1.0, (2,))
    singles = [MOSACLoss(make_gaussian_actor(OBS, spec, K, num_cells=(16, 16), preference_key=None),
                         make_vector_critic(OBS, 2, K, num_cells=(16, 16), preference_key=None),
                         num_objectives=K, preference=W[p], alpha_init=0.5, action_spec=spec) for p in range(P)]
    pop = PopulationMOSACLoss(make_population_gaussian_actor(P, OBS, spec, num_cells=(16, 16)),
                              make_population_critic(P, OBS, 2, K, num_cells=(16, 16)), weights=W, alpha_init=0.5,
                              action_spec=spec)
    action = torch.rand(P, B, 2, generator=torch.Generator().manual_seed(1)) * 2 - 1
    _check_equal_after_update(singles, pop, _batch(action), lambda l: SoftUpdate(l, tau=0.05))


def test_discrete_population_update_equals_separate_discrete_mosac_updates():
    torch.manual_seed(0)
    singles = [DiscreteMOSACLoss(make_categorical_actor(OBS, 3, K, num_cells=(16,), preference_key=None),
                                 make_vector_q_network(OBS, 3, K, num_cells=(16,), preference_key=None),
                                 num_objectives=K, preference=W[p], alpha_init=0.5, target_entropy_weight=0.3)
               for p in range(P)]
    pop = PopulationMOSACLoss(make_population_categorical_actor(P, OBS, 3, num_cells=(16,)),
                              make_population_q_network(P, OBS, 3, K, num_cells=(16,)), weights=W, num_actions=3,
                              alpha_init=0.5, target_entropy_weight=0.3)
    assert pop.target_entropy.item() == pytest.approx(0.3 * torch.log(torch.tensor(3.0)).item())
    action = torch.randint(3, (P, B), generator=torch.Generator().manual_seed(1))
    _check_equal_after_update(singles, pop, _batch(action),
                              lambda l: HardUpdate(l, value_network_update_interval=1))


def test_policies_route_sub_envs_and_preferences_to_members():
    torch.manual_seed(0)
    actor = make_population_categorical_actor(P, OBS, 3, num_cells=(8,))
    net = actor.module[0].module
    with torch.no_grad():  # member p always prefers action p
        for lin in (net.mlp[0], net.mlp[2]):
            lin.weight.zero_()
            lin.bias.zero_()
        net.mlp[2].bias.copy_((torch.eye(3) * 50).unsqueeze(1))  # bias [P, 1, out]
    weights = W.clone()
    explore, evaluate = population_policies(actor, weights)
    td = TensorDict({"observation": torch.randn(P * 2, OBS)}, [P * 2])
    assert explore(td)["action"].tolist() == [0, 0, 1, 1, 2, 2]
    pref = torch.tensor([[0.9, 0.1], [0.4, 0.6], [0.1, 0.9], [0.5, 0.5]])
    td = TensorDict({"observation": torch.randn(4, OBS), "preference": pref}, [4])
    assert evaluate(td)["action"].tolist() == [0, 1, 2, 1]
    weights.copy_(torch.tensor([[0.0, 1.0], [0.3, 0.7], [1.0, 0.0]]))  # adapted weights are seen at once
    assert evaluate(td)["action"].tolist() == [2, 1, 0, 1]
    assert nearest_member(pref, weights).tolist() == [2, 1, 0, 1]


def test_bad_batch_and_weights_raise():
    spec = Bounded(-1.0, 1.0, (2,))
    with pytest.raises(ValueError, match="simplex|weights"):
        PopulationMOSACLoss(make_population_gaussian_actor(P, OBS, spec, num_cells=(8,)),
                            make_population_critic(P, OBS, 2, K, num_cells=(8,)), weights=W * 2)
    pop = PopulationMOSACLoss(make_population_gaussian_actor(P, OBS, spec, num_cells=(8,)),
                              make_population_critic(P, OBS, 2, K, num_cells=(8,)), weights=W)
    with pytest.raises(ValueError, match=r"\[P, B\] batch with P = 3"):
        pop(_batch(torch.zeros(P, B, 2))[:2])
    with pytest.raises(ValueError, match="shape"):
        pop.set_weights(W[:2])


def test_population_gaussian_head_is_the_single_actors():
    spec = Bounded(-1.0, 1.0, (2,))
    for scale, name in (("softplus", "_LocScale"), ("clamped_log_std", "_LocClampedLogStd"),
                        ("tanh_log_std", "_LocTanhLogStd")):
        actor = make_population_gaussian_actor(P, OBS, spec, num_cells=(8,), scale=scale)
        assert type(actor.module[0].module).__name__ == name
    with pytest.raises(ValueError, match=r"scale='exp'; valid values are \('softplus', 'clamped_log_std', 'tanh_log_std'\)"):
        make_population_gaussian_actor(P, OBS, spec, scale="exp")
    with pytest.raises(ValueError, match="log_std_bounds must be"):
        make_population_gaussian_actor(P, OBS, spec, scale="clamped_log_std", log_std_bounds=(2.0, -20.0))
