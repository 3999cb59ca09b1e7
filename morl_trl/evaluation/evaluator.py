"""The multi-context evaluator: a policy on every (context, weight, episode) of an evaluation suite.

The whole grid runs as *one* batched environment whose sub-envs each get their context at
reset (the reset TensorDict's ``"context"``, read by
:class:`~morl_trl.envs.base.ContextualMOEnv`) and their preference in the TensorDict, so an
evaluation of ``C`` contexts × ``W`` weights × ``E`` episodes costs one ``step`` call per time
step (``chunk_size`` bounds the batch, and the memory, when the grid is large).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.envs import EnvBase, TransformedEnv
from torchrl.envs.utils import ExplorationType, set_exploration_type

from morl_trl.evaluation.results import ContextResult, EvaluationResult
from morl_trl.metrics import (
    Bounds,
    cardinality,
    eum,
    hypervolume,
    interquartile_mean,
    normalize,
    normalized_hypervolume,
    optimality_gap,
    pareto_front,
    sparsity,
)
from morl_trl.preferences import check_simplex, energy_weights

__all__ = ["MultiContextEvaluator"]

Policy = Callable[[TensorDictBase], TensorDictBase]


class MultiContextEvaluator:
    """Evaluate a preference-conditioned policy on every context of a suite, batched.

    For each context ``c``, weight ``w`` and episode ``e`` one sub-environment runs exactly one
    episode with context ``c`` while the policy reads ``w`` under ``preference_key``
    (``[*B, k]``). The discounted vector return of that episode is accumulated until its first
    ``done`` (terminated or truncated); the sub-env is masked afterwards and the loop stops when
    every sub-env is done. The value of ``(c, w)`` is the mean over episodes; the front of ``c``
    is the non-dominated subset of its ``W`` values (the paper's protocol, SPEC §2).

    Per context it reports ``hypervolume`` (against ``ref_point``, default the domain's; points
    that do not dominate it count for nothing, as in the paper), ``eum`` (over ``eum_weights``),
    ``sparsity`` and ``cardinality``; with bounds (``bounds`` or ``reference``)
    ``normalized_hypervolume`` and ``normalized_eum``; with a ``reference`` (frozen bounds and
    specialist fronts, :class:`~morl_trl.reporting.DomainReference`) ``nhgr`` and ``eugr``.

    Args:
        policy: a callable ``TensorDict -> TensorDict`` writing ``"action"`` (a
            ``TensorDictModule``, a ``ProbabilisticActor``, ...), or ``"random"`` to sample the
            env's action spec. A policy that ignores the preference (a single-objective
            baseline) works as is. Deterministic or stochastic actions are chosen with
            ``exploration_type`` (default deterministic: the mode/mean of a probabilistic
            actor; the paper evaluated MORL/D and SAC with ``ExplorationType.RANDOM``).
        contexts: a training id (its evaluation suite, e.g. ``"MOLunarLanderDR-v0"``), a list of
            env ids of one domain, or a mapping ``name -> context vector [c]`` (then pass
            ``env_factory``).
        weights: ``[W, k]`` preferences on the simplex, or an int ``W`` for
            :func:`~morl_trl.preferences.energy_weights` (default 100, the paper's).
        episodes: episodes per (context, weight) pair.
        gamma: discount (default: the domain's).
        env_factory: ``env_factory(num_envs=..., seed=...)`` building the batched env
            (default: the domain's env class on ``device``). It must read per-sub-env contexts
            from the reset TensorDict's ``"context"``.
        transform: a callable returning a TorchRL ``Transform`` (e.g. the
            ``StateActionHistory`` used in training); applied to every env built.
        reference: frozen bounds and specialist fronts for every context: adds NHGR, EUGR,
            normalized HV and EUM.
        bounds: ``name -> Bounds`` (or ``(lower, upper)``) for normalized HV and EUM without
            specialist fronts (``reference``'s bounds are used when not given).
        ref_point: unnormalized hypervolume reference point (default: the domain's).
        eum_weights: ``[M, k]`` weights of the EUM/EUGR (default: ``weights``).
        chunk_size: number of sub-envs of the batched env (default: the whole grid, one
            sub-env per row). A smaller pool bounds memory: its sub-envs stream through the
            grid, each taking the next pending (context, weight, episode) as soon as its
            episode ends. For envs whose cost is per sub-env (Box2D, MuJoCo), a pool of a
            few times fewer sub-envs than rows is also faster, since finished sub-envs no
            longer wait, being stepped, for the longest episode.
        exploration_type: TorchRL exploration type used while acting.
        device: device of the default env.
        seed: seed of everything random in the evaluation: the env (sub-env ``i`` is seeded
            with ``seed + i``) and torch's RNG while acting (stochastic policies); the global
            RNG state is restored afterwards. Results are reproducible for a given seed and
            ``chunk_size``.
        reset_finished: partially reset sub-envs once they are done even when no row is
            left for them, so that they keep stepping from valid states while masked (set
            ``False`` for domains that tolerate being stepped past their end).
        preference_key: where the policy reads the preference.
        max_steps: safety horizon (default: the env's ``max_episode_steps``); episodes still
            running then are cut, with a warning.

    Example:
        >>> from morl_trl.evaluation import MultiContextEvaluator
        >>> ev = MultiContextEvaluator("random", "MOLunarLanderDR-v0", weights=4, seed=0)
        >>> result = ev.evaluate()            # 8 contexts x 4 weights, one batched env of 32
        >>> result.returns.shape              # [contexts, weights, episodes, objectives]
        torch.Size([8, 4, 1, 4])
        >>> sorted(result.per_context["MOLunarLanderHard-v0"].metrics)
        ['cardinality', 'eum', 'hypervolume', 'sparsity']
    """

    def __init__(
        self,
        policy: Policy | str,
        contexts: str | Sequence[str] | Mapping[str, object],
        weights: torch.Tensor | np.ndarray | int | None = None,
        *,
        episodes: int = 1,
        gamma: float | None = None,
        env_factory: Callable[..., EnvBase] | None = None,
        transform: Callable[[], object] | None = None,
        reference=None,
        bounds: Mapping[str, object] | None = None,
        ref_point: Sequence[float] | None = None,
        eum_weights: torch.Tensor | np.ndarray | None = None,
        chunk_size: int | None = None,
        exploration_type: ExplorationType = ExplorationType.DETERMINISTIC,
        device: torch.device | str = "cpu",
        seed: int = 0,
        reset_finished: bool = True,
        preference_key: str = "preference",
        max_steps: int | None = None,
    ) -> None:
        if not (callable(policy) or policy == "random"):
            raise ValueError(f"policy must be a callable TensorDict -> TensorDict or 'random', got {policy!r}")
        self.policy = policy
        self.device = torch.device(device)
        self.transform = transform
        self.preference_key = preference_key
        self.exploration_type = exploration_type
        self.reset_finished = bool(reset_finished)
        self.seed = int(seed)
        if not isinstance(episodes, int) or episodes < 1:
            raise ValueError(f"episodes must be a positive int, got {episodes!r}")
        self.episodes = episodes

        self.domain = None
        self.context_names, self.contexts = self._resolve_contexts(contexts)
        if env_factory is None and self.domain is None:
            raise ValueError("contexts given as vectors need an env_factory(num_envs=..., seed=...)")
        self.env_factory = env_factory or self._domain_env
        self._envs: dict[int, EnvBase] = {}

        probe = self._build_env(1) if self.domain is None else None
        if self.domain is not None:
            self.objective_names = tuple(self.domain.objective_names)
        else:
            k = int(probe.full_reward_spec[probe.reward_key].shape[-1])
            names = getattr(probe, "objective_names", None) or ()
            self.objective_names = tuple(names) if len(names) == k else tuple(f"objective_{i}" for i in range(k))
        self.context_parameters = (
            tuple(self.domain.context_space.names)
            if self.domain is not None
            else tuple(getattr(getattr(probe, "context_space", None), "names", ()))
        )
        k = len(self.objective_names)
        if probe is not None and not probe.is_closed:
            probe.close()

        if weights is None:
            weights = 100
        if isinstance(weights, int):
            weights = energy_weights(k, weights)
        self.weights = torch.as_tensor(check_simplex(_as_2d(weights), k, name="weights"), dtype=torch.float64)
        self.eum_weights = (
            self.weights if eum_weights is None else torch.as_tensor(check_simplex(_as_2d(eum_weights), k, name="eum_weights"), dtype=torch.float64)
        )

        if gamma is None:
            if self.domain is None:
                raise ValueError("pass gamma: there is no domain to take the discount from")
            gamma = self.domain.gamma
        if not (isinstance(gamma, (int, float)) and 0.0 <= gamma <= 1.0):
            raise ValueError(f"gamma must be a number in [0, 1], got {gamma!r}")
        self.gamma = float(gamma)

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

        n_total = len(self.context_names) * len(self.weights) * episodes
        if chunk_size is None:
            chunk_size = n_total
        if not isinstance(chunk_size, int) or chunk_size < 1:
            raise ValueError(f"chunk_size must be a positive int, got {chunk_size!r}")
        self.chunk_size = min(chunk_size, n_total)
        self.max_steps = max_steps

    # ------------------------------------------------------------------ setup helpers
    def _resolve_contexts(self, contexts) -> tuple[tuple[str, ...], torch.Tensor]:
        from morl_trl.envs.registry import domain_of, evaluation_suite, is_randomized

        if isinstance(contexts, str):
            contexts = evaluation_suite(contexts) if is_randomized(contexts) else [contexts]
        if isinstance(contexts, Mapping):
            if not contexts:
                raise ValueError("contexts is empty")
            names = tuple(str(n) for n in contexts)
            vecs = []
            for n, v in contexts.items():
                v = torch.as_tensor(v, dtype=torch.float32)
                if v.ndim != 1 or not torch.isfinite(v).all():
                    raise ValueError(f"context {n!r} must be a finite vector [c], got {v.tolist()}")
                vecs.append(v)
            if len({v.shape for v in vecs}) != 1:
                raise ValueError(f"contexts have different sizes: {[tuple(v.shape) for v in vecs]}")
            return names, torch.stack(vecs)
        ids = list(contexts)
        if not ids:
            raise ValueError("contexts is empty")
        if len(set(ids)) != len(ids):
            raise ValueError(f"duplicate context ids in {ids}")
        specs = [domain_of(i) for i in ids]  # raises on unknown ids
        domains = {s.train_id for s in specs}
        if len(domains) != 1:
            raise ValueError(
                f"contexts {ids} belong to several domains {sorted(domains)}; evaluate one domain at a time"
            )
        self.domain = specs[0]
        return tuple(ids), torch.stack([self.domain.context_of(i) for i in ids])

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

    def _domain_env(self, num_envs: int, seed: int) -> EnvBase:
        spec = self.domain
        cls = spec.env_cls()
        return cls(
            num_envs=num_envs,
            context=spec.context_space.default_tensor(),
            device=self.device,
            seed=seed,
            **dict(spec.env_kwargs),
        )

    def _build_env(self, num_envs: int) -> EnvBase:
        env = self.env_factory(num_envs=num_envs, seed=self.seed)
        if tuple(env.batch_size) != (num_envs,):
            raise ValueError(f"env_factory(num_envs={num_envs}) built an env of batch size {tuple(env.batch_size)}")
        if self.transform is not None:
            env = TransformedEnv(env, self.transform())
        return env

    def _env(self, num_envs: int) -> EnvBase:
        # one env per batch size (the last chunk may be smaller), kept for later evaluations
        env = self._envs.get(num_envs)
        if env is None:
            env = self._envs[num_envs] = self._build_env(num_envs)
        return env

    # ------------------------------------------------------------------ running
    def evaluate(self, policy: Policy | str | None = None) -> EvaluationResult:
        """Run the grid (optionally with another ``policy``) and compute every metric."""
        policy = self.policy if policy is None else policy
        C, W, E = len(self.context_names), len(self.weights), self.episodes
        k = len(self.objective_names)
        # grid row r = (c * W + w) * E + e
        ctx_rows = self.contexts.repeat_interleave(W * E, dim=0)
        pref_rows = self.weights.repeat_interleave(E, dim=0).repeat(C, 1)
        disc, und, lengths = self._run_pool(policy, ctx_rows, pref_rows)
        return self._result(disc.reshape(C, W, E, k), und.reshape(C, W, E, k), lengths.reshape(C, W, E))

    __call__ = evaluate

    def _run_pool(self, policy, ctx_rows: torch.Tensor, pref_rows: torch.Tensor):
        """Run every grid row as one episode on a pool of ``chunk_size`` sub-envs.

        Sub-env ``i`` starts on row ``i``; whenever a sub-env finishes its episode it is
        partially reset with the context of the next pending row (so a pool smaller than the
        grid streams through it without waiting for the slowest episode of a batch). With
        the default pool (the whole grid) every row has its own sub-env, seeded ``seed + r``.
        """
        n_rows = ctx_rows.shape[0]
        m = self.chunk_size
        env = self._env(m)
        dev = env.device
        k = len(self.objective_names)
        env.set_seed(self.seed)

        row = torch.arange(m, device=dev)  # the grid row each sub-env runs (-1: idle)
        next_row = m
        ctx_rows, pref_rows = ctx_rows.to(dev), pref_rows.to(dev, torch.float32)
        pref = pref_rows[row]
        factor = torch.ones(m, dtype=torch.float64, device=dev)
        run_disc = torch.zeros(m, k, dtype=torch.float64, device=dev)
        run_und = torch.zeros(m, k, dtype=torch.float64, device=dev)
        run_len = torch.zeros(m, dtype=torch.long, device=dev)
        disc = torch.zeros(n_rows, k, dtype=torch.float64, device=dev)
        und = torch.zeros(n_rows, k, dtype=torch.float64, device=dev)
        lengths = torch.zeros(n_rows, dtype=torch.long, device=dev)
        reward_key = ("next", *_as_tuple(env.reward_key))

        horizon = self.max_steps or getattr(env, "max_episode_steps", None) or 100_000
        rng_devices = [dev.index or 0] if dev.type == "cuda" else []
        with torch.random.fork_rng(devices=rng_devices), torch.no_grad(), set_exploration_type(self.exploration_type):
            torch.manual_seed(self.seed)
            td = env.reset(
                TensorDict({"context": ctx_rows[row], self.preference_key: pref}, batch_size=env.batch_size, device=dev)
            )
            while True:
                td.set(self.preference_key, pref)
                if policy == "random":
                    td.set(env.action_key, env.full_action_spec[env.action_key].rand())
                else:
                    td = policy(td)
                active = row >= 0
                if not bool(active.all()):
                    # TorchRL partial step: domains that can (Box2D, MuJoCo) skip the idle sub-envs
                    td.set("_step", active.reshape(env.batch_size))
                td = env.step(td)
                reward = td.get(reward_key).reshape(m, k).to(torch.float64)
                run_disc += torch.where(active.unsqueeze(-1), factor.unsqueeze(-1) * reward, 0.0)
                run_und += torch.where(active.unsqueeze(-1), reward, 0.0)
                run_len += active
                factor *= self.gamma
                done = td.get(("next", "done")).reshape(m)
                cut = active & (run_len >= horizon) & ~done
                if cut.any():
                    warnings.warn(
                        f"{int(cut.sum())} episodes were still running after max_steps={horizon}; "
                        "their returns are cut there",
                        stacklevel=3,
                    )
                finished = active & (done | cut)
                td_next = env.step_mdp(td)
                reset = done.clone() if self.reset_finished else torch.zeros_like(done)
                if finished.any():
                    idx = finished.nonzero().squeeze(-1)
                    r = row[idx]
                    disc[r], und[r], lengths[r] = run_disc[idx], run_und[idx], run_len[idx]
                    run_disc[idx], run_und[idx], run_len[idx], factor[idx] = 0.0, 0.0, 0, 1.0
                    # hand the next pending rows to the sub-envs that just finished
                    take = min(len(idx), n_rows - next_row)
                    row[idx] = -1
                    if take:
                        fresh = idx[:take]
                        row[fresh] = torch.arange(next_row, next_row + take, device=dev)
                        next_row += take
                        pref = pref_rows[row.clamp(min=0)]
                        ctx = td_next.get("context").clone()
                        ctx[fresh] = ctx_rows[row[fresh]]
                        td_next.set("context", ctx)
                        reset[fresh] = True
                    if not (row >= 0).any():
                        break
                if reset.any():
                    td_next.set("_reset", reset.reshape(td_next.get("done").shape))
                    td_next = env.reset(td_next)
                td = td_next
        return disc.cpu(), und.cpu(), lengths.cpu()

    # ------------------------------------------------------------------ metrics
    def _result(self, disc, und, lengths) -> EvaluationResult:
        values = disc.mean(dim=2).numpy()  # [C, W, k]
        per_context = {}
        eum_w = self.eum_weights.numpy()
        for i, name in enumerate(self.context_names):
            front = pareto_front(values[i])
            m: dict[str, float | int | None] = {
                "hypervolume": None
                if self.ref_point is None
                else hypervolume(front, self.ref_point, drop_unbounded=True),
                "eum": eum(front, eum_w),
                "sparsity": sparsity(front),
                "cardinality": cardinality(front),
            }
            b = self.bounds.get(name)
            if b is not None:
                m["normalized_hypervolume"] = normalized_hypervolume(front, b.lower, b.upper)
                m["normalized_eum"] = eum(normalize(front, b.lower, b.upper), eum_w)
            if self.reference is not None:
                m["nhgr"] = self.reference.nhgr(name, front)
                try:
                    m["eugr"] = self.reference.eugr(name, front, eum_w)
                except ValueError:  # specialist EUM <= 0: the ratio means nothing
                    m["eugr"] = None
            per_context[name] = ContextResult(name, self.contexts[i].clone(), values[i], front, m)
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
            contexts=self.contexts.clone(),
            context_parameters=self.context_parameters,
            objective_names=self.objective_names,
            weights=self.weights.clone(),
            returns=disc,
            undiscounted_returns=und,
            lengths=lengths,
            gamma=self.gamma,
            per_context=per_context,
            aggregate=aggregate,
        )

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


def _as_2d(weights):
    w = weights if isinstance(weights, torch.Tensor) else np.asarray(weights, dtype=np.float64)
    if w.ndim != 2 or w.shape[0] == 0:
        raise ValueError(f"weights must be a non-empty [W, k] weight set, got shape {tuple(w.shape)}")
    return w


def _as_tuple(key) -> tuple:
    return key if isinstance(key, tuple) else (key,)




