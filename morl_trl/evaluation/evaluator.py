"""The multi-context evaluator: a policy on every (context, weight, episode) of an evaluation suite.

The whole grid runs as *one* batched environment (a pool of ``chunk_size`` sub-envs) built by
``env_factory(num_envs=..., seed=...)`` -- the training composition minus its training-only
parts. Every sub-env gets its context in the reset TensorDict's ``"context"`` (the rule of
every contextual env: a context given at reset is used; the evaluator checks that the env reports it back) and its
preference through the library's own :class:`~morl_trl.transforms.PreferenceConditioning` (``mode="given"``); the
library's :class:`~morl_trl.transforms.DiscountedVectorReturn` sums the returns. An evaluation of ``C`` contexts x
``W`` weights x ``E`` episodes costs one ``step`` call per time step.
"""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.envs import Compose, EnvBase, TransformedEnv
from torchrl.envs.transforms import Transform
from torchrl.envs.utils import ExplorationType, set_exploration_type

from morl_trl._torchrl_compat import transform_reset, transform_step
from morl_trl.evaluation.results import ContextResult, EvaluationResult
from morl_trl.metrics import (Bounds, cardinality, eum, hypervolume, igd, interquartile_mean, normalize,
                              normalized_hypervolume, optimality_gap, pareto_front, sparsity)
from morl_trl.preferences import check_simplex, energy_weights
from morl_trl.transforms import DiscountedVectorReturn, PreferenceConditioning

__all__ = ["MultiContextEvaluator", "suite_contexts"]

Policy = Callable[[TensorDictBase], TensorDictBase]
EnvFactory = Callable[..., EnvBase]

# the evaluator's own return keys (a training stack may carry DiscountedVectorReturn's defaults)
_RETURN = "eval_episode_return"
_DISCOUNTED = "eval_episode_discounted_return"
_DISCOUNT = "eval_episode_discount"
_FACTORY_HELP = (
    "env_factory must be a callable (num_envs, seed) -> env; got {what}: compose it in your factory, e.g. "
    "env_factory=lambda num_envs, seed: compose_policy_env(make_env(\"MOLunarLanderDR-v0\", num_envs=num_envs, "
    "seed=seed), history_len=2)"
)


def _check_factory(factory, what: str = "env_factory") -> EnvFactory:
    if isinstance(factory, Transform):
        raise ValueError(_FACTORY_HELP.format(what=f"a Transform ({type(factory).__name__})"))
    if isinstance(factory, EnvBase):
        raise ValueError(_FACTORY_HELP.format(what=f"an env instance ({type(factory).__name__}), not a function building one"))
    if not callable(factory):
        raise ValueError(_FACTORY_HELP.format(what=f"{what}={factory!r}"))
    return factory


def _domain_env_factory(env_id: str, device) -> EnvFactory:
    """The default env factory of a registered domain: ``make_env`` of its training id (the env
    of training; the evaluator's contexts, given at every reset, replace its draws)."""
    from morl_trl.envs import make_env

    def factory(num_envs: int, seed: int) -> EnvBase:
        return make_env(env_id, num_envs=num_envs, device=device, seed=seed)

    return factory


def _static(env: EnvBase, name: str):
    """An attribute of ``env`` or of the env under its transforms, read without triggering a
    batched env's attribute forwarding (which starts workers, or recurses before they start)."""
    while env is not None:
        value = inspect.getattr_static(env, name, None)
        if isinstance(value, property):
            value = getattr(env, name)
        if value is not None:
            return value
        env = env.base_env if isinstance(env, TransformedEnv) else None
    return None


class MultiContextEvaluator:
    """Evaluate a preference-conditioned policy on every context of a suite, batched.

    Each (context ``c``, weight ``w``, episode) runs one episode in its own sub-env, the policy reading ``w`` under
    ``preference_key``; the discounted vector return is read at the first ``done``. The value of ``(c, w)`` is the
    mean over episodes, the front of ``c`` the non-dominated subset of its ``W`` values (the paper's protocol, SPEC
    §2). The evaluator appends ``PreferenceConditioning(k, mode="given")`` and ``DiscountedVectorReturn(gamma)`` to
    the env, passes each context at reset and raises ``ValueError`` if the env reports another (e.g. a
    ``DomainRandomization`` left in the stack).

    Per context it reports ``hypervolume`` (points that do not dominate ``ref_point`` count for
    nothing, as in the paper), ``eum``, ``sparsity``, ``cardinality``; with bounds
    ``normalized_hypervolume`` and ``normalized_eum``; with a ``reference`` ``nhgr`` and ``eugr``.
    Where the env emits the original scalar reward (``sorl_key``: the SAC baseline's f_SORL) the
    evaluator also sums it over every episode
    (``EvaluationResult.sorl_returns``), as the authors' evaluator did: per context, the best
    weight's f_SORL return and that weight (:meth:`EvaluationResult.sorl_best`).

    Args:
        policy: a callable ``TensorDict -> TensorDict`` writing ``"action"``, or ``"random"`` (the
            env's action spec). A policy may ignore the preference. Actions follow
            ``exploration_type`` (the paper evaluated MORL/D and SAC with ``ExplorationType.RANDOM``).
        contexts: a training id (its evaluation suite) or a list of env ids of one domain; a mapping
            ``name -> context vector [c]`` (with ``env_factory``); a mapping ``name -> env_factory``
            (envs without a context vector); or ``None``: one context, ``"default"``.
        weights: ``[W, k]`` preferences on the simplex, or ``W`` energy weights (default 100, the paper's).
        episodes: episodes per (context, weight) pair.
        gamma: discount (default: the domain's).
        env_factory: ``env_factory(num_envs=..., seed=...)`` building the batched env with a vector
            reward: the training composition minus its training-only parts (default: ``make_env`` of
            the domain's training id).
        reference: frozen bounds and specialist fronts (:class:`~morl_trl.reporting.DomainReference`):
            adds NHGR, EUGR, normalized HV and EUM.
        bounds: ``name -> Bounds`` (or ``(lower, upper)``) for normalized HV and EUM without a reference.
        ref_point: unnormalized hypervolume reference point (default: the domain's).
        eum_weights: ``[M, k]`` weights of the EUM/EUGR (default: ``weights``).
        chunk_size: sub-envs of the pool (default: one per row). A smaller pool streams through the
            grid (a partial reset takes the next pending row), bounding memory; for envs whose cost
            is per sub-env (Box2D, MuJoCo) it is also faster.
        exploration_type: TorchRL exploration type used while acting.
        device: device of the default env (and of the reset TensorDicts).
        seed: seeds the env (re-seeded before each run) and torch's RNG while acting (restored
            afterwards); results are reproducible for a given seed and ``chunk_size``.
        reset_finished: reset done sub-envs with no row left, so that masked steps start from valid states.
        preference_key: where the policy reads the preference.
        max_steps: safety horizon (default: the env's ``max_episode_steps``); longer episodes are cut, with a warning.
        true_fronts: ``name -> [m, k]`` true Pareto front (discounted with ``gamma``): adds ``igd``
            and ``hv_ratio``. Default: the domain's ``true_front(gamma)`` where it knows one.
        sorl_key: the env's entry holding the original scalar reward ``[*B, 1]``; ``None``: not recorded.

    Example:
        >>> from morl_trl.evaluation import MultiContextEvaluator
        >>> ev = MultiContextEvaluator("random", "MOLunarLanderDR-v0", weights=4, seed=0)
        >>> result = ev.evaluate()            # 8 contexts x 4 weights, one batched env of 32
        >>> result.returns.shape              # [contexts, weights, episodes, objectives]
        torch.Size([8, 4, 1, 4])
        >>> sorted(result.per_context["MOLunarLanderHard-v0"].metrics)
        ['cardinality', 'eum', 'hypervolume', 'sparsity']
    """

    def __init__(self, policy: Policy | str, contexts: str | Sequence[str] | Mapping[str, object] | None = None,
                 weights: torch.Tensor | np.ndarray | int | None = None, *, episodes: int = 1,
                 gamma: float | None = None, env_factory: EnvFactory | None = None, reference=None,
                 bounds: Mapping[str, object] | None = None, ref_point: Sequence[float] | None = None,
                 eum_weights: torch.Tensor | np.ndarray | None = None, chunk_size: int | None = None,
                 exploration_type: ExplorationType = ExplorationType.DETERMINISTIC, device: torch.device | str = "cpu",
                 seed: int = 0, reset_finished: bool = True, preference_key: str = "preference",
                 max_steps: int | None = None, true_fronts: Mapping[str, object] | None = None,
                 sorl_key: str | tuple[str, ...] | None = "original_reward") -> None:
        if not (callable(policy) or policy == "random"):
            raise ValueError(f"policy must be a callable TensorDict -> TensorDict or 'random', got {policy!r}")
        self.policy = policy
        self.device = torch.device(device)
        self.preference_key = preference_key
        self.sorl_key = sorl_key
        self.exploration_type = exploration_type
        self.reset_finished = bool(reset_finished)
        self.seed = int(seed)
        if not isinstance(episodes, int) or episodes < 1:
            raise ValueError(f"episodes must be a positive int, got {episodes!r}")
        self.episodes = episodes
        if env_factory is not None:
            _check_factory(env_factory)

        self.domain = None
        self.context_factories: dict[str, EnvFactory] | None = None
        self.context_names, self.contexts = self._resolve_contexts(contexts, env_factory)
        if env_factory is None and self.domain is None and self.context_factories is None:
            raise ValueError(
                "contexts given as vectors (or none) need an env_factory(num_envs=..., seed=...); "
                "or give contexts as {name: env_factory}"
            )
        if env_factory is None and self.domain is not None:
            env_factory = _domain_env_factory(self.domain.train_id, self.device)
        self.env_factory = env_factory
        self._envs: dict[tuple[str | None, int], EnvBase] = {}

        n_weights = weights if isinstance(weights, int) else (100 if weights is None else len(weights))
        if isinstance(n_weights, bool) or not isinstance(n_weights, int) or n_weights < 1:
            raise ValueError(f"weights must be a [W, k] weight set or a positive int, got {weights!r}")
        self._n_weights = n_weights
        n_total = len(self.context_names) * n_weights * episodes
        if chunk_size is not None and (isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1):
            raise ValueError(f"chunk_size must be a positive int, got {chunk_size!r}")
        self._whole_grid = chunk_size is None  # (a pool of one sub-env per row, whatever the weights of a call)
        self.chunk_size = n_total if chunk_size is None else chunk_size

        probe = None
        if self.domain is not None:
            self.objective_names = tuple(self.domain.objective_names)
        else:
            probe = self._env(self.context_names[0] if self.context_factories else None)
            k = int(probe.full_reward_spec[probe.reward_key].shape[-1])
            names = _static(probe, "objective_names") or ()
            self.objective_names = tuple(names) if len(names) == k else tuple(f"objective_{i}" for i in range(k))
        space = _static(probe, "context_space") if probe is not None else None
        self.context_parameters = (tuple(self.domain.context_space.names) if self.domain is not None
                                   else tuple(getattr(space, "names", ())) if self.contexts is not None else ())
        k = len(self.objective_names)

        if weights is None:
            weights = 100
        if isinstance(weights, int):
            weights = energy_weights(k, weights)
        self.weights = torch.as_tensor(check_simplex(_as_2d(weights), k, name="weights"), dtype=torch.float64)
        self.eum_weights = (self.weights if eum_weights is None else torch.as_tensor(
            check_simplex(_as_2d(eum_weights), k, name="eum_weights"), dtype=torch.float64))

        if gamma is None:
            if self.domain is None:
                raise ValueError("pass gamma: there is no domain to take the discount from")
            gamma = self.domain.gamma
        if not (isinstance(gamma, (int, float)) and 0.0 <= gamma <= 1.0):
            raise ValueError(f"gamma must be a number in [0, 1], got {gamma!r}")
        self.gamma = float(gamma)
        for env in self._envs.values():  # the probe got its transforms before gamma was known
            env.transform[1].gamma = self.gamma

        if ref_point is None and self.domain is not None:
            ref_point = self.domain.hv_ref_point
        if ref_point is not None:
            ref_point = np.asarray(ref_point, dtype=np.float64)
            if ref_point.shape != (k,) or not np.isfinite(ref_point).all():
                raise ValueError(f"ref_point must be {k} finite numbers, got {ref_point.tolist()}")
        self.ref_point = ref_point

        self.reference = reference
        if reference is not None:
            missing = [c for c in self.context_names if c not in reference.bounds]
            if missing:
                raise ValueError(
                    f"the reference of {reference.domain} has no data for contexts {missing}; "
                    f"it covers {list(reference.contexts)}"
                )
            if reference.num_objectives != k:
                raise ValueError(f"the reference has {reference.num_objectives} objectives, the env {k}")
        self.bounds = self._resolve_bounds(bounds, k)
        self.max_steps = max_steps
        if true_fronts is None and self.domain is not None and self.domain.true_front is not None:
            true_fronts = {c: self.domain.true_front(self.gamma) for c in self.context_names}
        self.true_fronts = {c: np.asarray(f, dtype=np.float64).reshape(-1, k) for c, f in (true_fronts or {}).items()}

    # ------------------------------------------------------------------ setup helpers
    def _resolve_contexts(self, contexts, env_factory) -> tuple[tuple[str, ...], torch.Tensor | None]:
        if contexts is None:
            return ("default",), None
        if isinstance(contexts, Mapping):
            if not contexts:
                raise ValueError("contexts is empty")
            names = tuple(str(n) for n in contexts)
            values = list(contexts.values())
            if any(callable(v) or isinstance(v, (Transform, EnvBase)) for v in values):
                if env_factory is not None:
                    raise ValueError("contexts given as {name: env_factory} take no separate env_factory")
                self.context_factories = {n: _check_factory(v, f"contexts[{n!r}]") for n, v in zip(names, values)}
                return names, None
            vecs = []
            for n, v in contexts.items():
                v = torch.as_tensor(v, dtype=torch.float32)
                if v.ndim != 1 or not torch.isfinite(v).all():
                    raise ValueError(f"context {n!r} must be a finite vector [c], got {v.tolist()}")
                vecs.append(v)
            if len({v.shape for v in vecs}) != 1:
                raise ValueError(f"contexts have different sizes: {[tuple(v.shape) for v in vecs]}")
            return names, torch.stack(vecs)
        self.domain, names, table = suite_contexts(contexts)
        return names, table

    def _resolve_bounds(self, bounds, k: int) -> dict[str, Bounds]:
        out = {}
        if self.reference is not None:
            out.update({c: self.reference.bounds[c] for c in self.context_names})
        for c, b in (bounds or {}).items():
            if c not in self.context_names:
                raise ValueError(
                    f"bounds given for {c!r}, which is not evaluated; contexts: {list(self.context_names)}"
                )
            b = b if isinstance(b, Bounds) else Bounds(*b)
            if b.num_objectives != k:
                raise ValueError(f"bounds of {c!r} have {b.num_objectives} objectives, the env {k}")
            out[c] = b
        return out

    def _pool_size(self, group: str | None, n_weights: int | None = None) -> int:
        n_weights = self._n_weights if n_weights is None else n_weights
        rows = n_weights * self.episodes * (1 if group is not None else len(self.context_names))
        return rows if self._whole_grid else min(self.chunk_size, rows)

    def _env(self, group: str | None, n_weights: int | None = None) -> EnvBase:
        """The pool env of ``group`` (a context name for ``{name: env_factory}``, else ``None``):
        built once with the evaluation transforms appended, kept for later evaluations (an
        evaluation at other weights that needs another pool size replaces it)."""
        num_envs = self._pool_size(group, n_weights)
        env = self._envs.get((group, num_envs))
        if env is None:
            for key in [key for key in self._envs if key[0] == group]:
                old = self._envs.pop(key)
                if not old.is_closed:
                    old.close()
            factory = self.env_factory if group is None else self.context_factories[group]
            env = factory(num_envs=num_envs, seed=self.seed)
            if not isinstance(env, EnvBase):
                raise ValueError(f"env_factory returned {type(env).__name__}; it must return a TorchRL EnvBase")
            if tuple(env.batch_size) != (num_envs,):
                raise ValueError(
                    f"env_factory(num_envs={num_envs}) built an env of batch size {tuple(env.batch_size)}; "
                    f"expected ({num_envs},)"
                )
            env = self._with_evaluation_transforms(env)
            self._envs[(group, num_envs)] = env
        return env

    def _with_evaluation_transforms(self, env: EnvBase) -> TransformedEnv:
        """``TransformedEnv(env, Compose(PreferenceConditioning(k, mode="given"), DiscountedVectorReturn(gamma)))``."""
        if self.preference_key in env.full_observation_spec.keys(True, True):
            raise ValueError(f"the env from env_factory already writes {self.preference_key!r} (a training "
                             "PreferenceConditioning?); leave it out: the evaluator adds "
                             "PreferenceConditioning(mode='given') with its weights")
        reward = env.full_reward_spec[env.reward_key]
        if reward.ndim < 2:
            raise ValueError(f"the env's reward has shape {tuple(reward.shape)}; the evaluator needs a vector reward [*B, k]")
        k = int(reward.shape[-1])
        return TransformedEnv(env, Compose(
            PreferenceConditioning(k, mode="given", preference_key=self.preference_key),
            DiscountedVectorReturn(getattr(self, "gamma", 1.0), in_key=env.reward_key, return_key=_RETURN,
                                   discounted_key=_DISCOUNTED, discount_key=_DISCOUNT, dtype=torch.float64)),
            auto_unwrap=False)  # keep the factory's env whole: the loop steps it

    # ------------------------------------------------------------------ running
    def evaluate(self, policy: Policy | str | None = None, *, weights: torch.Tensor | np.ndarray | None = None,
                 seed: int | None = None) -> EvaluationResult:
        """Run the grid (optionally with another ``policy``) and compute every metric.

        ``weights`` ``[W', k]`` (on the simplex) and ``seed`` replace the evaluator's own for this
        call only: the same contexts, episodes, env and discount at other weights (GPI-LS's values
        at the corner weights of its CCS, :mod:`morl_trl.algorithms.gpi.recipe`). The result's ``weights``
        are the ones evaluated.
        """
        policy = self.policy if policy is None else policy
        k = len(self.objective_names)
        if weights is None:
            weights = self.weights
        else:
            weights = torch.as_tensor(check_simplex(_as_2d(weights), k, name="weights"), dtype=torch.float64)
        seed = self.seed if seed is None else int(seed)
        C, W, E = len(self.context_names), len(weights), self.episodes
        # grid row r = (c * W + w) * E + e
        pref_rows = weights.repeat_interleave(E, dim=0)
        if self.context_factories is None:
            ctx_rows = None if self.contexts is None else self.contexts.repeat_interleave(W * E, dim=0)
            disc, und, lengths, sorl = self._run_pool(policy, self._env(None, W), ctx_rows, pref_rows.repeat(C, 1), seed)
        else:
            runs = [self._run_pool(policy, self._env(name, W), None, pref_rows, seed) for name in self.context_names]
            disc, und, lengths = (torch.cat(parts) for parts in list(zip(*runs))[:3])
            # f_SORL only where every context's env emits it
            sorl = None if any(r[3] is None for r in runs) else torch.cat([r[3] for r in runs])
        if sorl is not None:
            sorl = sorl.reshape(C, W, E, 2)
        return self._result(disc.reshape(C, W, E, k), und.reshape(C, W, E, k), lengths.reshape(C, W, E), sorl, weights)

    __call__ = evaluate

    def _check_contexts(self, td: TensorDictBase, which: torch.Tensor, wanted: torch.Tensor, rows: torch.Tensor,
                        rows_per_context: int) -> None:
        """Raise unless the env reports the contexts it was given for the sub-envs ``which``."""
        got = td.get("context", None)
        if got is None:
            raise ValueError(
                "the env from env_factory does not report a 'context' entry, so the evaluator cannot force "
                "its contexts; give contexts as {name: env_factory} (one env per context) or None"
            )
        got = got[which].to(wanted.device, wanted.dtype)
        off = (got - wanted).abs() > 1e-6 + 1e-5 * wanted.abs()
        if bool(off.any()):
            ok = ~off.any(-1)
            i = int((~ok).nonzero()[0, 0])
            name = self.context_names[int(rows[i]) // rows_per_context]
            raise ValueError(f"the env from env_factory reset a sub-env to context {got[i].tolist()} where the "
                             f"evaluator gave {name!r} = {wanted[i].tolist()} in the reset TensorDict: something in "
                             "its stack draws its own contexts at reset (e.g. a DomainRandomization transform). "
                             "Build the evaluation env without it (a context given at reset must be used); results "
                             "would otherwise be labelled with contexts they did not run")

    def _run_pool(self, policy, env: TransformedEnv, ctx_rows: torch.Tensor | None, pref_rows: torch.Tensor, seed: int):
        """Run every row as one episode on the pool ``env`` (``chunk_size`` sub-envs).

        Sub-env ``i`` starts on row ``i``; whenever a sub-env finishes its episode it is
        partially reset with the context and preference of the next pending row (so a pool
        smaller than the grid streams through it without waiting for the slowest episode).

        ``env`` is the factory's env under ``Compose(PreferenceConditioning, DiscountedVectorReturn)``.
        The loop steps and resets the factory's env and applies the two transforms' ``_step`` /
        ``_reset`` to its outputs -- what ``TransformedEnv.step``/``reset`` do, without their
        per-call bookkeeping (which costs as much as the physics of a few hundred Box2D sub-envs).
        """
        inner = env.base_env
        prefs, returns = env.transform[0], env.transform[1]
        n_rows = pref_rows.shape[0]
        batch_size = inner.batch_size
        m = int(batch_size[0])
        k = len(self.objective_names)
        pref_key = self.preference_key
        inner.set_seed(seed)
        rows_per_context = n_rows // len(self.context_names)

        row = torch.arange(m)  # the grid row each sub-env runs (-1: idle)
        next_row = m
        pref_rows = pref_rows.to(torch.float32)
        run_len = torch.zeros(m, dtype=torch.long)
        disc = torch.zeros(n_rows, k, dtype=torch.float64)
        und = torch.zeros(n_rows, k, dtype=torch.float64)
        lengths = torch.zeros(n_rows, dtype=torch.long)
        reward_key = _as_tuple(inner.reward_key)[:-1]
        disc_key, und_key = ("next", *reward_key, _DISCOUNTED), ("next", *reward_key, _RETURN)
        action_key = inner.action_key
        action_spec = inner.full_action_spec[action_key] if policy == "random" else None
        everyone = torch.ones(m, dtype=torch.bool)
        # f_SORL: the env's original scalar reward summed per episode, as the vector reward is
        # (undiscounted; discounted with the factor gamma^t the return transform holds before step t)
        sorl_key = self.sorl_key
        discount_key = (*reward_key, _DISCOUNT)
        sorl = None  # [n_rows, 2] (undiscounted, discounted), once the env shows it emits sorl_key
        sorl_acc = None  # [m, 2] the running sums of the sub-envs

        def reset(td_in: TensorDictBase) -> TensorDictBase:
            # what the transforms read (the reset mask, the preferences given and the running
            # returns), taken before the env's reset pops the mask and merges its output into
            # td_in (it sets new tensors there, so these references keep the values read)
            carried = td_in.select(pref_key, _RETURN, _DISCOUNTED, _DISCOUNT, "_reset", strict=False)
            out = inner.reset(td_in)
            return transform_reset(returns, carried, transform_reset(prefs, carried, out))

        horizon = self.max_steps or _static(inner, "max_episode_steps") or 100_000
        dev = self.device
        rng_devices = [dev.index or 0] if dev.type == "cuda" else []
        with torch.random.fork_rng(devices=rng_devices), torch.no_grad(), set_exploration_type(self.exploration_type):
            torch.manual_seed(seed)
            first = TensorDict({pref_key: pref_rows[row]}, batch_size=batch_size, device=dev)
            if ctx_rows is not None:
                first.set("context", ctx_rows[row])
            td = reset(first)
            out_dev = td.get("done").device
            if ctx_rows is not None:
                self._check_contexts(td, everyone.to(out_dev), ctx_rows[row].to(out_dev), row, rows_per_context)
            while True:
                if action_spec is not None:
                    td.set(action_key, action_spec.rand())
                else:
                    td = policy(td)
                active = row >= 0
                if not bool(active.all()):
                    # TorchRL partial step: domains that can (Box2D, MuJoCo) skip the idle sub-envs
                    td.set("_step", active.to(out_dev).reshape(batch_size))
                discount = td.get(discount_key) if sorl_key is not None else None
                td = inner.step(td)
                nxt = td.get("next")
                transform_step(returns, td, transform_step(prefs, td, nxt))
                if sorl_key is not None:
                    scalar = nxt.get(sorl_key, None)
                    if scalar is None:  # an env without the original scalar reward: no f_SORL
                        sorl_key = None
                    else:
                        scalar = scalar.reshape(m).to(torch.float64)
                        if sorl_acc is None:
                            sorl_acc = torch.zeros(m, 2, dtype=torch.float64, device=scalar.device)
                            sorl = torch.zeros(n_rows, 2, dtype=torch.float64)
                        sorl_acc += torch.stack([scalar, scalar * discount.reshape(m).to(scalar)], -1)
                run_len += active
                done = nxt.get("done").reshape(m).cpu()
                cut = active & (run_len >= horizon) & ~done
                if bool(cut.any()):
                    warnings.warn(f"{int(cut.sum())} episodes were still running after max_steps={horizon}; "
                                  "their returns are cut there", stacklevel=3)
                finished = active & (done | cut)
                td_next = env.step_mdp(td)
                resetting = done.clone() if self.reset_finished else torch.zeros_like(done)
                fresh = None
                if bool(finished.any()):
                    idx = finished.nonzero().squeeze(-1)
                    r = row[idx]
                    idx_d = idx.to(out_dev)
                    disc[r] = td.get(disc_key)[idx_d].to("cpu", torch.float64)
                    und[r] = td.get(und_key)[idx_d].to("cpu", torch.float64)
                    lengths[r] = run_len[idx]
                    run_len[idx] = 0
                    if sorl_key is not None:
                        idx_s = idx.to(sorl_acc.device)
                        sorl[r] = sorl_acc[idx_s].to("cpu")
                        sorl_acc[idx_s] = 0.0
                    # hand the next pending rows to the sub-envs that just finished
                    take = min(len(idx), n_rows - next_row)
                    row[idx] = -1
                    if take:
                        fresh = idx[:take]
                        row[fresh] = torch.arange(next_row, next_row + take)
                        next_row += take
                        fresh_d = fresh.to(out_dev)
                        pref = td_next.get(pref_key).clone()
                        pref[fresh_d] = pref_rows[row[fresh]].to(out_dev)
                        td_next.set(pref_key, pref)
                        if ctx_rows is not None:
                            ctx = td_next.get("context").clone()
                            ctx[fresh_d] = ctx_rows[row[fresh]].to(out_dev, ctx.dtype)
                            td_next.set("context", ctx)
                        resetting[fresh] = True
                    if not bool((row >= 0).any()):
                        break
                if bool(resetting.any()):
                    td_next.set("_reset", resetting.to(out_dev).reshape(td_next.get("done").shape))
                    td_next = reset(td_next)
                    if fresh is not None and ctx_rows is not None:
                        self._check_contexts(td_next, fresh.to(out_dev), ctx_rows[row[fresh]].to(out_dev), row[fresh],
                                            rows_per_context)
                td = td_next
        return disc, und, lengths, (sorl if sorl_key is not None else None)

    # ------------------------------------------------------------------ metrics
    def _result(self, disc, und, lengths, sorl=None, weights=None) -> EvaluationResult:
        values = disc.mean(dim=2).numpy()  # [C, W, k]
        per_context = {}
        eum_w = self.eum_weights.numpy()
        for i, name in enumerate(self.context_names):
            front = pareto_front(values[i])
            m: dict[str, float | int | None] = {
                "hypervolume": None if self.ref_point is None else hypervolume(front, self.ref_point,
                                                                                drop_unbounded=True),
                "eum": eum(front, eum_w), "sparsity": sparsity(front), "cardinality": cardinality(front)}
            b = self.bounds.get(name)
            if b is not None:
                m["normalized_hypervolume"] = normalized_hypervolume(front, b.lower, b.upper)
                m["normalized_eum"] = eum(normalize(front, b.lower, b.upper), eum_w)
            true = self.true_fronts.get(name)
            if true is not None:
                m["igd"] = igd(front, true)
                if self.ref_point is not None:
                    best = hypervolume(true, self.ref_point, drop_unbounded=True)
                    m["hv_ratio"] = m["hypervolume"] / best if best > 0 else None
            if self.reference is not None:
                m["nhgr"] = self.reference.nhgr(name, front)
                try:
                    m["eugr"] = self.reference.eugr(name, front, eum_w)
                except ValueError:  # specialist EUM <= 0: the ratio means nothing
                    m["eugr"] = None
            ctx = None if self.contexts is None else self.contexts[i].clone()
            per_context[name] = ContextResult(name, ctx, values[i], front, m)
        aggregate: dict[str, float] = {}
        for metric in next(iter(per_context.values())).metrics:
            vals = [r.metrics.get(metric) for r in per_context.values()]
            if all(v is not None for v in vals):
                aggregate[metric] = float(np.mean(vals))
        if self.reference is not None:
            nh = np.array([[r.metrics["nhgr"] for r in per_context.values()]])
            aggregate["nhgr_iqm"] = interquartile_mean(nh)
            aggregate["nhgr_optimality_gap"] = optimality_gap(nh)
        return EvaluationResult(
            context_names=self.context_names,
            contexts=torch.zeros(len(self.context_names), 0) if self.contexts is None else self.contexts.clone(),
            context_parameters=self.context_parameters, objective_names=self.objective_names,
            weights=(self.weights if weights is None else weights).clone(), returns=disc, undiscounted_returns=und,
            lengths=lengths, gamma=self.gamma, per_context=per_context, aggregate=aggregate,
            sorl_returns=None if sorl is None else sorl[..., 0].clone(),
            sorl_discounted_returns=None if sorl is None else sorl[..., 1].clone())

    def close(self) -> None:
        """Close the environments built so far."""
        for env in self._envs.values():
            if not env.is_closed:
                env.close()
        self._envs.clear()

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(contexts={len(self.context_names)}, weights={len(self.weights)}, "
            f"episodes={self.episodes}, gamma={self.gamma}, chunk_size={self.chunk_size}, "
            f"reference={'yes' if self.reference is not None else 'no'})"
        )


def suite_contexts(contexts: str | Sequence[str]) -> tuple:
    """``(domain spec, names, [C, c] context vectors)`` of the env ids ``contexts`` (one domain), or of
    a training id's evaluation suite: the contexts, in the order, that
    :class:`MultiContextEvaluator` evaluates for the same ``contexts``.

    Example:
        >>> spec, names, table = suite_contexts("MOLavaGridDR-v0")
        >>> len(names), names[0], table.shape
        (8, 'MOLavaGridCheckerBoard-v0', torch.Size([8, 93]))
    """
    from morl_trl.envs.registry import domain_of, evaluation_suite, is_randomized

    if isinstance(contexts, str):
        contexts = evaluation_suite(contexts) if is_randomized(contexts) else [contexts]
    ids = list(contexts)
    if not ids:
        raise ValueError("contexts is empty")
    if len(set(ids)) != len(ids):
        raise ValueError(f"duplicate context ids in {ids}")
    specs = [domain_of(i) for i in ids]  # raises on unknown ids
    domains = {s.train_id for s in specs}
    if len(domains) != 1:
        raise ValueError(f"contexts {ids} belong to several domains {sorted(domains)}; evaluate one domain at a time")
    return specs[0], tuple(ids), torch.stack([specs[0].context_of(i) for i in ids])


def _as_2d(weights):
    w = weights if isinstance(weights, torch.Tensor) else np.asarray(weights, dtype=np.float64)
    if w.ndim != 2 or w.shape[0] == 0:
        raise ValueError(f"weights must be a non-empty [W, k] weight set, got shape {tuple(w.shape)}")
    return w


def _as_tuple(key) -> tuple:
    return key if isinstance(key, tuple) else (key,)




