import pytest
import torch
from tensordict import TensorDict
from torchrl.data import Bounded, OneHot
from torch import nn
from torchrl.objectives import HardUpdate

from morl_trl.objectives import (
    EnvelopeQLoss,
    NatureCNN,
    PreferenceConditionedMLP,
    make_categorical_actor,
    make_gaussian_actor,
    make_vector_critic,
    make_vector_q_network,
)


def test_mlp_concatenates_inputs_and_keeps_leading_dims():
    torch.manual_seed(0)
    net = PreferenceConditionedMLP(5 + 2, (3, 2), num_cells=(8,))
    obs, w = torch.randn(4, 6, 5), torch.rand(4, 6, 2)
    out = net(obs, w)
    assert out.shape == (4, 6, 3, 2)
    torch.testing.assert_close(out.reshape(4, 6, 6), net.mlp(torch.cat([obs, w], -1)))
    assert [m.out_features for m in net.mlp if isinstance(m, torch.nn.Linear)] == [8, 6]


def test_default_architecture_is_four_layers_of_256():
    net = PreferenceConditionedMLP(10, 4)
    assert [m.out_features for m in net.mlp if isinstance(m, torch.nn.Linear)] == [256, 256, 256, 256, 4]


def test_nature_cnn_scales_uint8_and_accepts_leading_dims():
    torch.manual_seed(0)
    enc = NatureCNN((3, 36, 36), features_dim=16)
    pixels = torch.randint(0, 256, (2, 5, 3, 36, 36), dtype=torch.uint8)
    out = enc(pixels)
    assert out.shape == (2, 5, 16)
    torch.testing.assert_close(out, enc(pixels.float() / 255.0))
    with pytest.raises(ValueError, match=r"\(C, H, W\)"):
        NatureCNN((36, 36))


def test_builders_record_sizes_and_produce_valid_outputs():
    torch.manual_seed(0)
    td = TensorDict({"observation": torch.randn(7, 4), "preference": torch.full((7, 2), 0.5), "action": torch.rand(7, 3)}, [7])
    q = make_vector_q_network(4, 5, 2, num_cells=(8,))
    assert (q.num_objectives, q.num_actions) == (2, 5) and q(td.clone())["action_value"].shape == (7, 5, 2)
    critic = make_vector_critic(4, 3, 2, num_cells=(8,))
    assert critic.num_objectives == 2 and critic(td.clone())["state_action_value"].shape == (7, 2)
    spec = Bounded(torch.tensor([-2.0, 0.0, 1.0]), torch.tensor([2.0, 0.5, 3.0]), (3,))
    action = make_gaussian_actor(4, spec, 2, num_cells=(8,))(td.clone())["action"]
    assert spec.is_in(action)
    discrete = make_categorical_actor(4, 5, 2, num_cells=(8,))(td.clone())["action"]
    assert discrete.dtype == torch.long and discrete.shape == (7,) and ((0 <= discrete) & (discrete < 5)).all()
    one_hot = make_categorical_actor(4, 5, 2, num_cells=(8,), action_spec=OneHot(5))(td.clone())["action"]
    assert one_hot.shape == (7, 5) and (one_hot.sum(-1) == 1).all()
    unconditioned = make_vector_q_network(4, 5, 2, num_cells=(8,), preference_key=None)
    assert unconditioned.in_keys == ["observation"]


def test_envelope_on_pixels():
    torch.manual_seed(0)
    q = make_vector_q_network((3, 36, 36), 4, 2, num_cells=(16,), features_dim=32)
    loss = EnvelopeQLoss(q, num_preference_samples=2)
    HardUpdate(loss, value_network_update_interval=10)
    data = TensorDict(
        {
            "observation": torch.randint(0, 256, (3, 3, 36, 36), dtype=torch.uint8),
            "action": torch.randint(4, (3,)),
            ("next", "observation"): torch.randint(0, 256, (3, 3, 36, 36), dtype=torch.uint8),
            ("next", "reward"): torch.randn(3, 2),
            ("next", "done"): torch.zeros(3, 1, dtype=torch.bool),
            ("next", "terminated"): torch.zeros(3, 1, dtype=torch.bool),
        },
        [3],
    )
    loss(data)["loss_qvalue"].backward()
    assert all(p.grad is not None for p in loss.parameters())


def test_networks_capture_as_one_graph_under_torch_compile():
    torch.manual_seed(0)
    mlp = PreferenceConditionedMLP(6 + 2, (3, 2), num_cells=(8, 8))
    cnn_net = PreferenceConditionedMLP(16 + 2, 3, num_cells=(8,), encoder=NatureCNN((3, 36, 36), 16))
    obs, w = torch.randn(5, 6), torch.rand(5, 2)
    pixels = torch.randint(0, 256, (5, 3, 36, 36), dtype=torch.uint8)
    torch._dynamo.reset()
    torch.testing.assert_close(torch.compile(mlp, fullgraph=True, backend="eager")(obs, w), mlp(obs, w))
    torch.testing.assert_close(torch.compile(cnn_net, fullgraph=True, backend="eager")(pixels, w), cnn_net(pixels, w))


# ---------------------------------------------------------------- the authors' forms
def test_envelope_network_concatenates_w_after_the_first_hidden_layer_as_the_authors():
    from tensordict import TensorDict

    obs_dim, k, actions = 26, 4, 4
    authors = make_vector_q_network(obs_dim, actions, k, num_cells=(64, 64, 64), preference_layer=1)
    net = authors.module
    assert net.trunk[0].in_features == obs_dim  # the first layer sees the observation only
    assert net.mlp[0].in_features == 64 + k  # w joins the first hidden layer's output
    td = TensorDict({"observation": torch.randn(5, obs_dim), "preference": torch.full((5, k), 0.25)}, [5])
    assert authors(td)["action_value"].shape == (5, actions, k)
    x = td["observation"]
    manual = net.mlp(torch.cat([torch.relu(net.trunk[0](x)), td["preference"]], -1)).reshape(5, actions, k)
    torch.testing.assert_close(authors(td)["action_value"], manual)
    # ours: at the input
    ours = make_vector_q_network(obs_dim, actions, k, num_cells=(64, 64, 64))
    assert ours.module.trunk is None and ours.module.mlp[0].in_features == obs_dim + k
    # the same number of layers; after the last hidden layer is allowed, beyond is not
    assert len([m for m in net.modules() if isinstance(m, nn.Linear)]) == 4
    make_vector_q_network(obs_dim, actions, k, num_cells=(8, 8), preference_layer=2)
    with pytest.raises(ValueError, match=r"preference_layer must be an int in \[0, 2\]"):
        make_vector_q_network(obs_dim, actions, k, num_cells=(8, 8), preference_layer=3)


def test_envelope_network_orthogonal_init_gain_1_as_the_authors():
    q = make_vector_q_network(26, 4, 4, num_cells=(64, 32), preference_layer=1, init="orthogonal")
    linears = [m for m in q.modules() if isinstance(m, nn.Linear)]
    assert len(linears) == 3
    for lin in linears:
        w = lin.weight.detach()
        gram = w @ w.T if w.shape[0] <= w.shape[1] else w.T @ w  # the smaller Gram matrix is the identity
        torch.testing.assert_close(gram, torch.eye(min(w.shape)), atol=1e-5, rtol=0)
        assert torch.equal(lin.bias.detach(), torch.zeros_like(lin.bias))
    default = make_vector_q_network(26, 4, 4, num_cells=(64, 32))
    assert not all(bool((m.bias == 0).all()) for m in default.modules() if isinstance(m, nn.Linear))
    with pytest.raises(ValueError, match=r"init='xavier'; valid values are \('default', 'orthogonal'\)"):
        make_vector_q_network(26, 4, 4, init="xavier")


def test_capql_actor_log_std_clamped_to_minus20_2_as_the_authors():
    from tensordict import TensorDict
    from torchrl.data import Bounded

    actor = make_gaussian_actor(5, Bounded(-1.0, 1.0, (2,)), 3, num_cells=(16,), scale="clamped_log_std")
    head = actor.module[0].module.net.mlp[-1]  # the last Linear: [loc (2), log_std (2)]
    td = TensorDict({"observation": torch.randn(4, 5), "preference": torch.full((4, 3), 1 / 3)}, [4])
    with torch.no_grad():
        head.weight.zero_()
        head.bias.copy_(torch.tensor([0.1, -0.2, 5.0, -30.0]))  # log-std beyond both bounds
        out = actor.module[0](td.clone())
        torch.testing.assert_close(out["loc"], torch.tensor([[0.1, -0.2]] * 4))
        torch.testing.assert_close(out["scale"], torch.tensor([[2.0, -20.0]] * 4).exp().expand(4, 2))
        head.bias.copy_(torch.tensor([0.0, 0.0, -1.0, 0.5]))  # inside: exp(log_std)
        torch.testing.assert_close(actor.module[0](td.clone())["scale"], torch.tensor([[-1.0, 0.5]] * 4).exp())
    ours = make_gaussian_actor(5, Bounded(-1.0, 1.0, (2,)), 3, num_cells=(16,))
    assert type(ours.module[0].module).__name__ == "_LocScale"  # the biased softplus stays the default
    with pytest.raises(ValueError, match="scale='exp'; valid values"):
        make_gaussian_actor(5, Bounded(-1.0, 1.0, (2,)), 3, scale="exp")
