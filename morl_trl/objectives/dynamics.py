"""GPI-PD's model: a probabilistic ensemble predicting the vector reward and the next observation.

* :class:`ProbabilisticEnsemble`: ``E`` Gaussian MLPs (one batched module) on
  ``x = (s, onehot(a))`` (or ``(s, a)`` for continuous actions) predicting
  ``y = (r, s' - s)``: mean and log-variance, the log-variance soft-clamped between learned
  bounds (the authors' ``ProbabilisticEnsemble``: 5 members, 2 elites, orthogonal init with
  ReLU gain, bounds initialised at 0.5 and -10).
* :class:`DynamicsLoss`: its Gaussian negative log-likelihood on a batch of transitions, plus
  ``0.01 * (sum max_logvar - sum min_logvar)``, as a TorchRL ``LossModule``.
* :func:`fit_dynamics`: the authors' ``fit``: a bootstrap per member, mini-batches of 256,
  a holdout of 10% (at most 5000) for early stopping (5 epochs without a 1% improvement, at
  most 200 epochs) and to pick the elites; Adam with the per-layer weight decays.
* :meth:`ProbabilisticEnsemble.step`: one model step: a sample from a random elite per row,
  with the uncertainty ``sum_j std_j`` of the ensemble's mixture (Lakshminarayanan et al., 2017).

Example:
    >>> model = ProbabilisticEnsemble(3, 2, hidden=(16, 16))
    >>> mean, logvar = model(torch.zeros(4, 3))
    >>> mean.shape, logvar.shape
    (torch.Size([5, 4, 2]), torch.Size([5, 4, 2]))
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import dispatch
from tensordict.utils import NestedKey
from torch import nn
from torch.nn import functional as F
from torchrl.objectives.common import LossModule

from morl_trl.objectives.batched import BatchedLinear

__all__ = ["ProbabilisticEnsemble", "DynamicsLoss", "fit_dynamics", "model_inputs"]

_DECAYS = (0.000025, 0.00005, 0.000075, 0.000075, 0.0001)


class ProbabilisticEnsemble(nn.Module):
    """``E`` Gaussian MLPs ``x [N, in] -> (mean, logvar) [E, N, out]``.

    Args:
        input_dim, output_dim: widths of ``x`` and ``y``.
        ensemble_size: ``E`` (the authors: 5).
        hidden: hidden widths (the authors' GPI-PD: ``[256, 256, 256]``; LavaGrid, Humanoid: ``[512, 512]``).
        num_elites: members sampled from (the authors: 2).
        normalize_inputs: standardise ``x`` with the statistics of the last fit (the authors' GPI-PD: off).
        max_logvar, min_logvar: initial values of the learned soft bounds of the log-variance (the
            authors' ``dynamics_max_logvar_scale`` 0.5, Humanoid 0.1, and ``-dynamics_min_logvar_scale``
            -10; ``probabilistic_ensemble.py:29-43``).
    """

    def __init__(self, input_dim: int, output_dim: int, *, ensemble_size: int = 5, hidden=(256, 256, 256),
                 num_elites: int = 2, normalize_inputs: bool = False, max_logvar: float = 0.5,
                 min_logvar: float = -10.0) -> None:
        super().__init__()
        if not min_logvar < max_logvar:
            raise ValueError(f"min_logvar must be below max_logvar, got min_logvar={min_logvar}, max_logvar={max_logvar}")
        if not 1 <= num_elites <= ensemble_size:
            raise ValueError(f"num_elites must lie in [1, ensemble_size={ensemble_size}], got {num_elites}")
        self.input_dim, self.output_dim = input_dim, output_dim
        self.ensemble_size, self.num_elites = ensemble_size, num_elites
        self.normalize_inputs = normalize_inputs
        widths = (input_dim, *hidden, 2 * output_dim)
        gain = nn.init.calculate_gain("relu")
        self.layers = nn.ModuleList(BatchedLinear(ensemble_size, a, b, gain=gain) for a, b in zip(widths[:-1], widths[1:]))
        self.register_buffer("inputs_mu", torch.zeros(1, input_dim))
        self.register_buffer("inputs_sigma", torch.ones(1, input_dim))
        self.register_buffer("elites", torch.arange(num_elites))
        self.max_logvar = nn.Parameter(torch.full((1, output_dim), float(max_logvar)))
        self.min_logvar = nn.Parameter(torch.full((1, output_dim), float(min_logvar)))

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``x`` ``[N, in]`` (the same rows for every member) or ``[E, N, in]`` (one set per member)."""
        if self.normalize_inputs:
            x = (x - self.inputs_mu) / self.inputs_sigma
        h = x if x.ndim == 3 else x.unsqueeze(0).expand(self.ensemble_size, *x.shape)
        for layer in self.layers[:-1]:
            h = F.relu(layer(h))
        mean, logvar = self.layers[-1](h).chunk(2, -1)
        logvar = self.max_logvar - F.softplus(self.max_logvar - logvar)
        logvar = self.min_logvar + F.softplus(logvar - self.min_logvar)
        return mean, logvar

    @torch.no_grad()
    def step(self, x: torch.Tensor, *, deterministic: bool = False,
             generator: torch.Generator | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """``(y [N, out], uncertainty [N])``: each row from a random elite (its mean, or a sample),
        and ``sum_j sqrt(mixture variance_j)`` of the whole ensemble."""
        mean, logvar = self(x)
        var = logvar.exp()
        mix_mean = mean.mean(0)
        mix_var = (mean.pow(2) + var).mean(0) - mix_mean.pow(2)
        uncertainty = (mix_var + 1e-12).clamp(min=0).sqrt().sum(-1)
        n = x.shape[-2]
        pick = self.elites[torch.randint(self.num_elites, (n,), generator=generator, device=x.device)]
        rows = torch.arange(n, device=x.device)
        y = mean[pick, rows]
        if not deterministic:
            noise = torch.randn(y.shape, generator=generator, device=x.device)
            y = y + var[pick, rows].sqrt() * noise
        return y, uncertainty


#: the authors' termination functions of imagined transitions (their ``mo_utils/model_based/utils.py:59-162``)
#: by training id; a domain not listed never terminates (HalfCheetah, LavaGrid: ``termination_fn_false``)
MODEL_TERMINATION = {"MOLunarLanderDR-v0": "lunar_lander", "MOHopperDR-v5": "hopper", "MOHumanoidDR-v5": "humanoid"}


def model_termination(kind: str | None, next_obs: torch.Tensor, reward: torch.Tensor, *,
                      hopper_abs: bool = False) -> torch.Tensor:
    """``[N]`` bool: whether the imagined transition ends its episode, as the authors' termination
    functions on the last state of the (history-stacked) predicted observation (SPEC §6):

    * ``"lunar_lander"`` (state 8): ``|x| >= 1`` or (``reward[0] != 0`` and both leg contacts ``>= 0.95``);
    * ``"hopper"`` (state 11): not (finite, ``state[1:] < 100``, height ``> 0.7``, ``|angle| < 0.2``); the
      authors' ``np.abs(state[1:] < 100)`` takes the abs of the comparison (a slip):
      ``hopper_abs=True`` checks ``|state[1:]| < 100`` as intended;
    * ``"humanoid"`` (state 348): not ``1 < z < 2``;
    * ``None``: never.

    Example:
        >>> obs = torch.tensor([[1.2, 0.1] + [0.0] * 9, [1.2, 0.3] + [0.0] * 9, [1.2, 0.1, -500.0] + [0.0] * 8])
        >>> model_termination("hopper", obs, torch.zeros(3, 3)).tolist()
        [False, True, False]
        >>> model_termination("hopper", obs, torch.zeros(3, 3), hopper_abs=True).tolist()
        [False, True, True]
    """
    n = next_obs.shape[0]
    if kind is None:
        return torch.zeros(n, dtype=torch.bool, device=next_obs.device)
    if kind == "lunar_lander":
        s = next_obs[:, -8:]
        legs = (s[:, 6] >= 0.95) & (s[:, 7] >= 0.95)
        return (s[:, 0].abs() >= 1) | ((reward[:, 0] != 0) & legs)
    if kind == "hopper":
        s = next_obs[:, -11:]
        rest = s[:, 1:].abs() if hopper_abs else s[:, 1:]
        healthy = torch.isfinite(s).all(-1) & (rest < 100).all(-1) & (s[:, 0] > 0.7) & (s[:, 1].abs() < 0.2)
        return ~healthy
    if kind == "humanoid":
        z = next_obs[:, -348]
        return ~((z > 1.0) & (z < 2.0))
    raise ValueError(f"unknown model termination {kind!r}; valid: {sorted(set(MODEL_TERMINATION.values()))} or None")


def model_inputs(observation: torch.Tensor, action: torch.Tensor, num_actions: int | None) -> torch.Tensor:
    """``x = (s, onehot(a))`` for ``num_actions`` discrete actions (integer ``[N]``/``[N, 1]``), else ``(s, a)``."""
    if num_actions is not None:
        if torch.is_floating_point(action) and action.shape[-1] == num_actions:
            a = action
        else:
            a = F.one_hot(action.reshape(observation.shape[0]).long(), num_actions)
    else:
        a = action.reshape(observation.shape[0], -1)
    return torch.cat([observation, a.to(observation.dtype)], -1)


class DynamicsLoss(LossModule):
    """Gaussian NLL of a :class:`ProbabilisticEnsemble` on transitions (``y = (r, s' - s)``).

    Example:
        >>> model = ProbabilisticEnsemble(4 + 3, 2 + 4, hidden=(16,))
        >>> loss = DynamicsLoss(model, num_actions=3)
        >>> td = TensorDict({"observation": torch.randn(8, 4), "action": torch.randint(3, (8,)),
        ...                  ("next", "observation"): torch.randn(8, 4), ("next", "reward"): torch.randn(8, 2)}, [8])
        >>> loss(td)["loss_dynamics"].shape
        torch.Size([])
    """

    @dataclass
    class _AcceptedKeys:
        observation: NestedKey = "observation"
        action: NestedKey = "action"
        reward: NestedKey = "reward"

    default_keys = _AcceptedKeys
    tensor_keys: _AcceptedKeys

    def __init__(self, model: ProbabilisticEnsemble, *, num_actions: int | None) -> None:
        super().__init__()
        self.model = model
        self.num_actions = num_actions

    @property
    def in_keys(self):
        k = self.tensor_keys
        return [k.observation, k.action, ("next", k.observation), ("next", k.reward)]

    @property
    def out_keys(self):
        return ["loss_dynamics"]

    def inputs_targets(self, td: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor]:
        k = self.tensor_keys
        obs = td.get(k.observation)
        x = model_inputs(obs, td.get(k.action), self.num_actions)
        y = torch.cat([td.get(("next", k.reward)), td.get(("next", k.observation)) - obs], -1)
        return x, y

    def nll(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        mean, logvar = self.model(x)
        if y.ndim == 2:
            y = y.unsqueeze(0).expand_as(mean)
        loss = F.gaussian_nll_loss(mean, y, logvar.exp(), reduction="none").mean()
        return loss + 0.01 * self.model.max_logvar.sum() - 0.01 * self.model.min_logvar.sum()

    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        x, y = self.inputs_targets(tensordict.reshape(-1))
        return TensorDict({"loss_dynamics": self.nll(x, y)}, batch_size=[])


def fit_dynamics(loss: DynamicsLoss, x: torch.Tensor, y: torch.Tensor, *, lr: float = 1e-3, batch_size: int = 256,
                 holdout_ratio: float = 0.1, max_holdout: int = 5000, patience: int = 5, max_epochs: int = 200,
                 max_grad_norm: float | None = None, generator: torch.Generator | None = None) -> float:
    """Fit the ensemble of ``loss`` on ``(x, y)`` as the authors; returns the mean holdout MSE.

    A fresh Adam (the authors build one per fit) with weight decays
    ``2.5e-5, 5e-5, 7.5e-5, 7.5e-5, 1e-4`` on the layers in order (the last for any further layer).
    """
    model = loss.model
    n = x.shape[0]
    if n < 2:
        raise ValueError(f"fit_dynamics needs at least 2 transitions, got {n}")
    if model.normalize_inputs:
        model.inputs_mu.copy_(x.mean(0, keepdim=True))
        sigma = x.std(0, unbiased=False, keepdim=True)
        model.inputs_sigma.copy_(torch.where(sigma < 1e-12, torch.ones_like(sigma), sigma))
    groups = [{"params": layer.parameters(), "weight_decay": _DECAYS[min(i, len(_DECAYS) - 1)]}
              for i, layer in enumerate(model.layers)]
    groups.append({"params": [model.max_logvar, model.min_logvar]})
    optim = torch.optim.Adam(groups, lr=lr)
    n_hold = min(int(n * holdout_ratio), max_holdout)
    perm = torch.randperm(n, generator=generator, device="cpu").to(x.device)
    hold_x, hold_y = x[perm[:n_hold]], y[perm[:n_hold]]
    train_x, train_y = x[perm[n_hold:]], y[perm[n_hold:]]
    m, e = train_x.shape[0], model.ensemble_size
    idx = torch.randint(m, (e, m), generator=generator, device="cpu").to(x.device)  # bootstrap per member
    best = [math.inf] * e
    epoch, stale, hold = 0, 0, torch.zeros(e)
    while stale < patience and epoch < max_epochs:
        model.train()
        for start in range(0, m, batch_size):
            b = idx[:, start:start + batch_size]
            nll = loss.nll(train_x[b], train_y[b])
            optim.zero_grad(set_to_none=True)
            nll.backward()
            if max_grad_norm is not None:
                nn.utils.clip_grad_norm_(model.parameters(), max_grad_norm)
            optim.step()
        shuffle = torch.rand(idx.shape, generator=generator).argsort(-1).to(x.device)
        idx = idx.gather(1, shuffle)
        model.eval()
        with torch.no_grad():
            if n_hold:
                mean, _ = model(hold_x)
                hold = (mean - hold_y).pow(2).mean(-1).mean(-1).cpu()
            else:
                hold = torch.zeros(e)
        model.elites.copy_(hold.argsort()[: model.num_elites].to(model.elites.device))
        improved = False
        for i in range(e):
            h = float(hold[i])
            if epoch == 0 or (best[i] - h) / best[i] > 0.01:
                best[i] = h
                improved = True
        stale = 0 if improved else stale + 1
        epoch += 1
    return float(hold.mean())
