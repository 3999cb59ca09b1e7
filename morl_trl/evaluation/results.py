"""Result types of the multi-context evaluator: every episode, every front, every metric, by name."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

__all__ = ["ContextResult", "EvaluationResult"]


@dataclass
class ContextResult:
    """What one evaluation context produced.

    Attributes:
        name: the context's name (an env id such as ``"MOLunarLanderHard-v0"``).
        context: its parameter vector ``[c]`` (``None`` when the env has no context vector).
        values: ``[W, k]`` discounted vector return per weight, averaged over the episodes.
        front: ``[m, k]`` the non-dominated, de-duplicated subset of ``values``.
        metrics: metric name -> value (``None`` where it is not defined, e.g. EUGR when the
            specialist's EUM is not positive, or a metric whose inputs were not given).
    """

    name: str
    context: torch.Tensor | None
    values: np.ndarray
    front: np.ndarray
    metrics: dict[str, float | int | None] = field(default_factory=dict)


@dataclass
class EvaluationResult:
    """The evaluation of one policy on a grid of contexts × weights × episodes.

    Attributes:
        context_names: ``C`` names, in order.
        contexts: ``[C, c]`` the context vectors (``[C, 0]`` for envs without one).
        context_parameters: the names of the ``c`` context parameters (may be empty).
        objective_names: the ``k`` objective names.
        weights: ``[W, k]`` the preferences the policy was conditioned on.
        returns: ``[C, W, E, k]`` discounted vector return of every episode (float64).
        undiscounted_returns: ``[C, W, E, k]`` the plain sum of vector rewards.
        lengths: ``[C, W, E]`` episode lengths (steps up to and including the first done).
        gamma: the discount.
        per_context: name -> :class:`ContextResult`.
        aggregate: metric -> mean over contexts (plus ``nhgr_iqm`` and
            ``nhgr_optimality_gap`` when NHGR was computed); metrics undefined in some context
            are left out.
        sorl_returns: ``[C, W, E]`` the undiscounted return of the env's original scalar reward
            (the domain's f_SORL, ``"original_reward"``) of every episode; ``None`` when the env
            has none (see :meth:`sorl_best`).
        sorl_discounted_returns: ``[C, W, E]`` the same, discounted with ``gamma``.
    """

    context_names: tuple[str, ...]
    contexts: torch.Tensor
    context_parameters: tuple[str, ...]
    objective_names: tuple[str, ...]
    weights: torch.Tensor
    returns: torch.Tensor
    undiscounted_returns: torch.Tensor
    lengths: torch.Tensor
    gamma: float
    per_context: dict[str, ContextResult]
    aggregate: dict[str, float]
    sorl_returns: torch.Tensor | None = None
    sorl_discounted_returns: torch.Tensor | None = None

    # ------------------------------------------------------------------ accessors
    def front(self, context: str) -> np.ndarray:
        """The ``[m, k]`` Pareto front of ``context``."""
        return self._ctx(context).front

    def metric(self, name: str) -> dict[str, float | int | None]:
        """``{context: value}`` of one metric."""
        return {c: r.metrics.get(name) for c, r in self.per_context.items()}

    def _ctx(self, context: str) -> ContextResult:
        try:
            return self.per_context[context]
        except KeyError:
            raise ValueError(f"no context {context!r}; evaluated: {list(self.context_names)}") from None

    # ------------------------------------------------------------------ f_SORL
    @property
    def has_sorl(self) -> bool:
        """Whether the env emitted its original scalar reward (f_SORL) and it was recorded."""
        return self.sorl_returns is not None

    def sorl_values(self, discounted: bool = False) -> np.ndarray:
        """``[C, W]`` the f_SORL return of each (context, weight), averaged over its episodes."""
        if not self.has_sorl:
            raise ValueError("no f_SORL: the env emits no original scalar reward ('original_reward')")
        t = self.sorl_discounted_returns if discounted else self.sorl_returns
        return t.mean(dim=2).numpy()

    def sorl_best(self) -> dict[str, dict[str, object]]:
        """Per context, the paper's "max over weights" of the f_SORL return (SPEC §3
        ``eval/single_objective_return``) and the weight that gave it (the first on ties):
        ``{context: {"return_max", "best_weight_index", "best_weight",
        "discounted_return_max", "discounted_best_weight_index", "discounted_best_weight"}}``
        (weights as ``{objective: value}``). For a policy that ignores the weight (SAC) this
        is the best of ``W`` episodes, and the "best weight" names only the episode."""
        out: dict[str, dict[str, object]] = {}
        und, disc = self.sorl_values(False), self.sorl_values(True)
        w = self.weights.tolist()
        for ci, cname in enumerate(self.context_names):
            row: dict[str, object] = {}
            for prefix, values in (("", und[ci]), ("discounted_", disc[ci])):
                i = int(np.argmax(values))
                row[f"{prefix}return_max"] = float(values[i])
                row[f"{prefix}best_weight_index"] = i
                row[f"{prefix}best_weight"] = dict(zip(self.objective_names, w[i]))
            out[cname] = row
        return out

    def sorl_rows(self) -> list[dict[str, object]]:
        """One row per (context, weight): the weight by objective, its f_SORL return
        (undiscounted and discounted, mean over episodes) and whether it is the context's best;
        empty without f_SORL."""
        if not self.has_sorl:
            return []
        und, disc = self.sorl_values(False), self.sorl_values(True)
        best = und.argmax(1)
        best_d = disc.argmax(1)
        w = self.weights.tolist()
        rows = []
        for ci, cname in enumerate(self.context_names):
            for wi in range(len(w)):
                row: dict[str, object] = {"context": cname, "weight_index": wi}
                row.update({f"weight_{o}": w[wi][j] for j, o in enumerate(self.objective_names)})
                row["sorl_return"] = float(und[ci, wi])
                row["sorl_discounted_return"] = float(disc[ci, wi])
                row["best"] = int(wi == best[ci])
                row["best_discounted"] = int(wi == best_d[ci])
                rows.append(row)
        return rows

    # ------------------------------------------------------------------ flat views for logging
    def to_rows(self) -> list[dict[str, object]]:
        """One row per (context, weight, episode): the weight and the returns, each objective by name."""
        C, W, E, _ = self.returns.shape
        ret = self.returns.tolist()
        und = self.undiscounted_returns.tolist()
        lengths = self.lengths.tolist()
        w = self.weights.tolist()
        sorl = None if not self.has_sorl else (self.sorl_returns.tolist(), self.sorl_discounted_returns.tolist())
        rows = []
        for ci, cname in enumerate(self.context_names):
            for wi in range(W):
                for e in range(E):
                    row: dict[str, object] = {"context": cname, "weight_index": wi, "episode": e}
                    row.update({f"weight_{o}": w[wi][j] for j, o in enumerate(self.objective_names)})
                    row.update({f"return_{o}": ret[ci][wi][e][j] for j, o in enumerate(self.objective_names)})
                    row.update(
                        {f"undiscounted_return_{o}": und[ci][wi][e][j] for j, o in enumerate(self.objective_names)}
                    )
                    row["length"] = lengths[ci][wi][e]
                    if sorl is not None:
                        row["sorl_return"] = sorl[0][ci][wi][e]
                        row["sorl_discounted_return"] = sorl[1][ci][wi][e]
                    rows.append(row)
        return rows

    def metric_rows(self) -> list[dict[str, object]]:
        """One row per context: its parameters by name, every metric and, with f_SORL, its max
        over weights and the best weight (``sorl_return_max``, ``sorl_best_weight_index``,
        ``sorl_best_weight_<objective>``, and the same for the discounted return)."""
        rows = []
        best = self.sorl_best() if self.has_sorl else {}
        for i, cname in enumerate(self.context_names):
            r = self.per_context[cname]
            row: dict[str, object] = {"context": cname}
            if self.context_parameters:
                row.update({p: float(v) for p, v in zip(self.context_parameters, self.contexts[i].tolist())})
            row.update(r.metrics)
            if cname in best:
                b = best[cname]
                for prefix in ("", "discounted_"):
                    row[f"sorl_{prefix}return_max"] = b[f"{prefix}return_max"]
                    row[f"sorl_{prefix}best_weight_index"] = b[f"{prefix}best_weight_index"]
                    row.update({f"sorl_{prefix}best_weight_{o}": v for o, v in b[f"{prefix}best_weight"].items()})
            rows.append(row)
        return rows

    def front_rows(self) -> list[dict[str, object]]:
        """One row per front point: context and the value of each objective by name."""
        rows = []
        for cname in self.context_names:
            for p in self.per_context[cname].front.tolist():
                rows.append({"context": cname, **{o: v for o, v in zip(self.objective_names, p)}})
        return rows

    def summary(self, prefix: str = "eval") -> dict[str, float]:
        """Flat ``{f"{prefix}/{metric}/{context}": value, f"{prefix}/{metric}/mean": ...}`` for a logger.

        Undefined values are left out.
        """
        out: dict[str, float] = {}
        for cname, r in self.per_context.items():
            for m, v in r.metrics.items():
                if v is not None and not (isinstance(v, float) and math.isnan(v)):
                    out[f"{prefix}/{m}/{cname}"] = float(v)
        for m, v in self.aggregate.items():
            out[f"{prefix}/{m}/mean" if not m.startswith("nhgr_") else f"{prefix}/{m}"] = float(v)
        if self.has_sorl:  # the paper's eval/single_objective_return/<env> and its best weight
            for cname, b in self.sorl_best().items():
                out[f"{prefix}/sorl_return_max/{cname}"] = b["return_max"]
                out[f"{prefix}/sorl_discounted_return_max/{cname}"] = b["discounted_return_max"]
                for o, v in b["best_weight"].items():
                    out[f"{prefix}/sorl_best_weight_{o}/{cname}"] = float(v)
        return out

    def write_csv(self, path: str | Path, kind: str = "episodes") -> Path:
        """Write ``to_rows()`` (``kind="episodes"``), ``metric_rows()`` (``"metrics"``),
        ``front_rows()`` (``"fronts"``) or ``sorl_rows()`` (``"sorl"``) as CSV."""
        makers = {"episodes": self.to_rows, "metrics": self.metric_rows, "fronts": self.front_rows,
                  "sorl": self.sorl_rows}
        if kind not in makers:
            raise ValueError(f"unknown kind {kind!r}; valid: {list(makers)}")
        rows = makers[kind]()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        keys = list(dict.fromkeys(k for r in rows for k in r))
        with path.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=keys)
            w.writeheader()
            w.writerows(rows)
        return path

    def __repr__(self) -> str:
        C, W, E, k = self.returns.shape
        agg = ", ".join(f"{m}={v:.4g}" for m, v in self.aggregate.items())
        return (
            f"EvaluationResult(contexts={C}, weights={W}, episodes={E}, "
            f"objectives={list(self.objective_names)}, {agg})"
        )
