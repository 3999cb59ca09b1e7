"""Preference conditioning: a weight vector per sub-env and episode (or step), carried in the TensorDict."""

from __future__ import annotations

import math

import torch
from tensordict import TensorDictBase
from torchrl.data import Bounded, Composite

from morl_trl.preferences import check_simplex, sample_preferences
from morl_trl.transforms._utils import SeededTransform, reset_mask

__all__ = ["PreferenceConditioning"]

_MODES = ("dirichlet", "gaussian", "cone", "cycle", "random", "given")
_RESAMPLE = ("episode", "step")


class PreferenceConditioning(SeededTransform):
    """Gives every sub-env a weight vector ``w`` on the simplex at each of its resets (or steps).

    ``w`` is written under ``preference_key`` (``[*B, k]``) at reset and copied to every step
    of the episode (``resample="episode"``, the default), so the policy, the loss (through the replay buffer) and
    :class:`LinearScalarization` all see it. The key is also in the env's state spec, so it
    reaches the reset and travels through ``SerialEnv``/``ParallelEnv`` like the context.

    Modes (how a sub-env being reset gets its ``w``):

    * ``"dirichlet"`` (default without ``weights``): ``w ~ Dirichlet(alpha)``; ``alpha=1`` is
      uniform on the simplex (:func:`morl_trl.preferences.sample_preferences`).
    * ``"gaussian"``: ``|N(0, I)|`` normalised (MORL-Baselines' ``random_weights(dist="gaussian")``,
      the authors' Envelope training preferences).
    * ``"cone"``: within 22.5 degrees of the equal-weight direction
      (:func:`morl_trl.preferences.sample_cone_preferences`, the authors' CAPQL preferences).
    * ``"cycle"`` (default with ``weights``): the rows of ``weights`` ``[m, k]`` in turn, in
      sub-env order, continuing from one reset to the next (``m`` sub-envs reset together
      get the ``m`` rows: the evaluation weights).
    * ``"random"``: a row of ``weights`` drawn uniformly.
    * ``"given"``: the preference in the reset TensorDict, e.g.
      ``env.reset(TensorDict(preference=w, batch_size=env.batch_size))``; every row of
      ``w`` ``[*B, k]`` must be on the simplex (``ValueError`` naming the value otherwise, before
      anything is reset). A sub-env keeps its ``w`` over later resets (the TensorDict carries
      it); before any is given, sub-envs get equal weights ``1/k``.

    With ``resample="step"`` every sub-env also gets a fresh ``w`` (same mode) at every step:
    the ``w`` a step writes under ``"next"`` is the one the policy acts on at the following
    step, so each stored transition carries the preference its action was chosen with (the
    authors' CAPQL). ``"given"`` cannot be resampled.

    :meth:`set_next_preference` gives every sub-env's *next* episode a chosen ``w`` once (in any
    sampling mode), after which its episodes follow the mode again: GPI-LS's first episode of an
    iteration, which acts with the iteration's new weight (SPEC §6).

    In the sampling modes a preference in the reset TensorDict is ignored (TorchRL's
    auto-resets carry the previous one there). Seeding follows
    :class:`~morl_trl.transforms._utils.SeededTransform`; the preference stream is independent
    of the context stream of :class:`DomainRandomization` seeded with the same value.

    Args:
        num_objectives: ``k``; inferred from ``weights`` or the env's reward when omitted.
        weights: a fixed weight set ``[m, k]`` for ``"cycle"``/``"random"``.
        mode: one of the modes above.
        alpha: Dirichlet concentration, a float or ``[k]``.
        resample: ``"episode"`` (a new ``w`` at each reset; the default) or ``"step"`` (also a new
            ``w`` at every step).
        seed: seed of the transform's generator.
        preference_key: where ``w`` goes.

    Example:
        >>> from torchrl.envs import TransformedEnv
        >>> from morl_trl.envs.toy import ToyContextEnv
        >>> env = TransformedEnv(ToyContextEnv(num_envs=3), PreferenceConditioning(weights=[[1.0, 0.0], [0.5, 0.5]]))
        >>> env.reset()["preference"]
        tensor([[1.0000, 0.0000],
                [0.5000, 0.5000],
                [1.0000, 0.0000]])
    """

    _salt = 0x5EED_0001

    def __init__(
        self,
        num_objectives: int | None = None,
        *,
        weights=None,
        mode: str | None = None,
        alpha: float | torch.Tensor = 1.0,
        resample: str = "episode",
        seed: int | None = None,
        preference_key: str = "preference",
    ) -> None:
        super().__init__(in_keys=[], out_keys=[preference_key])
        if mode is None:
            mode = "dirichlet" if weights is None else "cycle"
        if mode not in _MODES:
            raise ValueError(f"mode must be one of {_MODES}, got {mode!r}")
        if resample not in _RESAMPLE:
            raise ValueError(f"resample must be one of {_RESAMPLE}, got {resample!r}")
        if resample == "step" and mode == "given":
            raise ValueError("mode='given' keeps the preference it is given: use resample='episode'")
        if mode in ("gaussian", "cone") and not bool((torch.as_tensor(alpha) == 1).all()):
            raise ValueError(f"alpha={alpha!r} applies to mode='dirichlet' only")
        self.resample = resample
        if num_objectives is not None and (isinstance(num_objectives, bool) or not isinstance(num_objectives, int)
                                           or num_objectives < 1):
            raise ValueError(f"num_objectives must be a positive int, got {num_objectives!r}")
        if weights is not None:
            weights = torch.as_tensor(weights, dtype=torch.float32)
            if weights.ndim != 2 or weights.shape[0] == 0:
                raise ValueError(f"weights must be a non-empty [m, k] weight set, got shape {tuple(weights.shape)}")
            if num_objectives is None:
                num_objectives = weights.shape[1]
            weights = check_simplex(weights, num_objectives, name="weight set")
        elif mode in ("cycle", "random"):
            raise ValueError(f"mode={mode!r} draws from a weight set: pass weights=[[...], ...]")
        self.weights = weights
        self.mode = mode
        self.preference_key = preference_key
        self._k = num_objectives
        alpha_t = torch.as_tensor(alpha, dtype=torch.float64)
        if not torch.isfinite(alpha_t).all() or (alpha_t <= 0).any() or alpha_t.ndim > 1:
            raise ValueError(f"alpha must be a positive float or [k] vector, got {alpha}")
        if alpha_t.ndim == 1 and num_objectives is not None and alpha_t.numel() != num_objectives:
            raise ValueError(f"alpha has {alpha_t.numel()} entries; expected {num_objectives} (one per objective)")
        self.alpha = alpha_t
        self._cursor = 0
        self._current: torch.Tensor | None = None
        self._first: torch.Tensor | None = None  # set_next_preference's w [k], until every sub-env has had it
        self._first_left: torch.Tensor | None = None  # the sub-envs [*B] still to get it (None: all of them)
        self._init_seed(seed)

    # ------------------------------------------------------------------ sizes and specs
    @property
    def num_objectives(self) -> int:
        if self._k is None:
            parent = self.parent
            if parent is None:
                raise RuntimeError("PreferenceConditioning: num_objectives unknown (no parent env to infer it)")
            self._k = self._reward_width(parent)
        return self._k

    @staticmethod
    def _reward_width(parent) -> int:
        key = "reward" if "reward" in parent.reward_keys else parent.reward_key
        return int(parent.full_reward_spec[key].shape[-1])

    def _spec(self, batch, device) -> Bounded:
        return Bounded(0.0, 1.0, shape=(*batch, self.num_objectives), dtype=torch.float32, device=device)

    def _check_width(self) -> None:
        parent = self.parent
        if parent is not None and self._k is not None:
            width = self._reward_width(parent)
            if width != self._k:
                what = "the weight set has" if self.weights is not None else "num_objectives gives"
                raise ValueError(f"{what} {self._k} objectives; the env has {width}")

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        self._check_width()
        observation_spec[self.preference_key] = self._spec(observation_spec.shape, observation_spec.device)
        return observation_spec

    def transform_input_spec(self, input_spec: Composite) -> Composite:
        state = input_spec["full_state_spec"]
        if state is None:
            state = Composite(shape=input_spec.shape, device=input_spec.device)
        state[self.preference_key] = self._spec(input_spec.shape, input_spec.device)
        input_spec["full_state_spec"] = state
        return input_spec

    # ------------------------------------------------------------------ drawing
    def equal_weights(self, device=None) -> torch.Tensor:
        k = self.num_objectives
        return torch.full((k,), 1.0 / k, device=device)

    def sample(self, n: int) -> torch.Tensor:
        """Draw ``n`` preferences ``[n, k]`` (CPU) in a sampling mode (all but ``"given"``)."""
        k = self.num_objectives
        if self.mode == "dirichlet":
            return sample_preferences(n, k, alpha=self.alpha, generator=self.generator)
        if self.mode in ("gaussian", "cone"):
            return sample_preferences(n, k, distribution=self.mode, generator=self.generator)
        if self.weights.shape[1] != k:
            raise ValueError(f"the weight set has {self.weights.shape[1]} objectives; the env has {k}")
        m = self.weights.shape[0]
        if self.mode == "cycle":
            rows = (self._cursor + torch.arange(n)) % m
            self._cursor = int((self._cursor + n) % m)
        elif self.mode == "random":
            rows = torch.randint(m, (n,), generator=self.generator)
        else:
            raise RuntimeError(f"sample() does not apply to mode {self.mode!r}")
        return self.weights[rows]

    def set_next_preference(self, w) -> None:
        """Every sub-env's next episode gets ``w`` (``[k]``, on the simplex; ``ValueError`` naming it
        otherwise), once; each sub-env's later episodes follow the mode again, drawing nothing for the
        episode that got ``w``. ``None`` withdraws a ``w`` not yet given. Not for ``mode="given"``, whose
        preferences come in the reset TensorDict.

        Example:
            >>> from torchrl.envs import TransformedEnv
            >>> from morl_trl.envs.toy import ToyContextEnv
            >>> t = PreferenceConditioning(weights=[[1.0, 0.0], [0.5, 0.5]], mode="cycle")
            >>> env = TransformedEnv(ToyContextEnv(num_envs=2), t)
            >>> t.set_next_preference([0.0, 1.0])
            >>> env.reset()["preference"].tolist(), env.reset()["preference"].tolist()
            ([[0.0, 1.0], [0.0, 1.0]], [[1.0, 0.0], [0.5, 0.5]])
        """
        if w is None:
            self._first = self._first_left = None
            return
        if self.mode == "given":
            raise ValueError("mode='given' takes each preference from the reset TensorDict: pass it there")
        w = torch.as_tensor(w, dtype=torch.float32)
        if w.ndim != 1:
            raise ValueError(f"set_next_preference takes one weight vector [{self.num_objectives}], "
                             f"got shape {tuple(w.shape)}")
        self._first = check_simplex(w.reshape(1, -1), self.num_objectives, name="next preference")[0].clone()
        self._first_left = None

    def _given(self, tensordict: TensorDictBase | None, batch, device) -> torch.Tensor | None:
        """The preference in ``tensordict`` as ``[*batch, k]`` float32 (its width checked; its rows
        are checked on the simplex, for the sub-envs being reset only, in ``_reset_env_preprocess``)."""
        w = None if tensordict is None else tensordict.get(self.preference_key, None)
        if w is None:
            return None
        k = self.num_objectives
        w = torch.as_tensor(w, device=device)
        if w.ndim == 0 or w.shape[-1] != k:
            check_simplex(w, k)  # raises, naming the shape
        w = w.to(torch.float32)
        if w.shape != (*batch, k):
            try:
                w = w.expand(*batch, k)
            except RuntimeError:
                raise ValueError(
                    f"preference has shape {tuple(w.shape)}; expected [{k}] or {[*batch, k]}"
                ) from None
        return w

    # ------------------------------------------------------------------ env hooks
    def _reset_env_preprocess(self, tensordict: TensorDictBase | None) -> TensorDictBase | None:
        if self.mode == "given":  # validate before the env underneath resets: bad input changes nothing
            parent = self.parent
            mask = reset_mask(tensordict, parent.batch_size, parent.device)
            w = self._given(tensordict, parent.batch_size, parent.device)
            if w is not None and mask.any():
                check_simplex(w[mask], self.num_objectives)
        return tensordict

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        if self.mode != "given":  # (given preferences draw nothing: no seed to follow, no parent walk)
            self._sync_seed()
        batch, device = tensordict_reset.batch_size, tensordict_reset.device
        k = self.num_objectives
        mask = reset_mask(tensordict, batch, device)
        given = self._given(tensordict, batch, device) if self.mode == "given" else None
        current = tensordict.get(self.preference_key, None)
        if current is None or current.shape != (*batch, k):
            current = self._current
        if current is None or current.shape != (*batch, k):
            current = self.equal_weights(device).expand(*batch, k)
        current = current.to(device=device, dtype=torch.float32)
        if self.mode == "given":
            # otherwise (nothing given) the sub-envs keep what they had; no host sync on this path
            new = current.clone() if given is None else torch.where(mask.unsqueeze(-1), given, current)
        else:
            new = current.clone()
            if self._first is not None:  # (set_next_preference: these sub-envs' next episode is its w's)
                left = self._first_left
                left = mask.new_ones(mask.shape) if left is None else left.to(mask.device)
                first = mask & left
                new[first] = self._first.to(device)
                mask = mask & ~first
                left = left & ~first
                self._first_left = left
                if not bool(left.any()):
                    self._first = self._first_left = None
            n = int(mask.sum())
            if n:
                new[mask] = self.sample(n).to(device)
        self._current = new
        tensordict_reset.set(self.preference_key, new)
        return tensordict_reset

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        w = tensordict.get(self.preference_key, None)
        if w is None:
            w = self._current
            if w is None:
                raise RuntimeError("PreferenceConditioning: the env was stepped before it was reset")
        if self.resample == "step":
            batch = next_tensordict.batch_size
            n = math.prod(batch)
            w = self.sample(n).reshape(*batch, self.num_objectives).to(device=w.device, dtype=torch.float32)
        self._current = w
        next_tensordict.set(self.preference_key, w.clone())
        return next_tensordict

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        return tensordict

    def __repr__(self) -> str:
        extra = f", weights={tuple(self.weights.shape)}" if self.weights is not None else ""
        if self.mode == "dirichlet":
            extra = f", alpha={self.alpha.tolist()}"
        if self.resample != "episode":
            extra += f", resample={self.resample!r}"
        return f"{type(self).__name__}(mode={self.mode!r}{extra}, key={self.preference_key!r}, seed={self._seed})"
