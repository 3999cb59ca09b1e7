import pytest
import torch
from tensordict import TensorDict
from torchrl.data import Bounded
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.objectives import HardUpdate, SACLoss, SoftUpdate, ValueEstimators

from morl_trl.objectives import CAPQLLoss, make_gaussian_actor, make_vector_critic
from tests.objectives._helpers import (
    EXTREME_PREFERENCES,
    continuous_bandit_dataset,
    grads_of,
    random_batch,
    zero_grads,
)

pytestmark = pytest.mark.filterwarnings("ignore:No target network updater")

OBS, ACT, K, B = 7, 3, 3, 10
SPEC = Bounded(-1.0, 1.0, (ACT,))


def make_loss(k=K, **kwargs):
    torch.manual_seed(0)
    loss = CAPQLLoss(make_gaussian_actor(OBS, SPEC, k, num_cells=(32,)), make_vector_critic(OBS, ACT, k, num_cells=(32,)), **kwargs)
    loss.make_value_estimator(gamma=0.9)
    return loss


def test_defaults_are_the_paper_settings():
    loss = make_loss()
    assert float(loss._alpha) == pytest.approx(0.2)
    assert not isinstance(loss.log_alpha, torch.nn.Parameter)
    # the authors train on the preference stored with each transition (fresh per-sample draws: an option)
    assert loss.resample_preferences is False
    assert "preference" in loss.in_keys
    assert loss.num_qvalue_nets == 2
    assert loss.log_prob_form == "clamped"  # the authors' log pi (capql.py:149-155)


@pytest.mark.parametrize("resample", [False, True])
@pytest.mark.parametrize("fast", [True, False])
def test_capql_is_mosac_with_elementwise_min_vector_loss_and_fixed_alpha(resample, fast):
    """CAPQL's own value estimate, critic loss and actor loss compute, bit for bit, what ``MOSACLoss`` computes
    with ``critic_min="elementwise"``, ``critic_loss="vector"`` and a fixed temperature: losses, priorities,
    and the parameters after three Adam steps with Polyak targets."""
    from morl_trl.objectives import MOSACLoss

    capql = make_loss(resample_preferences=resample, log_prob_form="exact")  # (MOSAC's: TorchRL's TanhNormal)
    torch.manual_seed(0)
    mosac = MOSACLoss(make_gaussian_actor(OBS, SPEC, K, num_cells=(32,)), make_vector_critic(OBS, ACT, K, num_cells=(32,)),
                      critic_min="elementwise", critic_loss="vector", fixed_alpha=True, alpha_init=0.2,
                      resample_preferences=resample)
    mosac.make_value_estimator(gamma=0.9)
    assert capql.state_dict().keys() == mosac.state_dict().keys()
    data = random_batch(B, OBS, K, action_dim=ACT)
    results = []
    for loss in (capql, mosac):
        loss.fast_networks = fast
        torch.manual_seed(3)
        opt = torch.optim.Adam(loss.parameters(), lr=1e-3)
        updater = SoftUpdate(loss, tau=0.05)
        outs = []
        for _ in range(3):
            batch = data.clone()
            q, _ = loss.qvalue_loss(batch)
            out = loss(batch)
            opt.zero_grad()
            (q + out["loss_actor"]).backward()
            opt.step()
            updater.step()
            outs.append((q.detach(), out.detach(), batch["td_error"]))
        results.append((outs, {k: v.detach().clone() for k, v in loss.state_dict().items()}))
    (outs_c, state_c), (outs_m, state_m) = results
    for (qc, oc, pc), (qm, om, pm) in zip(outs_c, outs_m):
        assert torch.equal(qc, qm) and torch.equal(pc, pm)
        assert all(torch.equal(oc[key], om[key]) for key in oc.keys())
    assert all(torch.equal(state_c[key], state_m[key]) for key in state_c)


def _authors_log_prob(loc, scale, seed):
    """The authors' CAPQL ``sample`` (capql.py:149-155; MORL-Baselines 1.3.0 capql.py:138-154), written out: the
    pre-squash draw, its Normal log-density summed over dimensions, minus sum log(1 - tanh^2 + 1e-6) (action scale 1),
    clamped to [-1000, 1000]."""
    torch.manual_seed(seed)
    normal = torch.distributions.Normal(loc, scale)
    x = normal.rsample()
    y = torch.tanh(x)
    return y, (normal.log_prob(x).sum(1) - torch.log(1 * (1 - y.pow(2)) + 1e-6).sum(1)).clamp(-1e3, 1e3)


@pytest.mark.parametrize("saturate", [False, True])
def test_log_pi_is_the_authors_by_default_and_torchrls_tanh_normal_as_an_option(saturate):
    """The actor loss's action and log pi are the authors' formula on the same draw; where tanh saturates
    (|loc| ~ 40: 1 - tanh^2 underflows) the authors' log pi stays bounded (the 1e-6) and TorchRL's exact Jacobian
    does not, and the two forms' actor losses part; unsaturated they agree to float error."""
    data = random_batch(B, OBS, K, action_dim=ACT)
    losses = {form: make_loss(log_prob_form=form) for form in ("clamped", "exact")}
    if saturate:
        for loss in losses.values():
            for name, leaf in loss.actor_network_params.items(True, True):
                if name[-1] == "bias":
                    leaf.data.fill_(40.0)  # (the last layer's bias: every location ~40, the log-std clamped at 2)
    dist, _ = losses["clamped"].actor_dist(data)
    loc, scale = dist.base_dist.base_dist.loc.detach(), dist.base_dist.base_dist.scale.detach()
    action, expected = _authors_log_prob(loc, scale, seed=7)
    torch.manual_seed(7)
    _, info = losses["clamped"].actor_loss(data)
    torch.testing.assert_close(info["log_prob"], expected, rtol=1e-5, atol=1e-4)
    torch.manual_seed(7)
    _, exact = losses["exact"].actor_loss(data)
    if saturate:
        # the 1e-6 bounds the Jacobian term at 3 log(1e6) = 41.4; the exact one is ~2|x| - log 4 per dimension
        assert (info["log_prob"] < 41.5).all() and (exact["log_prob"] > 60).all() and exact["log_prob"].max() > 500
    else:
        torch.testing.assert_close(exact["log_prob"], info["log_prob"], rtol=1e-4, atol=1e-3)
    with pytest.raises(ValueError, match=r"log_prob_form='tanh'; valid values are \('clamped', 'exact'\)"):
        make_loss(log_prob_form="tanh")


def test_output_keys_finite_without_a_stored_preference():
    loss = make_loss(resample_preferences=True)
    data = random_batch(B, OBS, K, action_dim=ACT, preference=False)
    out = loss(data)
    assert sorted(out.keys()) == sorted(loss.out_keys) == ["alpha", "entropy", "loss_actor", "loss_qvalue"]
    assert all(torch.isfinite(v).all() for v in out.values())
    assert data["td_error"].shape == (B,)
    assert "preference" not in loss.in_keys


def test_fresh_preferences_per_sample_and_per_call():
    loss = make_loss(resample_preferences=True)
    data = random_batch(B, OBS, K, action_dim=ACT)
    w1, w2 = loss._batch_preferences(data), loss._batch_preferences(data)
    assert w1.shape == (B, K)
    torch.testing.assert_close(w1.sum(-1), torch.ones(B))
    assert (w1 >= 0).all()
    assert len({tuple(row.tolist()) for row in w1}) == B  # one draw per sample
    assert not torch.equal(w1, w2)  # a new draw at every call
    stored = make_loss()
    assert torch.equal(stored._batch_preferences(data), data["preference"])


def test_gradients_reach_exactly_the_right_parameters():
    loss = make_loss()
    data = random_batch(B, OBS, K, action_dim=ACT)
    zero_grads(loss)
    loss(data.clone())["loss_qvalue"].backward()
    assert all(grads_of(loss.qvalue_network_params).values())
    assert not any(grads_of(loss.actor_network_params).values())
    zero_grads(loss)
    loss(data.clone())["loss_actor"].backward()
    assert all(grads_of(loss.actor_network_params).values())
    assert not any(grads_of(loss.qvalue_network_params).values())
    for p in loss.target_qvalue_network_params.values(True, True):
        assert p.grad is None and not p.requires_grad
    assert {id(p) for p in loss.parameters()} == {
        id(p) for p in (*loss.actor_network_params.values(True, True), *loss.qvalue_network_params.values(True, True))
    }


def test_target_updaters_move_targets():
    loss = make_loss()
    key = next(iter(loss.qvalue_network_params.keys(True, True)))
    with torch.no_grad():
        loss.qvalue_network_params[key].add_(1.0)
    assert not torch.equal(loss.qvalue_network_params[key].data, loss.target_qvalue_network_params[key])
    updater = HardUpdate(loss, value_network_update_interval=0)
    updater.step()
    assert torch.equal(loss.qvalue_network_params[key].data, loss.target_qvalue_network_params[key])
    soft = SoftUpdate(loss, tau=0.1)
    with torch.no_grad():
        loss.qvalue_network_params[key].add_(1.0)
    before = loss.target_qvalue_network_params[key].clone()
    soft.step()
    torch.testing.assert_close(loss.target_qvalue_network_params[key], before + 0.1)


def test_set_keys_renames():
    torch.manual_seed(0)
    actor = make_gaussian_actor(OBS, SPEC, K, num_cells=(16,), observation_key="obs", preference_key="pref", action_key="u")
    critic = make_vector_critic(OBS, ACT, K, num_cells=(16,), observation_key="obs", action_key="u", preference_key="pref", out_key="qv")
    loss = CAPQLLoss(actor, critic)
    loss.set_keys(action="u", state_action_value="qv", preference="pref", reward="vec_r", terminated="term", done="dn", priority="p")
    base = random_batch(B, OBS, K, action_dim=ACT)
    data = TensorDict(
        {
            "obs": base["observation"],
            "pref": base["preference"],
            "u": base["action"],
            ("next", "obs"): base["next", "observation"],
            ("next", "vec_r"): base["next", "reward"],
            ("next", "dn"): base["next", "done"],
            ("next", "term"): base["next", "terminated"],
        },
        [B],
    )
    assert torch.isfinite(loss(data)["loss_qvalue"]) and data["p"].shape == (B,)


def test_k1_is_sac_with_a_fixed_temperature():
    ours = make_loss(k=1, resample_preferences=False, log_prob_form="exact")
    theirs = SACLoss(ours.actor_network, ours.qvalue_network, loss_function="l2", alpha_init=0.2, fixed_alpha=True)
    theirs.make_value_estimator(ValueEstimators.TD0, gamma=0.9)
    theirs.qvalue_network_params.data.update_(ours.qvalue_network_params.data)
    theirs.target_qvalue_network_params.data.update_(ours.target_qvalue_network_params.data)
    data = random_batch(B, OBS, 1, action_dim=ACT)
    data["next", "preference"] = data["preference"]  # all ones with k = 1
    d1, d2 = data.clone(), data.clone()
    torch.manual_seed(3)
    a = ours(d1)
    torch.manual_seed(3)
    b = theirs(d2)
    for key in ("loss_qvalue", "loss_actor", "entropy", "alpha"):
        torch.testing.assert_close(a[key], b[key], msg=key)


@pytest.mark.parametrize(
    "mutate, match",
    [
        (lambda d: d.set(("next", "reward"), torch.randn(B, 2)), r"reward .*shape \(10, 2\).*3 objectives"),
        (lambda d: d["next", "reward"].__setitem__((4, 2), float("-inf")), r"non-finite.*\[4, 2\]"),
    ],
)
def test_bad_input_raises_before_any_update(mutate, match):
    loss = make_loss()
    data = random_batch(B, OBS, K, action_dim=ACT)
    mutate(data)
    with pytest.raises(ValueError, match=match):
        loss(data)
    assert "td_error" not in data.keys()


def test_learns_preference_dependent_actions_on_a_convex_front():
    torch.manual_seed(0)
    data = continuous_bandit_dataset().exclude("preference")
    actor = make_gaussian_actor(2, Bounded(-1.0, 1.0, (1,)), 2, num_cells=(64, 64))
    critic = make_vector_critic(2, 1, 2, num_cells=(64, 64))
    loss = CAPQLLoss(actor, critic, resample_preferences=True)
    loss.make_value_estimator(gamma=0.9)
    updater = SoftUpdate(loss, tau=0.05)
    optim = torch.optim.Adam(loss.parameters(), lr=3e-3)
    for _ in range(150):
        out = loss(data[torch.randint(len(data), (64,))])
        optim.zero_grad()
        (out["loss_qvalue"] + out["loss_actor"]).backward()
        optim.step()
        updater.step()
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        action = actor(TensorDict({"observation": torch.ones(2, 2), "preference": EXTREME_PREFERENCES}, [2]))["action"][:, 0]
    # optimum: -0.86 under (0.9, 0.1) and +0.86 under (0.1, 0.9)
    assert action[0] < -0.5 and action[1] > 0.5, action
