"""Pareto Conditioned Networks (Reymond et al. 2022): the command-conditioned policy and its supervised loss.

The network is the authors' (their ``algos/multi_policy/pcn/pcn.py:52-112``): the command ``c = [desired_return,
desired_horizon] * scaling_factor`` and the observation are embedded (``Linear + Sigmoid`` each, width
``hidden[0]``), multiplied element-wise, then ``Linear, ReLU`` for each further width of ``hidden`` and a last
``Linear`` give log-probabilities (discrete actions, ``LogSoftmax``) or the action itself (continuous). The paper's
``net_arch`` is ``[256] * 4``: a 256-wide embedding and three 256 layers. The loss is the cross-entropy of the
stored action (discrete) or the mean squared error to it (continuous), on steps of the best episodes
(:class:`~morl_trl.data.episode_replay.EpisodeReplay`).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import TensorDict, TensorDictBase, TensorDictParams
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.objectives import LossModule

from morl_trl._torchrl_compat import module_kwargs
from morl_trl.objectives.common import module_output
from morl_trl.objectives.networks import encoder_and_width

__all__ = ["PCNNetwork", "PCNLoss", "make_pcn_network"]


class PCNNetwork(nn.Module):
    """``(observation, desired_return [k], desired_horizon [1]) -> log-probs [A]`` or ``action [A]``.

    ``obs_dim``: an int (vector observations) or ``(C, H, W)`` (images: the Nature CNN first). ``hidden``: the
    widths (the authors' ``net_arch``): the embeddings are ``hidden[0]`` wide and each further width adds a
    ``Linear, ReLU``; an int ``h`` is ``(h, h)`` (MORL-Baselines' ``hidden_dim``: one hidden layer).

    Example:
        >>> net = PCNNetwork(obs_dim=4, action_dim=3, num_objectives=2, scaling_factor=[0.1] * 3, hidden=(8, 8, 8))
        >>> logp = net(torch.zeros(5, 4), torch.zeros(5, 2), torch.ones(5, 1))
        >>> logp.shape, torch.allclose(logp.exp().sum(-1), torch.ones(5))
        (torch.Size([5, 3]), True)
        >>> [m.out_features for m in net.fc if isinstance(m, nn.Linear)]
        [8, 8, 3]
    """

    def __init__(self, obs_dim, action_dim: int, num_objectives: int, scaling_factor: Sequence[float],
                 hidden: int | Sequence[int] = (256, 256, 256, 256), *, discrete: bool = True) -> None:
        super().__init__()
        widths = (int(hidden), int(hidden)) if isinstance(hidden, int) else tuple(int(h) for h in hidden)
        if not widths or min(widths) < 1:
            raise ValueError(f"hidden must be a positive width or a non-empty sequence of them, got {hidden!r}")
        scale = torch.as_tensor(scaling_factor, dtype=torch.float32).flatten()
        if scale.numel() != num_objectives + 1:
            raise ValueError(f"scaling_factor needs num_objectives + 1 = {num_objectives + 1} values (the desired "
                             f"return's and the horizon's), got {list(scaling_factor)}")
        self.num_objectives, self.discrete = num_objectives, discrete
        self.register_buffer("scaling_factor", scale)
        # an image (C, H, W) goes through the Nature CNN first (512 features; MORL-Baselines' PCN is
        # written for vector observations)
        encoder, width = encoder_and_width(obs_dim, 512)
        self.obs_ndim = 1 if encoder is None else 3
        self.s_emb = nn.Sequential(*([encoder] if encoder is not None else []), nn.Linear(width, widths[0]), nn.Sigmoid())
        self.c_emb = nn.Sequential(nn.Linear(num_objectives + 1, widths[0]), nn.Sigmoid())
        layers = [m for a, b in zip(widths[:-1], widths[1:]) for m in (nn.Linear(a, b), nn.ReLU())]
        layers.append(nn.Linear(widths[-1], action_dim))
        if discrete:
            layers.append(nn.LogSoftmax(dim=-1))
        self.fc = nn.Sequential(*layers)
        for m in self.modules():  # the authors' layer_init: orthogonal weights (gain 1), zero biases (pcn.py:100,112)
            if isinstance(m, (nn.Linear, nn.Conv2d)):
                nn.init.orthogonal_(m.weight)
                nn.init.zeros_(m.bias)

    def forward(self, observation: torch.Tensor, desired_return: torch.Tensor, desired_horizon: torch.Tensor):
        c = torch.cat([desired_return, desired_horizon], -1).float() * self.scaling_factor
        obs = observation if self.obs_ndim == 3 else observation.float()
        x = self.s_emb(obs) * self.c_emb(c)
        for m in self.fc:  # each ReLU in place on its Linear's fresh output (the Linear's backward keeps its
            x = x.relu_() if type(m) is nn.ReLU else m(x)  # input, not its output): nn.ReLU's values
        return x


def _same(held, leaf) -> bool:
    """``held`` is ``leaf`` (a parameter: gradients must reach that very leaf), or, for a buffer,
    the same memory read the same way (TorchRL keeps a shallow copy of buffers)."""
    if held is leaf:
        return True
    return (held is not None and not isinstance(leaf, nn.Parameter) and held.data_ptr() == leaf.data_ptr()
            and held.shape == leaf.shape and held.stride() == leaf.stride() and held.dtype == leaf.dtype)


def make_pcn_network(obs_dim: int, action_dim: int, num_objectives: int, scaling_factor,
                     hidden: int | Sequence[int] = (256, 256, 256, 256), *, discrete: bool = True) -> TensorDictModule:
    """:class:`PCNNetwork` as a ``TensorDictModule`` reading ``observation``, ``desired_return`` and
    ``desired_horizon`` and writing ``"log_probs"`` (discrete) or ``"action_pred"`` (continuous)."""
    net = PCNNetwork(obs_dim, action_dim, num_objectives, scaling_factor, hidden, discrete=discrete)
    out = "log_probs" if discrete else "action_pred"
    return TensorDictModule(net, in_keys=["observation", "desired_return", "desired_horizon"], out_keys=[out])


class PCNLoss(LossModule):
    """PCN's supervised loss: the stored action under the command the episode achieved.

    The batch holds steps of stored episodes with ``desired_return`` = the step's return-to-go
    and ``desired_horizon`` = the steps left (what :meth:`EpisodeReplay.sample` gives);
    discrete actions: ``mean(-log pi(a | s, c))`` (the authors' one-hot cross-entropy);
    continuous: ``mse(pi(s, c), a)``.

    Example:
        >>> net = make_pcn_network(4, 3, 2, [0.1] * 3, hidden=8)
        >>> loss = PCNLoss(net)
        >>> td = TensorDict({"observation": torch.zeros(6, 4), "desired_return": torch.zeros(6, 2),
        ...                  "desired_horizon": torch.ones(6, 1), "action": torch.tensor([0, 1, 2, 0, 1, 2])}, [6])
        >>> out = loss(td)
        >>> sorted(out.keys()), out["loss_pcn"].shape
        (['entropy', 'loss_pcn'], torch.Size([]))
    """

    class _AcceptedKeys:
        action = "action"
        log_probs = "log_probs"
        action_pred = "action_pred"

    default_keys = _AcceptedKeys
    tensor_keys: _AcceptedKeys
    policy_network: TensorDictModule
    policy_network_params: TensorDictParams
    target_policy_network_params: TensorDictParams

    def __init__(self, network: TensorDictModule) -> None:
        super().__init__()
        self.convert_to_functional(network, "policy_network")
        self.discrete = bool(network.module.discrete) if hasattr(network, "module") else True

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        pass

    def _module_holds_params(self) -> bool:
        """Whether every functional parameter (and buffer) of the loss is the very tensor the network
        module holds at that place, as :meth:`convert_to_functional` leaves them (PCN has no target
        copy): then the network runs as it is. Anything that put other tensors in
        ``policy_network_params`` (or in the module) makes this false and the loss swaps them in."""
        leaves = list(self.policy_network_params.values(True, True))
        held = getattr(self, "_held", None)
        if held is None or len(held) != len(leaves):
            module = self.policy_network
            held = []
            for k in self.policy_network_params.keys(True, True):
                *path, name = (k,) if isinstance(k, str) else k
                held.append((module.get_submodule(".".join(path)), name))
            self._held = held
        return all(_same(getattr(m, name, None), leaf) for (m, name), leaf in zip(held, leaves))

    out_keys = ["loss_pcn", "entropy"]

    @property
    def in_keys(self):
        return ["observation", "desired_return", "desired_horizon", self.tensor_keys.action]

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        key = self.tensor_keys.log_probs if self.discrete else self.tensor_keys.action_pred
        if self._module_holds_params():  # swapping the same tensors in is a no-op (~0.25 ms per update on a CPU core)
            pred = module_output(self.policy_network, tensordict, key)
        else:
            with self.policy_network_params.to_module(self.policy_network, preserve_module_state=False):
                pred = module_output(self.policy_network, tensordict, key)
        return self._losses(pred, tensordict.get(self.tensor_keys.action))

    def losses_of(self, observation: torch.Tensor, action: torch.Tensor, desired_return: torch.Tensor,
                  desired_horizon: torch.Tensor) -> TensorDict | None:
        """:meth:`forward` on the batch's tensors, without building its TensorDict (the same operations: what
        :func:`morl_trl.algorithms.pcn.recipe.update` runs, ~0.5 ms less per update on a
        CPU core). ``None`` where the network is not the plain positional module holding the loss's own
        parameters: call :meth:`forward` then."""
        net = self.policy_network
        key = self.tensor_keys.log_probs if self.discrete else self.tensor_keys.action_pred
        if type(net) is not TensorDictModule or list(net.in_keys) != self.in_keys[:3] or list(net.out_keys) != [key] \
                or module_kwargs(net) or not self._module_holds_params():
            return None
        return self._losses(net.module(observation, desired_return, desired_horizon), action)

    def _losses(self, pred: torch.Tensor, action: torch.Tensor) -> TensorDict:
        if self.discrete:
            logp = pred
            if action.shape == logp.shape:  # one-hot
                action = action.argmax(-1)
            nll = -logp.gather(-1, action.long().reshape(*logp.shape[:-1], 1)).squeeze(-1)
            entropy = -(logp.exp() * logp).sum(-1).mean().detach()
            return TensorDict({"loss_pcn": nll.mean(), "entropy": entropy}, [])
        return TensorDict({"loss_pcn": torch.nn.functional.mse_loss(pred, action.to(pred.dtype))}, [])
