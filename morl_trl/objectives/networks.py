"""Preference-conditioned networks for the multi-objective losses.

Every network here maps ``[obs, w]`` (and, for critics, the action) to its output through one concatenation and a
plain MLP, optionally after a pixel encoder (:class:`NatureCNN`); the concatenation is at the input by default and
may come after the first hidden layers (``preference_layer``). They accept any number of leading batch dimensions,
have no data-dependent control flow and capture as one graph under ``torch.compile(fullgraph=True)``.

The ``make_*`` builders wrap them in TensorDict modules with the keys the
losses read by default (DESIGN.md): ``"observation"``, ``"preference"``, ``"action"``, ``"action_value"`` (``[*B,
|A|, k]``) and ``"state_action_value"`` (``[*B, k]``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from tensordict.nn import NormalParamExtractor, TensorDictModule
from tensordict.utils import NestedKey
from torch import nn
from torchrl.data import Bounded, Categorical, Composite, OneHot, TensorSpec
from torchrl.modules import OneHotCategorical, ProbabilisticActor, TanhNormal

__all__ = ["NatureCNN", "PreferenceConditionedMLP", "make_categorical_actor", "make_gaussian_actor",
           "make_vector_critic", "make_vector_q_network", "orthogonal_init_"]

INITS = ("default", "orthogonal")
SCALE_PARAMETERIZATIONS = ("softplus", "clamped_log_std", "tanh_log_std")
#: each scale's default ``log_std_bounds``: CAPQL's clamp [-20, 2] (capql.py:125); SAC/MOSAC's
#: tanh rescaling into [-5, 2] (sac_continuous.py / mosac_continuous_action.py:95-103)
LOG_STD_BOUNDS = {"softplus": (-20.0, 2.0), "clamped_log_std": (-20.0, 2.0), "tanh_log_std": (-5.0, 2.0)}

DEFAULT_NUM_CELLS: tuple[int, ...] = (256, 256, 256, 256)


class NatureCNN(nn.Module):
    """The DQN "Nature" convolutional encoder (Mnih et al., 2015).

    Three convolutions (32 8x8/4, 64 4x4/2, 64 3x3/1) and a linear layer to
    ``features_dim`` features, ReLU throughout. ``uint8`` pixels are scaled to
    ``[0, 1]``; float inputs are used as they are. Any leading batch shape is
    accepted: ``[*B, C, H, W] -> [*B, features_dim]``.

    Args:
        obs_shape: ``(C, H, W)`` of one observation.
        features_dim: output width. Defaults to 512.

    Examples:
        >>> enc = NatureCNN((4, 84, 84))
        >>> enc(torch.zeros(2, 3, 4, 84, 84, dtype=torch.uint8)).shape
        torch.Size([2, 3, 512])
    """

    def __init__(self, obs_shape: Sequence[int], features_dim: int = 512) -> None:
        super().__init__()
        if len(obs_shape) != 3:
            raise ValueError(f"NatureCNN expects obs_shape=(C, H, W), got {tuple(obs_shape)}.")
        self.obs_shape = tuple(int(s) for s in obs_shape)
        self.features_dim = int(features_dim)
        c, h, w = self.obs_shape
        self.cnn = nn.Sequential(nn.Conv2d(c, 32, kernel_size=8, stride=4), nn.ReLU(),
                                 nn.Conv2d(32, 64, kernel_size=4, stride=2), nn.ReLU(),
                                 nn.Conv2d(64, 64, kernel_size=3, stride=1), nn.ReLU(), nn.Flatten())
        with torch.no_grad():
            n_flat = self.cnn(torch.zeros(1, c, h, w)).shape[-1]
        self.linear = nn.Sequential(nn.Linear(n_flat, self.features_dim), nn.ReLU())

    def forward(self, pixels: torch.Tensor) -> torch.Tensor:
        batch = pixels.shape[:-3]
        x = pixels.reshape(-1, *pixels.shape[-3:])
        x = x.float() / 255.0 if pixels.dtype == torch.uint8 else x.float()
        return self.linear(self.cnn(x)).reshape(*batch, self.features_dim)


def _mlp(in_features: int, out_features: int, num_cells: Sequence[int], activation: type[nn.Module]) -> nn.Sequential:
    layers: list[nn.Module] = []
    width = in_features
    for cells in num_cells:
        layers += [nn.Linear(width, cells), activation()]
        width = cells
    layers.append(nn.Linear(width, out_features))
    return nn.Sequential(*layers)


def orthogonal_init_(module: nn.Module, gain: float = 1.0) -> nn.Module:
    """Orthogonal weights (``gain``) and zero biases on every ``nn.Linear`` and ``nn.Conv2d`` of
    ``module`` (a :class:`NatureCNN` too), in place.

    MORL-Baselines' ``layer_init(method="orthogonal", weight_gain=1, bias_const=0)``, which
    initialises every ``Linear`` and ``Conv2d`` (``mo_utils/networks.py:143-157``).

    Example:
        >>> lin = orthogonal_init_(nn.Linear(8, 4))
        >>> torch.allclose(lin.weight @ lin.weight.T, torch.eye(4), atol=1e-5), bool((lin.bias == 0).all())
        (True, True)
    """
    for m in module.modules():
        if isinstance(m, (nn.Linear, nn.Conv2d)):
            nn.init.orthogonal_(m.weight, gain=gain)
            if m.bias is not None:
                nn.init.zeros_(m.bias)
    return module


def _check_init(init: str) -> str:
    if init not in INITS:
        raise ValueError(f"init={init!r}; valid values are {INITS}")
    return init


class PreferenceConditionedMLP(nn.Module):
    """``cat([encoder(obs), *rest], -1) -> MLP -> [*B, *out_shape]``.

    ``rest`` is typically ``w`` (and the action, for a continuous critic); all inputs share their leading batch
    shape. With ``preference_layer = L > 0``: ``cat([h_L(encoder(obs)), *rest]) -> the remaining layers``.

    Args:
        in_features: width of the concatenated input (encoder output + the rest).
        out_shape: trailing output shape, e.g. ``(num_actions, k)``.
        num_cells: hidden layer widths. Defaults to four layers of 256, the paper's ``net_arch``.
        activation: activation class. Defaults to ``nn.ReLU``.
        encoder: optional module applied to the first input.
        preference_layer: hidden layers before the concatenation, in ``[0, len(num_cells)]``. Defaults to 0.
        rest_features: total width of ``rest``; required when ``preference_layer > 0``.

    Examples:
        >>> net = PreferenceConditionedMLP(8 + 2, (4, 2), num_cells=(32, 32))
        >>> net(torch.randn(5, 8), torch.rand(5, 2)).shape
        torch.Size([5, 4, 2])
        >>> late = PreferenceConditionedMLP(8 + 2, (4, 2), num_cells=(32, 32), preference_layer=1, rest_features=2)
        >>> late.trunk[0].in_features, late.mlp[0].in_features
        (8, 34)
    """

    def __init__(self, in_features: int, out_shape: int | Sequence[int], *,
                 num_cells: Sequence[int] = DEFAULT_NUM_CELLS, activation: type[nn.Module] = nn.ReLU,
                 encoder: nn.Module | None = None, preference_layer: int = 0, rest_features: int | None = None) -> None:
        super().__init__()
        self.out_shape = (int(out_shape),) if isinstance(out_shape, int) else tuple(int(s) for s in out_shape)
        self.encoder = encoder
        num_cells = tuple(num_cells)
        if isinstance(preference_layer, bool) or not isinstance(preference_layer, int) \
                or not 0 <= preference_layer <= len(num_cells):
            raise ValueError(f"preference_layer must be an int in [0, {len(num_cells)}] (the number of hidden "
                             f"layers), got {preference_layer!r}")
        self.preference_layer = preference_layer
        if preference_layer == 0:
            self.trunk = None
            self.mlp = _mlp(int(in_features), math.prod(self.out_shape), num_cells, activation)
        else:
            if rest_features is None or not 0 <= rest_features < in_features:
                raise ValueError(f"preference_layer={preference_layer} needs rest_features (the width of the "
                                 f"inputs after the first) in [0, {in_features}), got {rest_features!r}")
            first = int(in_features) - int(rest_features)
            layers: list[nn.Module] = []
            width = first
            for cells in num_cells[:preference_layer]:
                layers += [nn.Linear(width, cells), activation()]
                width = cells
            self.trunk = nn.Sequential(*layers)
            self.mlp = _mlp(width + int(rest_features), math.prod(self.out_shape), num_cells[preference_layer:],
                            activation)

    def forward(self, first: torch.Tensor, *rest: torch.Tensor) -> torch.Tensor:
        if self.encoder is not None:
            first = self.encoder(first)
        if self.trunk is not None:
            first = self.trunk(first)
        x = torch.cat([first, *rest], dim=-1) if rest else first
        out = self.mlp(x)
        return out.reshape(*out.shape[:-1], *self.out_shape)

    @property
    def supports_forward_with(self) -> bool:
        """Whether :meth:`forward_with` applies: no encoder, and only ``nn.Linear`` layers hold state."""
        if self.encoder is not None:
            return False
        layers = [*(self.trunk or ()), *self.mlp]
        return all(isinstance(m, nn.Linear) or not any(True for _ in m.parameters()) and not any(True for _ in m.buffers())
                   for m in layers)

    def forward_with(self, params: Sequence[torch.Tensor], first: torch.Tensor, *rest: torch.Tensor) -> torch.Tensor:
        """:meth:`forward` with the ``nn.Linear`` weights and biases taken from ``params``.

        ``params`` lists them in ``named_parameters()`` order (weight, bias per layer), e.g. the
        leaves of a loss's functional parameters. Nothing is swapped into the module: this is
        how the losses evaluate their networks with functional (target, detached, ensemble)
        parameters at a fraction of ``TensorDict.to_module``'s cost, with the same operations
        as :meth:`forward`. Weights of shape ``[n, out, in]`` evaluate an ensemble of ``n``
        networks on the same inputs in one batched matmul per layer (output ``[n, *B, *out_shape]``).

        Example:
            >>> net = PreferenceConditionedMLP(5 + 2, 3, num_cells=(8,))
            >>> x, w = torch.randn(4, 5), torch.rand(4, 2)
            >>> params = [p.detach() for p in net.parameters()]
            >>> torch.equal(net.forward_with(params, x, w), net(x, w))
            True
            >>> ensemble = [torch.stack([p, p]) for p in params]
            >>> torch.allclose(net.forward_with(ensemble, x, w)[1], net(x, w), atol=1e-6)
            True
        """
        if not self.supports_forward_with:
            raise ValueError("forward_with needs a network without encoder whose only stateful layers are nn.Linear")
        return self._forward_with(params, first, *rest)

    def _forward_with(self, params: Sequence[torch.Tensor], first: torch.Tensor, *rest: torch.Tensor) -> torch.Tensor:
        """:meth:`forward_with` without the structure check (done once by the caller)."""
        it = iter(params)
        ensemble = params[0].ndim == 3
        if ensemble:  # the members share the inputs
            n = params[0].shape[0]
            first = first.expand(n, *first.shape)
            rest = tuple(r.expand(n, *r.shape) for r in rest)

        def run(layers, x):
            for m in layers:
                if isinstance(m, nn.Linear):
                    weight = next(it)
                    bias = next(it) if m.bias is not None else None
                    if ensemble:
                        lead = x.shape[1:-1]
                        flat = x.reshape(n, -1, x.shape[-1])
                        y = torch.bmm(flat, weight.transpose(-1, -2)) if bias is None \
                            else torch.baddbmm(bias.unsqueeze(-2), flat, weight.transpose(-1, -2))
                        x = y.reshape(n, *lead, y.shape[-1])
                    else:
                        x = torch.nn.functional.linear(x, weight, bias)
                else:
                    x = m(x)
            return x

        if self.trunk is not None:
            first = run(self.trunk, first)
        x = torch.cat([first, *rest], dim=-1) if rest else first
        out = run(self.mlp, x)
        return out.reshape(*out.shape[:-1], *self.out_shape)


def encoder_and_width(obs_shape: int | Sequence[int], features_dim: int) -> tuple[nn.Module | None, int]:
    if isinstance(obs_shape, int):
        return None, obs_shape
    obs_shape = tuple(obs_shape)
    if len(obs_shape) == 1:
        return None, obs_shape[0]
    if len(obs_shape) == 3:
        enc = NatureCNN(obs_shape, features_dim)
        return enc, enc.features_dim
    raise ValueError(f"obs_shape must be an int, (obs_dim,) or (C, H, W); got {obs_shape}.")


def make_vector_q_network(obs_shape: int | Sequence[int], num_actions: int, num_objectives: int, *,
                          num_cells: Sequence[int] = DEFAULT_NUM_CELLS, activation: type[nn.Module] = nn.ReLU,
                          features_dim: int = 512, preference_layer: int = 0, init: str = "default",
                          observation_key: NestedKey = "observation", preference_key: NestedKey | None = "preference",
                          out_key: NestedKey = "action_value") -> TensorDictModule:
    """Vector Q-network ``Q(s, ., w) -> [*B, num_actions, num_objectives]`` for discrete actions.

    The Envelope Q-network (and, with ``preference_key=None``, MORL/D's unconditioned discrete MOSAC critic).
    ``obs_shape=(C, H, W)`` puts a :class:`NatureCNN` in front of the MLP.

    Forms of the Envelope network: ``preference_layer=0, init="orthogonal"``: ``w`` at the input, orthogonal
    weights (gain 1), zero biases, as the public MORL-Baselines 1.3.0 ``QNet`` (``mlp(obs_dim + k, ...)``, then
    ``self.apply(layer_init)``; ``envelope_network="mb"``); ``init="default"``: PyTorch's init (``"input"``);
    ``preference_layer=1, init="orthogonal"``: ``w`` after the first hidden layer, the paper authors' copy of
    MORL-Baselines per the line-by-line comparison of their code (``envelope_network="authors"``, the default).

    Args:
        preference_layer: hidden layers before ``w`` is concatenated (0: at the input). Defaults to 0.
        init: ``"default"`` (PyTorch's) or ``"orthogonal"`` (:func:`orthogonal_init_`).

    Examples:
        >>> from tensordict import TensorDict
        >>> q = make_vector_q_network(8, 4, 2, num_cells=(32,))
        >>> td = TensorDict({"observation": torch.randn(3, 8), "preference": torch.full((3, 2), 0.5)}, [3])
        >>> q(td)["action_value"].shape
        torch.Size([3, 4, 2])
        >>> authors = make_vector_q_network(8, 4, 2, num_cells=(32, 32), preference_layer=1, init="orthogonal")
        >>> authors(td)["action_value"].shape, authors.module.trunk[0].in_features
        (torch.Size([3, 4, 2]), 8)
    """
    _check_init(init)
    encoder, width = encoder_and_width(obs_shape, features_dim)
    in_keys = [observation_key]
    rest = 0
    if preference_key is not None:
        in_keys.append(preference_key)
        width += num_objectives
        rest = num_objectives
    net = PreferenceConditionedMLP(width, (num_actions, num_objectives), num_cells=num_cells, activation=activation,
                                   encoder=encoder, preference_layer=preference_layer, rest_features=rest)
    if init == "orthogonal":
        orthogonal_init_(net)
    net.num_objectives = num_objectives
    net.num_actions = num_actions
    return TensorDictModule(net, in_keys=in_keys, out_keys=[out_key])


def make_vector_critic(obs_dim: int, action_dim: int, num_objectives: int, *,
                       num_cells: Sequence[int] = DEFAULT_NUM_CELLS, activation: type[nn.Module] = nn.ReLU,
                       observation_key: NestedKey = "observation", action_key: NestedKey = "action",
                       preference_key: NestedKey | None = "preference",
                       out_key: NestedKey = "state_action_value") -> TensorDictModule:
    """Vector critic ``Q(s, a, w) -> [*B, num_objectives]`` for continuous actions (CAPQL, MOSAC).

    Examples:
        >>> from tensordict import TensorDict
        >>> q = make_vector_critic(5, 2, 3, num_cells=(16,))
        >>> td = TensorDict({"observation": torch.randn(4, 5), "action": torch.rand(4, 2),
        ...                  "preference": torch.full((4, 3), 1 / 3)}, [4])
        >>> q(td)["state_action_value"].shape
        torch.Size([4, 3])
    """
    in_keys = [observation_key, action_key]
    width = obs_dim + action_dim
    if preference_key is not None:
        in_keys.append(preference_key)
        width += num_objectives
    net = PreferenceConditionedMLP(width, num_objectives, num_cells=num_cells, activation=activation)
    net.num_objectives = num_objectives
    return TensorDictModule(net, in_keys=in_keys, out_keys=[out_key])


class _LocScale(nn.Module):
    """Splits an MLP's ``2 * d`` outputs into a location and a positive scale (biased softplus)."""

    def __init__(self, net: nn.Module) -> None:
        super().__init__()
        self.net = net
        self.extractor = NormalParamExtractor()

    def forward(self, *inputs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.head(self.net(*inputs))

    def head(self, out: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(loc, scale)`` from the MLP's output."""
        return self.extractor(out)


class _LocClampedLogStd(nn.Module):
    """Splits an MLP's ``2 * d`` outputs into a location and ``exp(clamp(log_std, lo, hi))``.

    MORL-Baselines' CAPQL ``GaussianPolicy`` (``LOG_SIG_MIN = -20``, ``LOG_SIG_MAX = 2``).
    """

    def __init__(self, net: nn.Module, log_std_min: float = -20.0, log_std_max: float = 2.0) -> None:
        super().__init__()
        self.net = net
        self.log_std_min, self.log_std_max = float(log_std_min), float(log_std_max)

    def forward(self, *inputs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.head(self.net(*inputs))

    def head(self, out: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(loc, scale)`` from the MLP's output."""
        loc, log_std = out.chunk(2, -1)
        return loc, log_std.clamp(self.log_std_min, self.log_std_max).exp()


class _LocTanhLogStd(_LocClampedLogStd):
    """Splits an MLP's ``2 * d`` outputs into a location and ``exp(lo + (hi - lo) (tanh(x) + 1) / 2)``.

    The authors' SAC and MOSAC actors (CleanRL's): ``log_std = -5 + 3.5 (tanh(x) + 1)`` in ``[-5, 2]``
    (``sac_continuous.py``; ``mosac_continuous_action.py:95-103``).
    """

    def head(self, out: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(loc, scale)`` from the MLP's output."""
        loc, x = out.chunk(2, -1)
        lo, hi = self.log_std_min, self.log_std_max
        return loc, (lo + 0.5 * (hi - lo) * (torch.tanh(x) + 1)).exp()


def make_gaussian_actor(obs_dim: int, action_spec: Bounded, num_objectives: int, *,
                        num_cells: Sequence[int] = DEFAULT_NUM_CELLS, activation: type[nn.Module] = nn.ReLU,
                        scale: str = "softplus", log_std_bounds: tuple[float, float] | None = None,
                        observation_key: NestedKey = "observation", preference_key: NestedKey | None = "preference",
                        action_key: NestedKey = "action") -> ProbabilisticActor:
    """Preference-conditioned tanh-Gaussian actor ``pi(a | s, w)`` within ``action_spec``'s bounds.

    Args:
        scale: how the second half of the MLP's output becomes the Gaussian's scale:
            ``"softplus"`` (TorchRL's biased softplus, the default), ``"clamped_log_std"``
            (``exp(clamp(log_std, *log_std_bounds))``, MORL-Baselines' CAPQL policy; the CAPQL
            recipe's default) or ``"tanh_log_std"`` (``log_std = min + (max - min) (tanh(x) + 1) / 2``,
            the authors' SAC and MOSAC: ``-5 + 3.5 (tanh(x) + 1)``; the SAC and MORL/D recipes' default).
        log_std_bounds: ``(min, max)`` of the log-std. Defaults to the scale's
            (:data:`LOG_STD_BOUNDS`: ``(-20, 2)`` clamped, ``(-5, 2)`` tanh).

    Examples:
        >>> from tensordict import TensorDict
        >>> from torchrl.data import Bounded
        >>> actor = make_gaussian_actor(5, Bounded(-1.0, 1.0, (2,)), 3, num_cells=(16,))
        >>> td = TensorDict({"observation": torch.randn(4, 5), "preference": torch.full((4, 3), 1 / 3)}, [4])
        >>> actor(td)["action"].shape
        torch.Size([4, 2])
        >>> clamped = make_gaussian_actor(5, Bounded(-1.0, 1.0, (2,)), 3, num_cells=(16,), scale="clamped_log_std")
        >>> clamped(td)["action"].shape
        torch.Size([4, 2])
    """
    lo, hi = _check_scale(scale, log_std_bounds)
    action_dim = action_spec.shape[-1]
    in_keys = [observation_key]
    width = obs_dim
    if preference_key is not None:
        in_keys.append(preference_key)
        width += num_objectives
    mlp = PreferenceConditionedMLP(width, 2 * action_dim, num_cells=num_cells, activation=activation)
    return tanh_normal_actor(gaussian_head(mlp, scale, (lo, hi)), in_keys, action_spec, action_key)


def _check_scale(scale: str, log_std_bounds: tuple[float, float] | None) -> tuple[float, float]:
    """Validates a Gaussian head's ``scale`` and ``log_std_bounds`` (``None``: the scale's
    :data:`LOG_STD_BOUNDS`); returns the bounds as floats."""
    if scale not in SCALE_PARAMETERIZATIONS:
        raise ValueError(f"scale={scale!r}; valid values are {SCALE_PARAMETERIZATIONS}")
    if log_std_bounds is None:
        log_std_bounds = LOG_STD_BOUNDS[scale]
    lo, hi = (float(b) for b in log_std_bounds)
    if not lo < hi:
        raise ValueError(f"log_std_bounds must be (min, max) with min < max, got {log_std_bounds!r}")
    return lo, hi


def gaussian_head(net: nn.Module, scale: str, log_std_bounds: tuple[float, float] | None = None) -> nn.Module:
    """``net``'s output ``[..., 2 d]`` as ``(loc, scale)``: the biased softplus, the clamped
    log-std or the tanh-rescaled log-std (``scale``, see :func:`make_gaussian_actor`)."""
    lo, hi = _check_scale(scale, log_std_bounds)
    if scale == "softplus":
        return _LocScale(net)
    return (_LocClampedLogStd if scale == "clamped_log_std" else _LocTanhLogStd)(net, lo, hi)


def tanh_normal_actor(net: nn.Module, in_keys, action_spec: Bounded, action_key: NestedKey) -> ProbabilisticActor:
    """``ProbabilisticActor``: ``net`` writes ``(loc, scale)``, a ``TanhNormal`` within ``action_spec``'s bounds."""
    return ProbabilisticActor(TensorDictModule(net, in_keys=in_keys, out_keys=["loc", "scale"]),
                              in_keys=["loc", "scale"], out_keys=[action_key],
                              spec=Composite({action_key: action_spec}), distribution_class=TanhNormal,
                              distribution_kwargs={"low": action_spec.space.low, "high": action_spec.space.high},
                              return_log_prob=False)


def make_categorical_actor(obs_shape: int | Sequence[int], num_actions: int, num_objectives: int, *,
                           num_cells: Sequence[int] = DEFAULT_NUM_CELLS, activation: type[nn.Module] = nn.ReLU,
                           features_dim: int = 512, observation_key: NestedKey = "observation",
                           preference_key: NestedKey | None = "preference", action_key: NestedKey = "action",
                           action_spec: TensorSpec | None = None) -> ProbabilisticActor:
    """Preference-conditioned categorical actor ``pi(. | s, w)`` writing an integer action.

    Examples:
        >>> from tensordict import TensorDict
        >>> actor = make_categorical_actor(8, 4, 2, num_cells=(16,))
        >>> td = TensorDict({"observation": torch.randn(3, 8), "preference": torch.full((3, 2), 0.5)}, [3])
        >>> actor(td)["action"].shape
        torch.Size([3])
    """
    encoder, width = encoder_and_width(obs_shape, features_dim)
    in_keys = [observation_key]
    if preference_key is not None:
        in_keys.append(preference_key)
        width += num_objectives
    net = PreferenceConditionedMLP(width, num_actions, num_cells=num_cells, activation=activation, encoder=encoder)
    if action_spec is None:
        action_spec = Categorical(num_actions)
    return categorical_actor(net, in_keys, action_spec, action_key)


def categorical_actor(net: nn.Module, in_keys, action_spec: TensorSpec, action_key: NestedKey) -> ProbabilisticActor:
    """``ProbabilisticActor``: ``net`` writes ``logits``, the categorical matching ``action_spec`` (one-hot or index)."""
    return ProbabilisticActor(TensorDictModule(net, in_keys=in_keys, out_keys=["logits"]), in_keys=["logits"],
                              out_keys=[action_key], spec=Composite({action_key: action_spec}),
                              distribution_class=_discrete_distribution(action_spec), return_log_prob=False)


def _discrete_distribution(spec: TensorSpec) -> type:
    """The distribution matching a discrete action spec: one-hot or integer actions."""
    return OneHotCategorical if isinstance(spec, OneHot) else torch.distributions.Categorical
