import pytest
import torch
from tensordict import TensorDict
from torchrl.data import Bounded
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.objectives import SACLoss, SoftUpdate, ValueEstimators

from morl_trl.objectives import (
    DiscreteMOSACLoss,
    MOSACLoss,
    make_categorical_actor,
    make_gaussian_actor,
    make_vector_critic,
    make_vector_q_network,
)
from tests.objectives._helpers import (
    EXTREME_PREFERENCES,
    START,
    continuous_bandit_dataset,
    grads_of,
    random_batch,
    two_step_dataset,
    zero_grads,
)

pytestmark = pytest.mark.filterwarnings("ignore:No target network updater")

OBS, ACT, NA, K, B = 5, 2, 4, 3, 12
SPEC = Bounded(-1.0, 1.0, (ACT,))


def continuous_loss(k=K, **kwargs):
    torch.manual_seed(0)
    actor = make_gaussian_actor(OBS, SPEC, k, num_cells=(32,))
    critic = make_vector_critic(OBS, ACT, k, num_cells=(32,))
    loss = MOSACLoss(actor, critic, **kwargs)
    loss.make_value_estimator(gamma=0.9)
    return loss


def discrete_loss(k=K, **kwargs):
    torch.manual_seed(0)
    actor = make_categorical_actor(OBS, NA, k, num_cells=(32,))
    critic = make_vector_q_network(OBS, NA, k, num_cells=(32,))
    loss = DiscreteMOSACLoss(actor, critic, **kwargs)
    loss.make_value_estimator(gamma=0.9)
    return loss


def batch_for(loss, **kwargs):
    if isinstance(loss, DiscreteMOSACLoss):
        return random_batch(B, OBS, loss.num_objectives, num_actions=NA, **kwargs)
    return random_batch(B, OBS, loss.num_objectives, action_dim=ACT, **kwargs)


LOSSES = [
    pytest.param(lambda **kw: continuous_loss(**kw), id="continuous"),
    pytest.param(lambda **kw: discrete_loss(**kw), id="discrete"),
]


@pytest.mark.parametrize("make", LOSSES)
@pytest.mark.parametrize(
    "source",
    [{}, {"preference": torch.tensor([0.2, 0.3, 0.5])}, {"resample_preferences": True}],
    ids=["batch", "fixed", "resampled"],
)
def test_output_keys_finite_and_priority(make, source):
    loss = make(**source)
    data = batch_for(loss, preference=not source)
    out = loss(data)
    assert sorted(out.keys()) == sorted(loss.out_keys) == ["alpha", "entropy", "loss_actor", "loss_alpha", "loss_qvalue"]
    assert all(torch.isfinite(v).all() for v in out.values())
    assert data["td_error"].shape == (B,) and (data["td_error"] >= 0).all()
    assert "preference" not in data["next"].keys()  # the input is not modified beyond the priority


@pytest.mark.parametrize("make", LOSSES)
def test_each_loss_reaches_exactly_its_parameters(make):
    loss = make()
    loss.log_alpha.data.fill_(-1.0)
    data = batch_for(loss)
    for name, owner in [("loss_qvalue", "critic"), ("loss_actor", "actor"), ("loss_alpha", "alpha")]:
        zero_grads(loss)
        loss(data.clone())[name].backward()
        critic = grads_of(loss.qvalue_network_params)
        actor = grads_of(loss.actor_network_params)
        assert all(critic.values()) == (owner == "critic") and any(critic.values()) == (owner == "critic"), name
        assert all(actor.values()) == (owner == "actor") and any(actor.values()) == (owner == "actor"), name
        assert (loss.log_alpha.grad is not None and loss.log_alpha.grad != 0) == (owner == "alpha"), name
        for p in loss.target_qvalue_network_params.values(True, True):
            assert p.grad is None and not p.requires_grad


@pytest.mark.parametrize("make", LOSSES)
def test_soft_update_moves_target_critics(make):
    loss = make()
    updater = SoftUpdate(loss, tau=0.25)
    key = next(iter(loss.qvalue_network_params.keys(True, True)))
    before = loss.target_qvalue_network_params[key].clone()
    with torch.no_grad():
        loss.qvalue_network_params[key].add_(4.0)
    updater.step()
    torch.testing.assert_close(loss.target_qvalue_network_params[key], 0.75 * before + 0.25 * loss.qvalue_network_params[key].data)
    assert loss.target_qvalue_network_params[key].shape[0] == 2  # one target per critic


def test_set_keys_renames_every_entry():
    torch.manual_seed(0)
    actor = make_gaussian_actor(OBS, SPEC, K, num_cells=(16,), observation_key="obs", preference_key="w", action_key="act")
    critic = make_vector_critic(OBS, ACT, K, num_cells=(16,), observation_key="obs", action_key="act", preference_key="w", out_key="qv")
    loss = MOSACLoss(actor, critic)
    loss.set_keys(action="act", state_action_value="qv", preference="w", reward="r", done="d", terminated="t", priority="prio")
    loss.make_value_estimator(gamma=0.9)
    base = random_batch(B, OBS, K, action_dim=ACT)
    data = TensorDict(
        {
            "obs": base["observation"],
            "act": base["action"],
            "w": base["preference"],
            ("next", "obs"): base["next", "observation"],
            ("next", "r"): base["next", "reward"],
            ("next", "d"): base["next", "done"],
            ("next", "t"): base["next", "terminated"],
        },
        [B],
    )
    out = loss(data)
    assert torch.isfinite(out["loss_qvalue"]) and data["prio"].shape == (B,)
    assert set(loss.in_keys) == {"act", "obs", "w", ("next", "obs"), ("next", "r"), ("next", "d"), ("next", "t")}


def test_discrete_set_keys_renames():
    torch.manual_seed(0)
    actor = make_categorical_actor(OBS, NA, K, num_cells=(16,), observation_key="obs", preference_key="w", action_key="act")
    critic = make_vector_q_network(OBS, NA, K, num_cells=(16,), observation_key="obs", preference_key="w", out_key="qs")
    loss = DiscreteMOSACLoss(actor, critic)
    loss.set_keys(action="act", action_value="qs", preference="w", reward="r", priority="prio")
    base = random_batch(B, OBS, K, num_actions=NA)
    data = base.rename_key_("action", "act").rename_key_("preference", "w").rename_key_(("next", "reward"), ("next", "r"))
    data.rename_key_("observation", "obs").rename_key_(("next", "observation"), ("next", "obs"))
    assert torch.isfinite(loss(data)["loss_qvalue"]) and data["prio"].shape == (B,)


def test_select_min_modes_on_concrete_values():
    q = torch.tensor([[[1.0, 5.0]], [[2.0, 2.0]]])  # two critics, one sample
    w = torch.tensor([[0.5, 0.5]])
    # critic 1 has the lower w . Q (2 < 3): its whole vector
    torch.testing.assert_close(continuous_loss(k=2)._select_min(q, w), torch.tensor([[2.0, 2.0]]))
    torch.testing.assert_close(continuous_loss(k=2, critic_min="elementwise")._select_min(q, w), torch.tensor([[1.0, 2.0]]))
    qd = torch.stack([torch.tensor([[[1.0, 5.0], [0.0, 0.0]]]), torch.tensor([[[2.0, 2.0], [1.0, 1.0]]])])  # [2, 1, A=2, 2]
    torch.testing.assert_close(discrete_loss(k=2)._select_min(qd, w), torch.tensor([[[2.0, 2.0], [0.0, 0.0]]]))
    with pytest.raises(ValueError, match="critic_min='worst'; valid values are"):
        continuous_loss(k=2, critic_min="worst")


def test_k1_matches_torchrl_sac():
    """With one objective and w = 1, MOSAC is SAC: same losses and TD errors as TorchRL's SACLoss."""
    ours = continuous_loss(k=1, preference=torch.ones(1), alpha_init=0.5, critic_loss="vector")
    theirs = SACLoss(ours.actor_network, ours.qvalue_network, loss_function="l2", alpha_init=0.5)
    theirs.make_value_estimator(ValueEstimators.TD0, gamma=0.9)
    theirs.qvalue_network_params.data.update_(ours.qvalue_network_params.data)
    theirs.target_qvalue_network_params.data.update_(ours.target_qvalue_network_params.data)
    data = random_batch(B, OBS, 1, action_dim=ACT)
    data["preference"] = torch.ones(B, 1)
    data["next", "preference"] = torch.ones(B, 1)
    d1, d2 = data.clone(), data.clone()
    torch.manual_seed(11)
    a = ours(d1)
    torch.manual_seed(11)
    b = theirs(d2)
    for key in ("loss_qvalue", "loss_actor", "loss_alpha", "entropy", "alpha"):
        torch.testing.assert_close(a[key], b[key], msg=key)
    torch.testing.assert_close(d1["td_error"], d2["td_error"])


def test_discrete_k1_matches_hand_computation():
    loss = discrete_loss(k=1, preference=torch.ones(1), alpha_init=0.3)
    with torch.no_grad():
        for p in loss.target_qvalue_network_params.values(True, True):
            p.add_(0.1 * torch.randn_like(p))
    data = random_batch(B, OBS, 1, num_actions=NA, preference=False)
    out = loss(data)
    actor_net = loss.actor_network.module[0].module
    critic_net = loss.qvalue_network.module
    ones = torch.ones(B, 1)
    with torch.no_grad():
        with loss.actor_network_params.to_module(loss.actor_network):
            logits_next = actor_net(data["next", "observation"], ones)
            logits = actor_net(data["observation"], ones)

        def critics(params, obs):
            values = []
            for i in range(2):
                with params[i].to_module(loss.qvalue_network):
                    values.append(critic_net(obs, ones)[..., 0])
            return torch.stack(values)

        q_next = critics(loss.target_qvalue_network_params, data["next", "observation"]).min(0).values
        p_next, logp_next = logits_next.softmax(-1), logits_next.log_softmax(-1)
        v_next = (p_next * (q_next - 0.3 * logp_next)).sum(-1)
        y = data["next", "reward"][:, 0] + 0.9 * (~data["next", "terminated"][:, 0]) * v_next
        q = critics(loss.qvalue_network_params, data["observation"])
        q_taken = q[:, torch.arange(B), data["action"]]
        loss_q = ((q_taken - y) ** 2).sum(0).mean()
        p, logp = logits.softmax(-1), logits.log_softmax(-1)
        loss_pi = (p * (0.3 * logp - q.min(0).values)).sum(-1).mean()
        neg_entropy = (p * logp).sum(-1)
        loss_alpha = (-torch.log(torch.tensor(0.3)) * (neg_entropy + 0.98 * torch.log(torch.tensor(float(NA))))).mean()
    torch.testing.assert_close(out["loss_qvalue"], loss_q)
    torch.testing.assert_close(out["loss_actor"], loss_pi)
    torch.testing.assert_close(out["loss_alpha"], loss_alpha)
    torch.testing.assert_close(out["entropy"], -neg_entropy.mean())
    torch.testing.assert_close(data["td_error"], (q_taken - y).abs().max(0).values)


def test_scalarized_and_vector_critic_losses_differ_only_for_k_above_1():
    torch.manual_seed(2)
    data = random_batch(B, OBS, 2, action_dim=ACT)
    values = {}
    for mode in ("scalarized", "vector"):
        loss = continuous_loss(k=2, critic_loss=mode)
        torch.manual_seed(5)
        values[mode] = loss(data.clone())["loss_qvalue"]
    assert not torch.allclose(values["scalarized"], values["vector"])


def test_fixed_preference_can_be_replaced():
    loss = continuous_loss(preference=torch.tensor([1.0, 0.0, 0.0]))
    loss.set_preference(torch.tensor([0.0, 0.5, 0.5]))
    assert loss.fixed_preference.tolist() == [0.0, 0.5, 0.5]
    with pytest.raises(ValueError, match="simplex"):
        loss.set_preference(torch.tensor([0.5, 0.5, 0.5]))
    with pytest.raises(ValueError, match="shape \\(2,\\)"):
        loss.set_preference(torch.tensor([0.5, 0.5]))
    with pytest.raises(ValueError, match="no fixed preference"):
        continuous_loss().set_preference(torch.tensor([1.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="either a fixed preference or resample"):
        continuous_loss(preference=torch.ones(3) / 3, resample_preferences=True)


@pytest.mark.parametrize("make", LOSSES)
@pytest.mark.parametrize(
    "mutate, match",
    [
        (lambda d: d.set(("next", "reward"), torch.randn(B, K - 1)), r"reward .*shape \(12, 2\).*3 objectives"),
        (lambda d: d["next", "reward"].__setitem__((2, 0), float("nan")), r"non-finite.*\[2, 0\]"),
        (lambda d: d.set("preference", torch.full((B, K + 1), 0.25)), r"preference.*shape \(12, 4\)"),
        (lambda d: d.set("preference", -torch.ones(B, K) / K), r"simplex"),
        (lambda d: d.exclude("preference", inplace=True), r"no preference"),
    ],
)
def test_bad_input_raises_before_any_update(make, mutate, match):
    loss = make()
    data = batch_for(loss)
    mutate(data)
    with pytest.raises(ValueError, match=match):
        loss(data)
    assert "td_error" not in data.keys()
    assert all(p.grad is None for p in loss.parameters())


def test_continuous_learns_preference_dependent_actions():
    torch.manual_seed(0)
    data = continuous_bandit_dataset()
    actor = make_gaussian_actor(2, Bounded(-1.0, 1.0, (1,)), 2, num_cells=(64, 64))
    critic = make_vector_critic(2, 1, 2, num_cells=(64, 64))
    loss = MOSACLoss(actor, critic, alpha_init=0.2)
    loss.make_value_estimator(gamma=0.9)
    updater = SoftUpdate(loss, tau=0.05)
    optim = torch.optim.Adam(loss.parameters(), lr=3e-3)
    for _ in range(150):
        out = loss(data[torch.randint(len(data), (64,))])
        optim.zero_grad()
        (out["loss_qvalue"] + out["loss_actor"] + out["loss_alpha"]).backward()
        optim.step()
        updater.step()
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        action = actor(TensorDict({"observation": torch.ones(2, 2), "preference": EXTREME_PREFERENCES}, [2]))["action"][:, 0]
    # optimum: -0.86 under (0.9, 0.1) and +0.86 under (0.1, 0.9)
    assert action[0] < -0.5 and action[1] > 0.5, action


def test_discrete_learns_preference_dependent_actions():
    torch.manual_seed(0)
    data = two_step_dataset()
    actor = make_categorical_actor(3, 3, 2, num_cells=(64, 64))
    critic = make_vector_q_network(3, 3, 2, num_cells=(64, 64))
    loss = DiscreteMOSACLoss(actor, critic, alpha_init=0.1, target_entropy_weight=0.3)
    loss.make_value_estimator(gamma=0.9)
    updater = SoftUpdate(loss, tau=0.05)
    optim = torch.optim.Adam(loss.parameters(), lr=3e-3)
    for _ in range(150):
        out = loss(data[torch.randint(len(data), (64,))])
        optim.zero_grad()
        (out["loss_qvalue"] + out["loss_actor"] + out["loss_alpha"]).backward()
        optim.step()
        updater.step()
    with torch.no_grad(), loss.actor_network_params.to_module(loss.actor_network):
        probs = loss.actor_network.get_dist(
            TensorDict({"observation": START.expand(2, 3), "preference": EXTREME_PREFERENCES}, [2])
        ).probs
    assert probs.argmax(-1).tolist() == [0, 1], probs
    assert (probs.max(-1).values > 0.6).all(), probs


@pytest.mark.parametrize("make", LOSSES)
def test_state_dict_round_trip(make):
    loss = make(preference=torch.tensor([0.6, 0.2, 0.2]))
    with torch.no_grad():
        loss.log_alpha.fill_(-0.7)
        for p in loss.target_qvalue_network_params.values(True, True):
            p.add_(0.1)
    other = make(preference=torch.tensor([1.0, 0.0, 0.0]))
    other.load_state_dict(loss.state_dict())
    assert other.fixed_preference.tolist() == pytest.approx([0.6, 0.2, 0.2])
    data = batch_for(loss, preference=False)
    torch.manual_seed(4)
    a = loss(data.clone())
    torch.manual_seed(4)
    b = other(data.clone())
    for key in ("loss_qvalue", "loss_actor", "loss_alpha", "alpha"):
        torch.testing.assert_close(a[key], b[key], msg=key)


@pytest.mark.parametrize("make", LOSSES)
def test_vmapped_and_looped_critic_ensembles_agree(make):
    loss = make()
    data = batch_for(loss)
    outs = {}
    for mode in ("loop", "vmap"):
        loss.critic_ensemble_mode = mode
        torch.manual_seed(8)
        outs[mode] = loss(data.clone())
    for key in ("loss_qvalue", "loss_actor", "loss_alpha"):
        torch.testing.assert_close(outs["loop"][key], outs["vmap"][key], msg=key)
