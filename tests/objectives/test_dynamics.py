"""The probabilistic dynamics ensemble fits a known linear system."""

import torch
from tensordict import TensorDict

from morl_trl.objectives import DynamicsLoss, ProbabilisticEnsemble, fit_dynamics


def _linear_system(n, g):
    # s' = A s + B onehot(a), r = C s  (2 objectives, 3 actions)
    A = torch.tensor([[0.9, 0.1, 0.0], [0.0, 0.8, 0.2], [0.1, 0.0, 0.7]])
    B = torch.tensor([[0.5, 0.0, -0.5], [0.0, 0.3, 0.0], [-0.2, 0.2, 0.1]])
    C = torch.tensor([[1.0, 0.0, -1.0], [0.0, 2.0, 0.5]])
    s = torch.randn(n, 3, generator=g)
    a = torch.randint(3, (n,), generator=g)
    nxt = s @ A.T + torch.nn.functional.one_hot(a, 3).float() @ B.T
    return TensorDict({"observation": s, "action": a, ("next", "observation"): nxt, ("next", "reward"): s @ C.T}, [n])


def test_fits_a_known_linear_system():
    torch.manual_seed(0)
    g = torch.Generator().manual_seed(0)
    model = ProbabilisticEnsemble(3 + 3, 2 + 3, ensemble_size=3, hidden=(64, 64), num_elites=2)
    loss = DynamicsLoss(model, num_actions=3)
    x, y = loss.inputs_targets(_linear_system(3000, g))
    fit_dynamics(loss, x, y, lr=3e-3, max_epochs=60, generator=g)
    test = _linear_system(500, g)
    xt, yt = loss.inputs_targets(test)
    pred, unc = model.step(xt, deterministic=True)
    mse = (pred - yt).pow(2).mean()
    assert mse < 0.01 * yt.var()  # explains more than 99% of the variance
    assert unc.shape == (500,) and bool((unc > 0).all())
    assert model.elites.shape == (2,)


def test_uncertainty_grows_off_the_data():
    torch.manual_seed(0)
    g = torch.Generator().manual_seed(1)
    model = ProbabilisticEnsemble(6, 5, ensemble_size=4, hidden=(32, 32))
    loss = DynamicsLoss(model, num_actions=3)
    x, y = loss.inputs_targets(_linear_system(1500, g))
    fit_dynamics(loss, x, y, lr=3e-3, max_epochs=30, generator=g)
    _, near = model.step(x[:200], deterministic=True)
    far = x[:200].clone()
    far[:, :3] *= 20
    _, away = model.step(far, deterministic=True)
    assert away.mean() > 3 * near.mean()
