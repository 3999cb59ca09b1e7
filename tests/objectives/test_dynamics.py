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


def test_each_fit_builds_a_fresh_adam_with_weight_decay_rising_by_layer(monkeypatch):
    # SPEC §6 GPI-PD model-based part: "a fresh Adam each fit, weight decay 2.5e-5 to 1e-4 by layer"
    built = []

    class RecordingAdam(torch.optim.Adam):
        def __init__(self, params, **kwargs):
            super().__init__(params, **kwargs)
            built.append(self)

    monkeypatch.setattr(torch.optim, "Adam", RecordingAdam)
    g = torch.Generator().manual_seed(0)
    model = ProbabilisticEnsemble(3 + 3, 2 + 3, ensemble_size=2, hidden=(8, 8, 8, 8), num_elites=1)
    loss = DynamicsLoss(model, num_actions=3)
    x, y = loss.inputs_targets(_linear_system(64, g))
    fit_dynamics(loss, x, y, max_epochs=2, generator=g)
    fit_dynamics(loss, x, y, max_epochs=2, generator=g)
    assert len(built) == 2 and built[0] is not built[1]
    decays = [group["weight_decay"] for group in built[1].param_groups[:-1]]  # the last group: the logvar bounds
    assert decays == [2.5e-5, 5e-5, 7.5e-5, 7.5e-5, 1e-4]  # one per layer: 4 hidden + the output
    assert built[1].param_groups[-1]["weight_decay"] == 0
