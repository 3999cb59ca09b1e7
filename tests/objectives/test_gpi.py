"""GPI action selection against a brute-force max; the GPI loss against a hand computation."""

import itertools

import pytest
import torch
from tensordict import TensorDict

from morl_trl.objectives import GPILoss, GPIPolicy, GPIQNetwork, gpi_action
from morl_trl.objectives.gpi import thresholded_huber


def test_gpi_action_matches_brute_force():
    g = torch.Generator().manual_seed(0)
    q = torch.randn(7, 4, 3, 2, generator=g)  # [B, M, A, k]
    w = torch.rand(7, 2, generator=g)
    w = w / w.sum(-1, keepdim=True)
    action, policy = gpi_action(q, w)
    for b in range(7):
        best, arg = -float("inf"), None
        for i, a in itertools.product(range(4), range(3)):
            v = float(w[b] @ q[b, i, a])
            if v > best:
                best, arg = v, (i, a)
        assert (int(policy[b]), int(action[b])) == arg


def test_gpi_policy_uses_member_zero_over_the_support():
    torch.manual_seed(0)
    qnet = GPIQNetwork(5, 4, 3, hidden=(16, 16), dropout=0.0).eval()
    support = torch.tensor([[1.0, 0, 0], [0, 1.0, 0], [0.2, 0.3, 0.5]])
    obs, w = torch.randn(6, 5), torch.tensor([[0.3, 0.3, 0.4]]).expand(6, 3)
    td = GPIPolicy(qnet, support)(TensorDict(observation=obs, preference=w, batch_size=[6]))
    with torch.no_grad():
        for b in range(6):
            scores = torch.stack([qnet(obs[b:b + 1], support[i:i + 1])[0, 0] @ w[b] for i in range(3)])  # [M, A]
            assert int(td["action"][b]) == int(scores.max(0).values.argmax())
            assert int(td["policy_index"][b]) == int(scores.max(1).values.argmax())


def test_ensemble_members_are_independent_networks():
    qnet = GPIQNetwork(3, 2, 2, hidden=(8, 8), num_nets=3, dropout=0.0)
    out = qnet(torch.ones(4, 3), torch.full((4, 2), 0.5))
    assert out.shape == (3, 4, 2, 2)
    assert not torch.allclose(out[0], out[1])
    torch.testing.assert_close(qnet(torch.ones(4, 3), torch.full((4, 2), 0.5), members=slice(1, 2))[0], out[1])


def _batch(b=6, obs=4, k=2, a=3, seed=0):
    g = torch.Generator().manual_seed(seed)
    return TensorDict({
        "observation": torch.randn(b, obs, generator=g), "action": torch.randint(a, (b,), generator=g),
        ("next", "observation"): torch.randn(b, obs, generator=g), ("next", "reward"): torch.randn(b, k, generator=g),
        ("next", "done"): torch.tensor([[False], [True]] * (b // 2)),
        ("next", "terminated"): torch.tensor([[False], [True]] * (b // 2))}, [b])


def test_loss_matches_the_authors_update_by_hand():
    torch.manual_seed(0)
    qnet = GPIQNetwork(4, 3, 2, hidden=(16, 16), dropout=0.0)
    loss = GPILoss(qnet, min_priority=0.01)
    loss.make_value_estimator(gamma=0.9)
    w = torch.tensor([0.3, 0.7])
    loss.set_weights(w, w.unsqueeze(0))  # support of one weight: no doubling
    with torch.no_grad():  # make the target differ from the online network
        for p in loss.target_value_network_params.values(True, True):
            p.add_(0.1)
    data = _batch()
    out = loss(data)
    with torch.no_grad(), loss.target_value_network_params.to_module(loss.value_network):
        qt = qnet(data["next", "observation"], w.expand(6, 2))  # [E, B, A, k]
    with loss.value_network_params.to_module(loss.value_network):
        q = qnet(data["observation"], w.expand(6, 2))
    want_loss, tds = 0.0, []
    for b in range(6):
        # per action, the member with the lowest w.Q; then the greedy action under w
        per_action = torch.stack([qt[int((qt[:, b, a] @ w).argmin()), b, a] for a in range(3)])
        nxt = per_action[int((per_action @ w).argmax())]
        y = data["next", "reward"][b] + 0.9 * (1 - float(data["next", "terminated"][b])) * nxt
        tds.append(torch.stack([q[e, b, int(data["action"][b])] - y for e in range(2)]))
    td = torch.stack(tds, 1).abs()  # [E, B, k]
    want_loss = torch.stack([thresholded_huber(td[e], 0.01) for e in range(2)]).mean()
    torch.testing.assert_close(out["loss_qvalue"], want_loss)
    want_prio = (td.max(0).values @ w).abs().clamp(min=0.01)
    torch.testing.assert_close(data["td_error"], want_prio.detach())


def test_doubled_batch_and_gpi_priorities():
    torch.manual_seed(0)
    loss = GPILoss(GPIQNetwork(4, 3, 2, hidden=(16, 16)), gpi_pd=True)
    loss.make_value_estimator(gamma=0.99)
    loss.set_weights(torch.tensor([1.0, 0.0]), torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]]))
    data = _batch()
    out = loss(data)
    out["loss_qvalue"].backward()
    assert data["td_error"].shape == (6,) and bool((data["td_error"] >= 0.01).all())
    prio = loss.priorities(_batch())
    assert prio.shape == (6,) and bool((prio >= 0.01).all())


def test_gpi_target_is_at_least_the_td_target_under_w():
    # the GPI target maximises over the support (which includes w): never below the plain target's scalarisation
    torch.manual_seed(1)
    loss = GPILoss(GPIQNetwork(4, 3, 2, hidden=(16, 16), dropout=0.0), gpi_pd=True)
    loss.make_value_estimator(gamma=0.99)
    w = torch.tensor([0.4, 0.6])
    loss.set_weights(w, torch.tensor([[0.4, 0.6], [1.0, 0.0], [0.0, 1.0]]))
    nxt = torch.randn(10, 4)
    W = w.expand(10, 2)
    plain = loss.td_target_value(nxt, W) @ w
    gpi = loss.gpi_target_value(nxt, W, loss.weight_support) @ w
    assert bool((gpi >= plain - 1e-6).all())


def test_bad_arguments_raise():
    with pytest.raises(ValueError, match="GPIQNetwork"):
        GPILoss(torch.nn.Linear(2, 2))
    loss = GPILoss(GPIQNetwork(4, 3, 2, hidden=(8,)))
    with pytest.raises(ValueError, match="weight must be"):
        loss.set_weights(torch.tensor([1.0, 0.0, 0.0]), torch.eye(2))


# ------------------------------------------------------------------ continuous actions
from morl_trl.objectives.gpi import GPIActor, GPIContinuousLoss, GPIContinuousPolicy, GPIVectorCritic  # noqa: E402


def _continuous(seed=0):
    torch.manual_seed(seed)
    actor = GPIActor(5, 2, 3, low=-torch.ones(3), high=2 * torch.ones(3), hidden=(16,))
    critic = GPIVectorCritic(5, 3, 2, hidden=(16, 16), dropout=0.0)
    return actor, critic


def test_actor_respects_the_action_bounds():
    actor, _ = _continuous()
    a = actor(torch.randn(64, 5) * 100, torch.full((64, 2), 0.5), noise=0.2, noise_clip=0.5)
    assert bool((a >= -1).all() and (a <= 2).all())


def test_continuous_gpi_picks_the_best_candidate_by_brute_force():
    actor, critic = _continuous()
    support = torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.3, 0.7]])
    obs, w = torch.randn(4, 5), torch.tensor([[0.6, 0.4]]).expand(4, 2)
    act = GPIContinuousPolicy(actor, critic, support, gpi=True)(
        TensorDict(observation=obs, preference=w, batch_size=[4]))["action"]
    with torch.no_grad():
        for b in range(4):
            cands = [actor(obs[b:b + 1], support[j:j + 1])[0] for j in range(3)]
            scores = torch.tensor([[float(critic(obs[b:b + 1], cands[j][None], support[i:i + 1])[0, 0] @ w[b])
                                    for j in range(3)] for i in range(3)])
            j = int(scores.max(0).values.argmax())
            torch.testing.assert_close(act[b], cands[j])


def test_continuous_critic_loss_by_hand():
    actor, critic = _continuous()
    loss = GPIContinuousLoss(actor, critic, policy_noise=0.0, noise_clip=0.5)
    loss.make_value_estimator(gamma=0.9)
    w = torch.tensor([0.25, 0.75])
    loss.set_weights(w, w[None])
    g = torch.Generator().manual_seed(3)
    td = TensorDict({"observation": torch.randn(6, 5, generator=g), "action": torch.rand(6, 3, generator=g),
                     ("next", "observation"): torch.randn(6, 5, generator=g),
                     ("next", "reward"): torch.randn(6, 2, generator=g),
                     ("next", "done"): torch.zeros(6, 1, dtype=torch.bool),
                     ("next", "terminated"): torch.zeros(6, 1, dtype=torch.bool)}, [6])
    out = loss(td)
    with torch.no_grad():
        na = actor(td["next", "observation"], w.expand(6, 2))  # target == online at init
        qt = critic(td["next", "observation"], na, w.expand(6, 2))  # [E, B, k]
        pick = (qt @ w).argmin(0)
        y = td["next", "reward"] + 0.9 * qt[pick, torch.arange(6)]
        q = critic(td["observation"], td["action"], w.expand(6, 2))
        want = torch.stack([((q[e] - y) ** 2).mean() for e in range(2)]).mean()
    torch.testing.assert_close(out["loss_qvalue"], want)
    torch.testing.assert_close(td["td_error"], ((q[0] - y).abs() * 0.05 @ w).clamp(min=0.1))


def test_image_observations_use_one_cnn_per_member():
    torch.manual_seed(0)
    qnet = GPIQNetwork((4, 84, 84), 5, 3, hidden=(32, 16), dropout=0.0, layer_norm=False)
    obs = torch.randint(0, 255, (2, 4, 84, 84), dtype=torch.uint8)
    out = qnet(obs, torch.full((2, 3), 1 / 3))
    assert out.shape == (2, 2, 5, 3) and not torch.allclose(out[0], out[1])
    td = GPIPolicy(qnet, torch.eye(3))(TensorDict(observation=obs, preference=torch.full((2, 3), 1 / 3), batch_size=[2]))
    assert td["action"].shape == (2,)
    loss = GPILoss(qnet)
    loss.make_value_estimator(gamma=0.99)
    loss.set_weights(torch.tensor([1.0, 0, 0]), torch.eye(3))
    data = TensorDict({"observation": obs, "action": torch.tensor([0, 4]), ("next", "observation"): obs,
                       ("next", "reward"): torch.zeros(2, 3), ("next", "done"): torch.zeros(2, 1, dtype=torch.bool),
                       ("next", "terminated"): torch.zeros(2, 1, dtype=torch.bool)}, [2])
    loss(data)["loss_qvalue"].backward()


def test_dropout_keeps_the_expectation_and_rate():
    from morl_trl.objectives.batched import batched_dropout as dropout

    torch.manual_seed(0)
    x = torch.ones(200_000)
    y = dropout(x, 0.1, True)
    assert abs(float((y == 0).float().mean()) - 0.1) < 0.005
    assert abs(float(y.mean()) - 1.0) < 0.01
    assert dropout(x, 0.1, False) is x


def test_continuous_gpi_policy_on_an_env_without_context_parameters():
    """A foreign env (MO-Gymnasium's mo-mountaincarcontinuous-v0) has contexts of width 0 and one
    context: the policy acts as without a context table (it raised on the reshape before)."""
    from tensordict import TensorDict

    from morl_trl.objectives.gpi import GPIActor, GPIContinuousPolicy, GPIVectorCritic

    torch.manual_seed(0)
    actor = GPIActor(4, 2, 3, low=-torch.ones(3), high=torch.ones(3), hidden=(8,))
    critic = GPIVectorCritic(4, 3, 2, hidden=(8,))
    td = TensorDict(observation=torch.zeros(5, 4), preference=torch.full((5, 2), .5), context=torch.zeros(5, 0),
                    batch_size=[5])
    with_table = GPIContinuousPolicy(actor, critic, support=torch.eye(2), gpi=True, context_table=torch.zeros(1, 0))
    without = GPIContinuousPolicy(actor, critic, support=torch.eye(2), gpi=True)
    assert torch.equal(with_table(td.clone())["action"], without(td.clone())["action"])


def test_continuous_gpi_loss_state_loads_with_a_grown_weight_support():
    # found by the parity benchmark: `morl_trl.train("gpi_ls", env="mo-mountaincarcontinuous-v0")` failed
    # when the trained policy was reloaded (the borrowed loader's zero-argument super())
    from morl_trl.objectives.gpi import GPIActor, GPIContinuousLoss, GPIVectorCritic

    torch.manual_seed(0)
    make = lambda: GPIContinuousLoss(GPIActor(5, 2, 3, low=-torch.ones(3), high=torch.ones(3), hidden=(16,)),
                                     GPIVectorCritic(5, 3, 2, hidden=(16,)))
    trained, fresh = make(), make()
    support = torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]])
    trained.set_weights(torch.tensor([0.25, 0.75]), support)
    fresh.load_state_dict(trained.state_dict())
    assert fresh.weight_support.tolist() == support.tolist()
    assert fresh.current_weight.tolist() == [0.25, 0.75]
    for a, b in zip(trained.parameters(), fresh.parameters()):
        assert torch.equal(a, b)
