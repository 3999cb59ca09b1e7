"""MemberAdam (training/optim.py): Adam over a population's stacked parameters stepping only the
active members, each exactly as torch.optim.Adam on that member alone."""

import copy

import pytest
import torch

from morl_trl.training.optim import MemberAdam, NonFiniteLossError, adam, optimizer_step

P = 4


def _params(seed=0):
    g = torch.Generator().manual_seed(seed)
    actor = torch.nn.Parameter(torch.randn(P, 5, 3, generator=g))  # [P, in, out]
    critic = torch.nn.Parameter(torch.randn(2, P, 1, 3, generator=g))  # [n, P, 1, out]: an ensemble's bias
    return actor, critic


def _loss(actor, critic, x):
    # every member's loss depends only on its own slices (as the population's summed losses)
    return (torch.tanh(x @ actor).pow(2).sum() + (critic * x.mean()).sin().sum())


def test_member_adam_steps_each_active_member_as_a_standalone_adam_on_that_member():
    actor, critic = _params()
    opt = MemberAdam([{"params": [actor], "member_dim": 0}, {"params": [critic], "member_dim": 1}],
                     lr=1e-2, population=P, eps=1e-4)
    # member 2 alone, as a standalone Adam on copies of its slices
    ref_a = torch.nn.Parameter(actor.detach()[2].clone())
    ref_c = torch.nn.Parameter(critic.detach()[:, 2].clone())
    ref = torch.optim.Adam([ref_a, ref_c], lr=1e-2, eps=1e-4, foreach=False)
    schedule = [[2], [2, 0], [0], [2], [1, 2, 3], [2]] * 3  # who is active at each step
    frozen = {}
    g = torch.Generator().manual_seed(1)
    for active in schedule:
        x = torch.randn(P, 7, 5, generator=g)
        opt.members = torch.tensor([i in active for i in range(P)])
        before = (actor.detach().clone(), critic.detach().clone(),
                  {k: v.clone() for k, v in opt.state[actor].items()} if opt.state[actor] else None)
        optimizer_step(_loss(actor, critic, x), [opt])
        if 2 in active:  # member 2's gradient from the population's backward: only the two Adams differ
            ref_a.grad, ref_c.grad = actor.grad[2].clone(), critic.grad[:, 2].clone()
            ref.step()
        for p in range(P):
            if p not in active:  # untouched, bit for bit: parameters, moments, step count
                assert torch.equal(actor[p], before[0][p]) and torch.equal(critic[:, p], before[1][:, p])
                if before[2] is not None:
                    for k in ("exp_avg", "exp_avg_sq"):
                        assert torch.equal(opt.state[actor][k][p], before[2][k][p])
                    assert opt.state[actor]["step"][p] == before[2]["step"][p]
        frozen[tuple(active)] = True
    torch.testing.assert_close(actor.detach()[2], ref_a.detach(), rtol=1e-6, atol=1e-7)
    torch.testing.assert_close(critic.detach()[:, 2], ref_c.detach(), rtol=1e-6, atol=1e-7)
    torch.testing.assert_close(opt.state[actor]["exp_avg_sq"][2], ref.state[ref_a]["exp_avg_sq"], rtol=1e-6, atol=0)
    # each member's own count: member 2 was active 15 times, 0 6 times, 1 and 3 3 times
    assert opt.state[actor]["step"].tolist() == [6.0, 3.0, 15.0, 3.0]
    assert opt.state[critic]["step"].tolist() == [6.0, 3.0, 15.0, 3.0]


def test_member_adam_with_every_member_active_is_torch_adam_over_the_stacked_tensors():
    a1, c1 = _params()
    a2, c2 = (torch.nn.Parameter(t.detach().clone()) for t in (a1, c1))
    mine = MemberAdam([{"params": [a1]}, {"params": [c1], "member_dim": 1}], lr=3e-3, population=P)
    ref = torch.optim.Adam([a2, c2], lr=3e-3, foreach=False)
    g = torch.Generator().manual_seed(3)
    for _ in range(5):
        x = torch.randn(P, 7, 5, generator=g)
        optimizer_step(_loss(a1, c1, x), [mine])
        optimizer_step(_loss(a2, c2, x), [ref])
    torch.testing.assert_close(a1, a2, rtol=1e-6, atol=1e-7)
    torch.testing.assert_close(c1, c2, rtol=1e-6, atol=1e-7)


def test_a_torch_adam_state_loads_with_its_count_for_every_member_and_continues_identically():
    a1, c1 = _params()
    old = adam([c1], lr=1e-3)  # what a concurrent MORL/D run saved (fused Adam, one scalar step)
    for _ in range(3):
        optimizer_step(_loss(a1, c1, torch.ones(P, 2, 5)), [old])
    mine = MemberAdam([c1], lr=1e-3, population=P, member_dim=1)
    mine.load_state_dict(copy.deepcopy(old.state_dict()))  # (a state_dict shares the live moments)
    assert mine.state[c1]["step"].tolist() == [3.0] * P and mine.param_groups[0]["member_dim"] == 1
    c2 = torch.nn.Parameter(c1.detach().clone())
    ref = torch.optim.Adam([c2], lr=1e-3, foreach=False)
    ref.load_state_dict(copy.deepcopy(old.state_dict()))
    x = torch.full((P, 2, 5), 0.5)
    mine.members = torch.tensor([True, False, True, True])
    optimizer_step(_loss(a1, c1, x), [mine])
    optimizer_step(_loss(a1, c2, x), [ref])
    torch.testing.assert_close(c1[:, [0, 2, 3]], c2[:, [0, 2, 3]], rtol=1e-6, atol=1e-7)
    assert mine.state_dict()["state"][0]["step"].tolist() == [4.0, 3.0, 4.0, 4.0]


def test_member_adam_goes_through_the_non_finite_guard_and_refuses_a_parameter_without_the_population():
    actor, critic = _params()
    opt = MemberAdam([actor], lr=1e-3, population=P)
    before = actor.detach().clone()
    with pytest.raises(NonFiniteLossError, match="nan"):
        optimizer_step(actor.sum() * float("nan"), [opt])
    assert torch.equal(actor, before) and not opt.state[actor]
    found = optimizer_step(actor.sum() * float("inf"), [opt], on_device=True)  # skipped on the device
    assert found.item() == 1.0 and torch.equal(actor, before)
    with pytest.raises(ValueError, match=r"shape \(2, 4, 1, 3\) has no population dimension 0 of size 3"):
        MemberAdam([critic], lr=1e-3, population=3)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_subnormal_second_moments_give_plain_adams_values_bit_for_bit(dtype):
    """MemberAdam takes Adam's square root of max(v, tiny) (subnormal square roots are ~50x slower on a
    CPU core); parameters, moments and counts stay torch's foreach Adam's bit for bit."""
    tiny = torch.finfo(dtype).tiny
    g = torch.Generator().manual_seed(3)
    w = torch.nn.Parameter(torch.randn(2, 6, dtype=dtype, generator=g))  # 2 members
    ref = torch.nn.Parameter(w.detach().clone())
    opt = MemberAdam([w], lr=1e-3, population=2, fused=False)  # (the foreach path: the fused kernel takes v as it is)
    plain = torch.optim.Adam([ref], lr=1e-3, foreach=True)
    # member 0: second moments at zero, subnormal, just under and at the smallest normal, and normal;
    # member 1: ordinary; every member's first step count 10
    v = torch.tensor([0.0, tiny / 8, tiny / 1024, tiny * 0.999, tiny, 1e-6], dtype=dtype)
    for o, p in ((opt, w), (plain, ref)):
        o.state[p]["step"] = torch.full((2,), 10.0) if o is opt else torch.tensor(10.0)
        o.state[p]["exp_avg"] = torch.full((2, 6), 1e-3, dtype=dtype)
        o.state[p]["exp_avg_sq"] = torch.stack([v, torch.full((6,), 1e-4, dtype=dtype)])
    assert (o.state[p]["exp_avg_sq"][0, 1:4] < tiny).all()
    grads = [torch.zeros(2, 6, dtype=dtype), torch.randn(2, 6, dtype=dtype, generator=g) * 1e-21,
             torch.randn(2, 6, dtype=dtype, generator=g)]
    for grad in grads:  # zero gradients keep v subnormal (and push it down), tiny ones too, then ordinary ones
        w.grad, ref.grad = grad.clone(), grad.clone()
        opt.step()
        plain.step()
        assert torch.equal(w.detach(), ref.detach())
        for k in ("exp_avg", "exp_avg_sq"):
            assert torch.equal(opt.state[w][k], plain.state[ref][k])
    assert opt.state[w]["step"].tolist() == [13.0, 13.0]
    assert opt._floors is not None  # (the floored square root did run)


def test_an_eps_too_small_for_the_floor_falls_back_to_plain_adam():
    w = torch.nn.Parameter(torch.ones(2, 3))
    opt = MemberAdam([w], lr=1e-3, population=2, eps=1e-30, fused=False)
    assert opt._sqrt_floors([torch.zeros(3)], 1e-30, 0.999) is None
    assert opt._sqrt_floors([torch.zeros(3)], 1e-8, 1.0) is None
    floors = opt._sqrt_floors([torch.zeros(3), torch.zeros(2, 2)], 1e-8, 0.999)
    assert [f.shape for f in floors] == [torch.Size([3]), torch.Size([2, 2])]
    assert all((f == torch.finfo(torch.float32).tiny).all() for f in floors)
    w.grad = torch.ones(2, 3)
    ref = torch.nn.Parameter(torch.ones(2, 3))
    ref.grad = torch.ones(2, 3)
    opt.step()
    torch.optim.Adam([ref], lr=1e-3, eps=1e-30, foreach=True).step()
    assert torch.equal(w.detach(), ref.detach())


def _standalone_fused(actor, critic, m):
    """Member ``m``'s networks on their own, each parameter a tensor of its own (the ensemble's two critics too),
    with ``torch.optim.Adam(fused=True)``."""
    a = torch.nn.Parameter(actor.detach()[m].clone())
    cs = [torch.nn.Parameter(critic.detach()[i, m].clone()) for i in range(critic.shape[0])]
    return a, cs, torch.optim.Adam([a, *cs], lr=1e-2, eps=1e-4, fused=True)


@pytest.mark.parametrize("schedule", [[[0, 1, 2, 3]] * 4 + [[2], [1, 3], [0, 1, 2, 3], [3]],  # all, then subsets
                                      [[1], [0, 2, 3], [1]]])
def test_fused_member_adam_is_each_members_fused_torch_adam(schedule):
    """The default (fused) step: every active member's slices in one kernel call, each with its own count,
    equal to a standalone torch.optim.Adam(fused=True) on that member's own tensors given the same gradients.

    To float rounding, not bit for bit: the one kernel runs over the members' blocks at other offsets than over
    each member's own tensor, and a CPU may round an element of a vector lane and one of the scalar tail
    differently (an FMA in one, a multiply and an add in the other). A skipped step (lr 1e-2) or a wrong count
    (bias correction) is 1e-3 or more; the tolerance is 1e-6."""
    actor, critic = _params()
    opt = MemberAdam([{"params": [actor], "member_dim": 0}, {"params": [critic], "member_dim": 1}],
                     lr=1e-2, population=P, eps=1e-4)
    assert opt.fused
    refs = [_standalone_fused(actor, critic, m) for m in range(P)]
    g = torch.Generator().manual_seed(5)
    for active in schedule:
        x = torch.randn(P, 7, 5, generator=g)
        opt.members = torch.tensor([i in active for i in range(P)])
        optimizer_step(_loss(actor, critic, x), [opt])
        for m in active:  # the population's gradient of member m, so that only the two Adams are compared
            a, cs, ref = refs[m]
            a.grad = actor.grad[m].clone()
            for i, c in enumerate(cs):
                c.grad = critic.grad[i, m].clone()
            ref.step()
    close = dict(rtol=1e-6, atol=1e-6)
    for m, (a, cs, ref) in enumerate(refs):
        torch.testing.assert_close(actor.detach()[m], a.detach(), **close)
        for i, c in enumerate(cs):
            torch.testing.assert_close(critic.detach()[i, m], c.detach(), **close)
            for k in ("exp_avg", "exp_avg_sq"):
                torch.testing.assert_close(opt.state[critic][k][i, m], ref.state[c][k], **close)
        assert opt.state[actor]["step"][m] == ref.state[a]["step"]
    counts = [float(sum(m in active for active in schedule)) for m in range(P)]
    assert opt.state[actor]["step"].tolist() == opt.state[critic]["step"].tolist() == counts


def test_fused_and_foreach_member_adam_agree_to_float_rounding_and_a_loaded_state_keeps_its_counts():
    a1, c1 = _params()
    a2, c2 = (torch.nn.Parameter(t.detach().clone()) for t in (a1, c1))
    fused = MemberAdam([{"params": [a1]}, {"params": [c1], "member_dim": 1}], lr=3e-3, population=P)
    plain = MemberAdam([{"params": [a2]}, {"params": [c2], "member_dim": 1}], lr=3e-3, population=P, fused=False)
    g = torch.Generator().manual_seed(7)
    for active in ([0, 1, 2, 3], [1], [0, 1, 2, 3]):
        x = torch.randn(P, 7, 5, generator=g)
        for opt, (a, c) in ((fused, (a1, c1)), (plain, (a2, c2))):
            opt.members = torch.tensor([i in active for i in range(P)])
            optimizer_step(_loss(a, c, x), [opt])
    torch.testing.assert_close(a1, a2, rtol=1e-6, atol=1e-7)
    torch.testing.assert_close(c1, c2, rtol=1e-6, atol=1e-7)
    again = MemberAdam([{"params": [a1]}, {"params": [c1], "member_dim": 1}], lr=3e-3, population=P)
    again.load_state_dict(copy.deepcopy(fused.state_dict()))
    assert again.fused and again.state[a1]["step"].tolist() == [2.0, 3.0, 2.0, 2.0]


def test_fused_member_adam_falls_back_to_the_per_member_step_on_a_non_contiguous_gradient():
    w = torch.nn.Parameter(torch.randn(P, 3, 2))
    ref = torch.nn.Parameter(w.detach().clone())
    opt = MemberAdam([w], lr=1e-2, population=P)
    plain = MemberAdam([ref], lr=1e-2, population=P, fused=False)
    grad = torch.randn(P, 2, 3).transpose(1, 2)  # (a transposed view: the kernel would read it flat)
    assert not grad.is_contiguous()
    w.grad, ref.grad = grad, grad.contiguous()
    opt.step()
    plain.step()
    assert torch.equal(w.detach(), ref.detach())
