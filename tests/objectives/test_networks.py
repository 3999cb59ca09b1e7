import pytest
import torch
from tensordict import TensorDict
from torchrl.data import Bounded, OneHot
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
