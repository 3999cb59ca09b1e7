import pytest
import torch
from tensordict import TensorDict
from torch import nn
from torchrl.data import Categorical, LazyTensorStorage, TensorDictReplayBuffer
from torchrl.modules import QValueActor
from torchrl.objectives import DQNLoss, HardUpdate, SoftUpdate, ValueEstimators

from morl_trl.data import TorchPrioritizedSampler
from morl_trl.objectives import EnvelopeQLoss, make_vector_q_network
from tests.objectives._helpers import (
    EXTREME_PREFERENCES,
    START,
    grads_of,
    random_batch,
    two_step_dataset,
)

pytestmark = pytest.mark.filterwarnings("ignore:No target network updater")

OBS, A, K, B = 6, 4, 3, 16


def make_loss(k=K, num_actions=A, **kwargs):
    torch.manual_seed(0)
    q = make_vector_q_network(OBS, num_actions, k, num_cells=(32, 32))
    kwargs.setdefault("num_preference_samples", 4)
    loss = EnvelopeQLoss(q, **kwargs)
    loss.make_value_estimator(gamma=0.9)
    return loss


def perturb_targets(loss, scale=0.3):
    with torch.no_grad():
        for p in loss.target_value_network_params.values(True, True):
            p.add_(torch.randn_like(p) * scale)


def test_output_keys_finite_and_priority_written():
    loss = make_loss(homotopy_lambda=0.95)
    data = random_batch(B, OBS, K, num_actions=A)
    out = loss(data)
    assert set(out.keys()) == set(loss.out_keys)
    assert all(torch.isfinite(v).all() for v in out.values())
    assert out["homotopy_lambda"] == pytest.approx(0.95)
    assert data["td_error"].shape == (B,)
    assert (data["td_error"] >= 0).all() and data["td_error"].sum() > 0


def test_gradients_reach_online_params_only():
    loss = make_loss()
    perturb_targets(loss)
    loss(random_batch(B, OBS, K, num_actions=A))["loss_qvalue"].backward()
    assert all(grads_of(loss.value_network_params).values())
    for p in loss.target_value_network_params.values(True, True):
        assert p.grad is None and not p.requires_grad
    assert {id(p) for p in loss.parameters()} == {id(p) for p in loss.value_network_params.values(True, True)}


def test_target_updaters_move_target_params():
    loss = make_loss()
    online = loss.value_network_params
    target = loss.target_value_network_params
    hard = HardUpdate(loss, value_network_update_interval=1)
    with torch.no_grad():
        for p in online.values(True, True):
            p.add_(1.0)
    key = next(iter(online.keys(True, True)))
    assert not torch.equal(online[key], target[key])
    hard.step()  # counter 0 -> 1
    hard.step()  # copies
    assert torch.equal(online[key].data, target[key])

    soft = SoftUpdate(loss, tau=0.5)
    before = target[key].clone()
    with torch.no_grad():
        online[key].add_(2.0)
    soft.step()
    torch.testing.assert_close(target[key], 0.5 * before + 0.5 * online[key].data)


def test_set_keys_renames_every_entry():
    torch.manual_seed(0)
    q = make_vector_q_network(OBS, A, K, num_cells=(16,), observation_key="obs", preference_key="w", out_key="q")
    loss = EnvelopeQLoss(q, num_preference_samples=2)
    loss.set_keys(action_value="q", action="act", preference="w", reward="vec_reward", done="d", terminated="t", priority="prio")
    loss.make_value_estimator(gamma=0.9)
    base = random_batch(B, OBS, K, num_actions=A)
    data = TensorDict(
        {
            "obs": base["observation"],
            "act": base["action"],
            ("next", "obs"): base["next", "observation"],
            ("next", "vec_reward"): base["next", "reward"],
            ("next", "d"): base["next", "done"],
            ("next", "t"): base["next", "terminated"],
        },
        [B],
    )
    out = loss(data)
    assert torch.isfinite(out["loss_qvalue"])
    assert data["prio"].shape == (B,)
    assert set(loss.in_keys) == {"act", "obs", ("next", "obs"), ("next", "vec_reward"), ("next", "d"), ("next", "t")}


class _Scalar(nn.Module):
    """The k = 1 network seen as a scalar Q-network for TorchRL's DQNLoss."""

    def __init__(self, net):
        super().__init__()
        self.net = net

    def forward(self, obs):
        return self.net(obs, torch.ones(*obs.shape[:-1], 1))[..., 0]


def test_k1_target_is_the_double_dqn_target():
    """With one objective every preference is w = 1 and the envelope target is the DQN target."""
    loss = make_loss(k=1, num_actions=3, num_preference_samples=3, homotopy_lambda=0.5)
    perturb_targets(loss)
    data = random_batch(B, OBS, 1, num_actions=3, preference=False)
    out = loss(data)

    net = loss.value_network.module
    with torch.no_grad():
        with loss.value_network_params.to_module(loss.value_network):
            q = net(data["observation"], torch.ones(B, 1))[..., 0]
            q_next_online = net(data["next", "observation"], torch.ones(B, 1))[..., 0]
        with loss.target_value_network_params.to_module(loss.value_network):
            q_next_target = net(data["next", "observation"], torch.ones(B, 1))[..., 0]
        a_star = q_next_online.argmax(-1)
        y = data["next", "reward"][:, 0] + 0.9 * (~data["next", "terminated"][:, 0]) * q_next_target.gather(1, a_star[:, None])[:, 0]
        expected = ((q.gather(1, data["action"][:, None])[:, 0] - y) ** 2).mean()
    torch.testing.assert_close(out["loss_qvalue"], expected)
    torch.testing.assert_close(data["td_error"], (q.gather(1, data["action"][:, None])[:, 0] - y).abs())


def test_k1_loss_equals_torchrl_double_dqn_loss():
    loss = make_loss(k=1, num_actions=3, num_preference_samples=2)
    scalar = QValueActor(_Scalar(loss.value_network.module), in_keys=["observation"], spec=Categorical(3))
    dqn = DQNLoss(scalar, double_dqn=True, delay_value=True, loss_function="l2", action_space=Categorical(3))
    dqn.make_value_estimator(ValueEstimators.TD0, gamma=0.9)
    data = random_batch(B, OBS, 1, num_actions=3, preference=False)
    ours = loss(data.clone())["loss_qvalue"]
    theirs = dqn(data.clone())["loss"]
    torch.testing.assert_close(ours, theirs)


def brute_force_targets(loss, data, w):
    """y[b, i] by explicit loops over the candidate (preference, action) pairs."""
    net = loss.value_network.module
    batch, n, k = w.shape
    y = torch.zeros(batch, n, k)
    with torch.no_grad():
        for b in range(batch):
            s1 = data["next", "observation"][b]
            for i in range(n):
                best, best_val = None, -float("inf")
                for m in range(n):
                    with loss.value_network_params.to_module(loss.value_network):
                        q_online = net(s1, w[b, m])
                    for a in range(q_online.shape[0]):
                        score = float(w[b, i] @ q_online[a])
                        if score > best_val:
                            best, best_val = (m, a), score
                m, a = best
                with loss.target_value_network_params.to_module(loss.value_network):
                    q_target = net(s1, w[b, m])[a]
                alive = 0.0 if bool(data["next", "terminated"][b]) else 1.0
                y[b, i] = data["next", "reward"][b] + 0.9 * alive * q_target
    return y


@pytest.mark.parametrize("shared", [True, False])
def test_envelope_target_matches_brute_force(shared):
    loss = make_loss(k=2, num_actions=3, num_preference_samples=3, shared_preferences=shared)
    perturb_targets(loss)
    data = random_batch(5, OBS, 2, num_actions=3, preference=False)
    torch.manual_seed(7)
    w = loss._preferences(data)
    assert w.shape == (5, 3, 2)
    assert torch.equal(w[0], w[1]) == shared
    loss._preferences = lambda _: w  # pin the sampled preferences
    y = brute_force_targets(loss, data, w)
    net = loss.value_network.module
    with torch.no_grad(), loss.value_network_params.to_module(loss.value_network):
        q = net(data["observation"].unsqueeze(1).expand(5, 3, OBS), w)
    q_taken = q[torch.arange(5), :, data["action"]]  # [B, N, k]
    loss.homotopy_lambda = 0.0
    torch.testing.assert_close(loss(data)["loss_qvalue"], ((q_taken - y) ** 2).mean(), rtol=1e-5, atol=1e-6)
    loss.homotopy_lambda = 1.0
    scalar = ((w * (q_taken - y)).sum(-1) ** 2).mean()
    torch.testing.assert_close(loss(data)["loss_qvalue"], scalar, rtol=1e-5, atol=1e-6)
    # the priority is the first sampled preference's scalarised TD error (MORL-Baselines) by default
    torch.testing.assert_close(data["td_error"], (w * (q_taken - y)).sum(-1).abs()[:, 0], rtol=1e-5, atol=1e-6)
    loss.priority = "mean"
    loss(data)
    torch.testing.assert_close(data["td_error"], (w * (q_taken - y)).sum(-1).abs().mean(-1), rtol=1e-5, atol=1e-6)


def test_homotopy_schedule_and_combination():
    loss = make_loss(homotopy_lambda=0.95, final_homotopy_lambda=1.0, homotopy_steps=100)
    assert loss.update_homotopy(0) == pytest.approx(0.95)
    assert loss.update_homotopy(50) == pytest.approx(0.975)
    assert loss.update_homotopy(1000) == pytest.approx(1.0)
    loss.homotopy_lambda = 0.3
    assert isinstance(loss.homotopy_lambda, torch.Tensor) and float(loss.homotopy_lambda) == pytest.approx(0.3)
    out = loss(random_batch(B, OBS, K, num_actions=A))
    torch.testing.assert_close(out["loss_qvalue"].detach(), 0.7 * out["vector_loss"] + 0.3 * out["scalarized_loss"])
    assert "homotopy_lambda" in loss.state_dict()


def test_multi_dimensional_batch_and_one_hot_actions():
    loss = make_loss()
    data = random_batch(B, OBS, K, num_actions=A)
    data["action"] = torch.nn.functional.one_hot(data["action"], A)
    torch.manual_seed(3)
    flat = loss(data.clone())["loss_qvalue"]
    torch.manual_seed(3)
    grid = data.reshape(4, 4)
    out = loss(grid)
    torch.testing.assert_close(out["loss_qvalue"], flat)
    assert grid["td_error"].shape == (4, 4)


def test_priority_weights_weight_the_samples():
    loss = make_loss(reduction="none")
    data = random_batch(B, OBS, K, num_actions=A)
    torch.manual_seed(1)
    per_sample = loss(data.clone())["loss_qvalue"]
    assert per_sample.shape == (B,)
    loss.reduction = "mean"
    weights = torch.rand(B)
    weighted = data.clone()
    weighted["priority_weight"] = weights
    torch.manual_seed(1)
    torch.testing.assert_close(loss(weighted)["loss_qvalue"], (per_sample * weights).sum() / weights.sum())


def test_include_batch_preference_uses_the_stored_preference():
    loss = make_loss(include_batch_preference=True)
    data = random_batch(B, OBS, K, num_actions=A)
    w = loss._preferences(data)
    assert torch.equal(w[:, 0], data["preference"])
    assert "preference" in loss.in_keys


@pytest.mark.parametrize(
    "mutate, match",
    [
        (lambda d: d.set(("next", "reward"), torch.randn(B, K + 1)), r"reward .*shape \(16, 4\).*3 objectives"),
        (lambda d: d["next", "reward"].__setitem__((3, 1), float("nan")), r"non-finite.*index \[3, 1\]"),
        (lambda d: d["next", "reward"].__setitem__((0, 0), float("inf")), r"non-finite"),
        (lambda d: d.set("preference", torch.full((B, K + 1), 0.25)), r"preference.*shape \(16, 4\).*3"),
        (lambda d: d.set("preference", torch.full((B, K), 0.5)), r"simplex"),
    ],
)
def test_bad_input_raises_before_any_update(mutate, match):
    loss = make_loss(include_batch_preference=True)
    data = random_batch(B, OBS, K, num_actions=A)
    mutate(data)
    before = loss.value_network_params.clone()
    with pytest.raises(ValueError, match=match):
        loss(data)
    assert "td_error" not in data.keys()
    assert (loss.value_network_params == before).all()
    assert all(p.grad is None for p in loss.parameters())


def test_value_estimator_options():
    loss = make_loss(k=1, num_actions=2, num_preference_samples=1)
    with pytest.raises(NotImplementedError, match="TD0"):
        loss.make_value_estimator(ValueEstimators.GAE)
    loss.make_value_estimator("td0", gamma=0.0)
    data = random_batch(B, OBS, 1, num_actions=2, preference=False)
    net = loss.value_network.module
    with torch.no_grad(), loss.value_network_params.to_module(loss.value_network):
        q = net(data["observation"], torch.ones(B, 1))[torch.arange(B), data["action"], 0]
    torch.testing.assert_close(loss(data)["loss_qvalue"], ((q - data["next", "reward"][:, 0]) ** 2).mean())


def test_works_with_prioritized_replay_buffer():
    loss = make_loss()
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(64), sampler=TorchPrioritizedSampler(64, alpha=0.6, beta=0.4), batch_size=B)
    rb.extend(random_batch(64, OBS, K, num_actions=A))
    sample = rb.sample()
    assert "priority_weight" in sample.keys()
    loss(sample)["loss_qvalue"].backward()
    rb.update_tensordict_priority(sample)
    index = sample["index"]
    expected = (sample["td_error"] + 1e-8) ** 0.6
    got = rb.sampler._sum_tree[index]
    # a repeated index keeps the last write
    last = {int(i): float(e) for i, e in zip(index, expected)}
    torch.testing.assert_close(got, torch.tensor([last[int(i)] for i in index]))


def greedy_first_action(loss, w):
    net = loss.value_network.module
    with torch.no_grad(), loss.value_network_params.to_module(loss.value_network):
        q = net(START.expand(len(w), 3), w)
    return (q * w.unsqueeze(1)).sum(-1).argmax(-1)


def test_learns_preference_dependent_actions_on_a_convex_front():
    torch.manual_seed(0)
    data = two_step_dataset()
    q = make_vector_q_network(3, 3, 2, num_cells=(64, 64))
    loss = EnvelopeQLoss(q, num_preference_samples=4, homotopy_lambda=0.5)
    loss.make_value_estimator(gamma=0.9)
    updater = SoftUpdate(loss, tau=0.05)
    optim = torch.optim.Adam(loss.parameters(), lr=3e-3)
    for _ in range(200):
        batch = data[torch.randint(len(data), (64,))]
        optim.zero_grad()
        loss(batch)["loss_qvalue"].backward()
        optim.step()
        updater.step()
    assert greedy_first_action(loss, EXTREME_PREFERENCES).tolist() == [0, 1]
    # the vector Q of the chosen first action is the discounted extreme point of the front
    net = loss.value_network.module
    with torch.no_grad(), loss.value_network_params.to_module(loss.value_network):
        q0 = net(START.expand(2, 3), EXTREME_PREFERENCES)
    torch.testing.assert_close(q0[0, 0], torch.tensor([0.9, 0.0]), atol=0.15, rtol=0)
    torch.testing.assert_close(q0[1, 1], torch.tensor([0.0, 0.9]), atol=0.15, rtol=0)


def test_trains_on_rollouts_of_a_batched_contextual_env():
    from tests.mocks import ToyContextEnv

    env = ToyContextEnv(num_envs=4, seed=0)
    rollout = env.rollout(6, break_when_any_done=False)  # [4 envs, 6 steps], reward [4, 6, 2]
    torch.manual_seed(0)
    loss = EnvelopeQLoss(make_vector_q_network(2, 2, 2, num_cells=(16,)), num_preference_samples=3)
    HardUpdate(loss, value_network_update_interval=10)
    out = loss(rollout)
    assert torch.isfinite(out["loss_qvalue"]) and rollout["td_error"].shape == (4, 6)
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(100), sampler=TorchPrioritizedSampler(100, 0.6, 0.4), batch_size=8)
    rb.extend(rollout.reshape(-1).exclude("td_error"))
    sample = rb.sample()
    loss(sample)["loss_qvalue"].backward()
    rb.update_tensordict_priority(sample)


@pytest.mark.parametrize(
    "options",
    [{"envelope": False}, {"double_dqn": False}, {"double_dqn": False, "delay_value": False}],
    ids=["scalarized-ddqn-target", "single-q", "no-target-net"],
)
def test_target_variants(options):
    loss = make_loss(**options)
    data = random_batch(B, OBS, K, num_actions=A)
    out = loss(data)
    assert torch.isfinite(out["loss_qvalue"])
    out["loss_qvalue"].backward()
    assert all(grads_of(loss.value_network_params).values())
    if options.get("delay_value") is False:
        with pytest.raises(RuntimeError):
            HardUpdate(loss)  # nothing to update
    with pytest.raises(ValueError, match="double_dqn=True requires delay_value=True"):
        make_loss(double_dqn=True, delay_value=False)


def test_state_dict_round_trip():
    loss = make_loss(homotopy_lambda=0.4)
    perturb_targets(loss)
    other = make_loss()
    other.load_state_dict(loss.state_dict())
    assert float(other.homotopy_lambda) == pytest.approx(0.4)
    data = random_batch(B, OBS, K, num_actions=A)
    torch.manual_seed(9)
    a = loss(data.clone())["loss_qvalue"]
    torch.manual_seed(9)
    b = other(data.clone())["loss_qvalue"]
    torch.testing.assert_close(a, b)


# ---------------------------------------------------------------- the authors' PER priority
class _TableQ(nn.Module):
    """``Q(s, a, w) = s.view(|A|=2, k=2)`` whatever ``w``: hand-checkable values."""

    def __init__(self):
        super().__init__()
        self.zero = nn.Parameter(torch.zeros(()))

    def forward(self, obs, w):
        return obs.reshape(*obs.shape[:-1], 2, 2) + self.zero


def test_envelope_priority_uses_the_first_sampled_preference_as_the_authors():
    loss = EnvelopeQLoss(_TableQ(), num_objectives=2, num_preference_samples=2, homotopy_lambda=0.95)
    loss.make_value_estimator(gamma=0.9)
    assert loss.priority == "first"
    w = torch.tensor([[0.25, 0.75], [0.5, 0.5]]).expand(2, 2, 2)  # w_0, w_1 shared by the batch
    loss._preferences = lambda _: w
    done = torch.ones(2, 1, dtype=torch.bool)  # terminal: y = r
    data = TensorDict({
        "observation": torch.tensor([[1.0, 2.0, 3.0, 4.0], [0.0, 0.0, 2.0, -6.0]]),
        "action": torch.tensor([0, 1]),
        ("next", "observation"): torch.zeros(2, 4),
        ("next", "reward"): torch.tensor([[0.0, 0.0], [1.0, 1.0]]),
        ("next", "done"): done, ("next", "terminated"): done.clone(),
    }, [2])
    # transition 0: Q(s, 0) - y = (1, 2)  -> |w_0 . (1, 2)| = 1.75, |w_1 . (1, 2)| = 1.5
    # transition 1: Q(s, 1) - y = (1, -7) -> |w_0 . (1, -7)| = 5.0,  |w_1 . (1, -7)| = 3.0
    loss(data)
    torch.testing.assert_close(data["td_error"], torch.tensor([1.75, 5.0]))
    ours = EnvelopeQLoss(_TableQ(), num_objectives=2, num_preference_samples=2, priority="mean")
    ours.make_value_estimator(gamma=0.9)
    ours._preferences = lambda _: w
    ours(data)
    torch.testing.assert_close(data["td_error"], torch.tensor([1.625, 4.0]))
    with pytest.raises(ValueError, match="priority='max'; valid values are 'first', 'mean'"):
        EnvelopeQLoss(_TableQ(), num_objectives=2, priority="max")


def test_envelope_per_applies_no_importance_weights_when_told_as_the_authors():
    data = random_batch(B, OBS, K, num_actions=A, preference=False)
    data["priority_weight"] = torch.linspace(0.1, 3.0, B)
    torch.manual_seed(1)
    plain = make_loss(use_prioritized_weights=False)(data.clone())["loss_qvalue"]
    torch.manual_seed(1)
    unweighted = make_loss(use_prioritized_weights=False)(data.exclude("priority_weight"))["loss_qvalue"]
    torch.manual_seed(1)
    weighted = make_loss()(data.clone())["loss_qvalue"]
    torch.testing.assert_close(plain, unweighted)
    assert not torch.allclose(plain, weighted)


class _LinearInWQ(nn.Module):
    """``Q(s, a, w) = P[s, a] + w_0 R[s, a]`` for an integer state ``s`` (the observation's first entry)."""

    def __init__(self, p, r):
        super().__init__()
        self.p, self.r = nn.Parameter(torch.tensor(p)), nn.Parameter(torch.tensor(r))

    def forward(self, obs, w):
        s = obs[..., 0].long()
        return self.p[s] + w[..., 0, None, None] * self.r[s]


@pytest.mark.parametrize("end", ["alive", "truncated", "terminated"])
def test_envelope_target_by_hand(end):
    """One transition s=0 -> s'=1, two actions, two objectives, the sampled preferences pinned to
    w1 = (1, 0) and w2 = (0, 1), gamma 0.5, reward (1, -1). Online Q at s' (P + w_0 R):
    Q(s', a0, w1) = (3, 0), Q(s', a1, w1) = (0, 2), Q(s', a0, w2) = (1, 0), Q(s', a1, w2) = (0, 1).
    The envelope picks, for each w_i, the (w', a') maximising w_i . Q_online(s', a', w'):
    w1 -> (w1, a0) (score 3), w2 -> (w1, a1) (score 2: another preference's value, the envelope
    max over the sampled set). The value is the target network's there (twice the online: 2P, 2R):
    (6, 0) and (0, 4). Targets y1 = (1, -1) + 0.5 (6, 0) = (4, -1), y2 = (1, -1) + 0.5 (0, 4) = (1, 1);
    a time-limit truncation bootstraps the same, a termination gives y = r for both.
    Q(s, a, w) = 0 at s = 0, so the vector loss is mean(y^2) and the scalarised one mean((w_i . y_i)^2)."""
    p = [[[0.0, 0.0], [0.0, 0.0]], [[1.0, 0.0], [0.0, 1.0]]]
    r = [[[0.0, 0.0], [0.0, 0.0]], [[2.0, 0.0], [0.0, 1.0]]]
    loss = EnvelopeQLoss(_LinearInWQ(p, r), num_objectives=2, num_preference_samples=2)
    loss.make_value_estimator(gamma=0.5)
    with torch.no_grad():
        for v in loss.target_value_network_params.values(True, True):
            v.mul_(2.0)
    w = torch.tensor([[[1.0, 0.0], [0.0, 1.0]]])
    loss._preferences = lambda _: w
    done, terminated = end != "alive", end == "terminated"
    data = TensorDict({
        "observation": torch.tensor([[0.0]]), "action": torch.tensor([1]),
        ("next", "observation"): torch.tensor([[1.0]]), ("next", "reward"): torch.tensor([[1.0, -1.0]]),
        ("next", "done"): torch.tensor([[done]]), ("next", "terminated"): torch.tensor([[terminated]]),
    }, [1])
    y = torch.tensor([[1.0, -1.0], [1.0, -1.0]]) if terminated else torch.tensor([[4.0, -1.0], [1.0, 1.0]])
    torch.testing.assert_close(loss._envelope_next_value(data["next"], w)[0],
                               torch.tensor([[6.0, 0.0], [0.0, 4.0]]))
    loss.homotopy_lambda = 0.0
    expected_vector = (y ** 2).mean()  # alive: (16 + 1 + 1 + 1) / 4 = 4.75
    torch.testing.assert_close(loss(data)["loss_qvalue"], expected_vector)
    scalar_y = (w[0] * y).sum(-1)  # alive: (4, 1)
    assert data["td_error"].item() == pytest.approx(abs(scalar_y[0].item()))  # |w1 . (0 - y1)|: the first w
    loss.homotopy_lambda = 0.5
    torch.testing.assert_close(loss(data)["loss_qvalue"], 0.5 * expected_vector + 0.5 * (scalar_y ** 2).mean())
    if end == "alive":
        assert expected_vector.item() == pytest.approx(4.75) and data["td_error"].item() == pytest.approx(4.0)
