"""Honest floors: what trivial policies score under the paper's protocol.

Under the paper's NHGR protocol (SPEC §2: energy weights, one episode each, the front of the
discounted returns, normalised by the frozen bounds and divided by the specialist's) a policy
that ignores everything can already score well: the spread of a random policy's (or a constant action's) returns
over 100 episodes is itself a front, and the frozen bounds were fitted on weak runs. On MO-LunarLander the
always-noop policy scores about 0.43, above the paper's Envelope (0.18). A learned policy's NHGR says little until
it is read against these floors.

For every domain with published reference data this module evaluates the trivial policies —
``"random"`` (uniform samples of the action spec) and each constant action (discrete domains:
every action index, named as the domain names its actions; continuous domains: the zero
action, ``"zero"``) — with :class:`~morl_trl.evaluation.MultiContextEvaluator` at its defaults
and the paper's protocol (the domain's evaluation suite, its number of weights — 100, Mario 32
— its gamma, one episode, seed 0), and records the NHGR per context.

The results ship as ``morl_trl/reporting/floors.json``, written by ``morl-trl floors
--reference DIR --write`` (incrementally, one (domain, policy) at a time), and show up in
``morl-trl reference-table`` (a ``floor: <policy>`` row per domain), in a run's ``report.md``
(a floor column and a floor line on the NHGR plot) and in the docs (concepts/nhgr-and-floors.md).

Example:
    >>> from morl_trl.reporting.floors import best_floor, load_floors
    >>> floors = load_floors()
    >>> best_floor(floors, "MOLunarLanderDR-v0").policy     # doctest: +SKIP
    'noop'
"""

from __future__ import annotations

import datetime
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
import torch

__all__ = ["FLOORS_FILE", "Floor", "trivial_policies", "constant_policy", "evaluate_floor", "load_floors", "best_floor",
           "floor_entries", "update_floors_file", "floors_markdown", "floors_main", "floor_at_weights"]

FLOORS_FILE = "floors.json"

# the actions' names where the domain's env does not carry them (SPEC §1.1, §1.3)
_ACTION_NAMES = {"MOLunarLanderDR-v0": ("noop", "left", "main", "right"),
                 "MOLavaGridDR-v0": ("left", "right", "forward")}


def _default_path() -> Path:
    return Path(str(resources.files("morl_trl.reporting").joinpath(FLOORS_FILE)))


# ---------------------------------------------------------------------- the policies
def _action_info(train_id: str) -> tuple[bool, int, tuple[str, ...]]:
    """``(discrete, n_or_dim, names)`` of the domain's action space."""
    from morl_trl.envs.registry import domain_of

    spec = domain_of(train_id)
    cls = spec.env_cls()
    if hasattr(cls, "action_names"):
        names = tuple(getattr(cls, "action_names"))
        names = tuple("noop" if n.upper() == "NOOP" else n for n in names)
        return True, len(names), names
    if train_id in _ACTION_NAMES:
        names = _ACTION_NAMES[train_id]
        return True, len(names), names
    env = cls(num_envs=1, context=spec.context_space.default_tensor(), seed=0, **dict(spec.env_kwargs))
    try:
        a = env.full_action_spec[env.action_key]
        if a.dtype in (torch.int64, torch.int32, torch.long):
            n = int(a.space.n)
            return True, n, tuple(f"action {i}" for i in range(n))
        return False, int(a.shape[-1]), ("zero",)
    finally:
        env.close()


def trivial_policies(train_id: str) -> dict[str, object]:
    """The domain's trivial policies: ``name -> "random"`` or ``name -> constant action``.

    Discrete domains: ``"random"`` and every action index (by its name, e.g. ``"noop"``);
    continuous ones: ``"random"`` and ``"zero"`` (the zero action).
    """
    discrete, n, names = _action_info(train_id)
    out: dict[str, object] = {"random": "random"}
    if discrete:
        for i, name in enumerate(names):
            out[name] = torch.tensor(i, dtype=torch.long)
    else:
        out["zero"] = torch.zeros(n, dtype=torch.float32)
    return out


def constant_policy(action: torch.Tensor, action_key: str = "action") -> Callable:
    """A policy that writes ``action`` (one sub-env's action) for every sub-env."""
    action = torch.as_tensor(action)

    def policy(td):
        a = action.to(td.device) if td.device is not None else action
        return td.set(action_key, a.expand(*td.batch_size, *action.shape).clone())

    return policy


@dataclass
class Floor:
    """A trivial policy's NHGR on a domain: per context, and mean ± population std over them."""

    domain: str
    policy: str
    nhgr: dict[str, float]

    @property
    def values(self) -> np.ndarray:
        return np.array(list(self.nhgr.values()), dtype=np.float64)

    @property
    def mean(self) -> float:
        return float(self.values.mean())

    @property
    def std(self) -> float:
        return float(self.values.std())  # ddof=0, as the paper's ±


def evaluate_floor(train_id: str, policy: str, reference, *, weights: int | None = None, seed: int = 0,
                   contexts: Sequence[str] | None = None) -> Floor:
    """Evaluate one trivial policy (a name from :func:`trivial_policies`) on the domain's suite.

    ``weights`` defaults to the paper's count (``DomainSpec.eval_weights``: 100, Mario 32); the
    evaluator runs at its defaults otherwise (one episode per weight, the domain's gamma,
    deterministic exploration, the whole grid as one batched env).
    """
    from morl_trl.envs.registry import domain_of
    from morl_trl.evaluation import MultiContextEvaluator

    spec = domain_of(train_id)
    policies = trivial_policies(train_id)
    if policy not in policies:
        raise ValueError(f"unknown trivial policy {policy!r} for {train_id}; valid: {list(policies)}")
    target = policies[policy]
    fn = "random" if isinstance(target, str) else constant_policy(target)
    ev = MultiContextEvaluator(fn, list(contexts) if contexts is not None else train_id,
                               weights=int(weights if weights is not None else spec.eval_weights), reference=reference,
                               seed=seed)
    try:
        result = ev.evaluate()
    finally:
        ev.close()
    nhgr = {c: float(result.per_context[c].metrics["nhgr"]) for c in result.context_names}
    return Floor(train_id, policy, nhgr)


# ---------------------------------------------------------------------- the shipped file
def load_floors(path: str | Path | None = None) -> dict:
    """The floors file (default: the shipped ``morl_trl/reporting/floors.json``); ``{}`` if absent."""
    p = Path(path) if path is not None else _default_path()
    if not p.is_file():
        return {}
    with p.open() as fh:
        return json.load(fh)


def floor_entries(floors: dict, domain: str) -> list[Floor]:
    """Every computed floor of ``domain`` in ``floors`` (a loaded floors file)."""
    d = floors.get("domains", {}).get(domain, {})
    return [Floor(domain, name, dict(e["nhgr"])) for name, e in d.get("policies", {}).items()]


def best_floor(floors: dict, domain: str) -> Floor | None:
    """The trivial policy with the highest mean NHGR on ``domain`` (``None`` if none computed)."""
    entries = floor_entries(floors, domain)
    return max(entries, key=lambda f: f.mean) if entries else None


def update_floors_file(path: str | Path, floor: Floor, *, weights: int, seed: int, gamma: float,
                       command: str, seconds: float, all_policies: Sequence[str]) -> dict:
    """Merge one computed floor into the JSON at ``path`` (written atomically) and return it."""
    path = Path(path)
    data = load_floors(path) if path.is_file() else {}
    data.setdefault(
        "description",
        "NHGR of trivial policies (random; each constant action, or the zero action) under the paper's "
        "protocol: MultiContextEvaluator at its defaults on the domain's evaluation suite, energy weights "
        "(100; Mario 32), one episode per weight, the domain's gamma, frozen bounds and specialist fronts "
        "from the published reference data. mean/std: over the suite's contexts (population std).",
    )
    data["command"] = "morl-trl floors --reference DIR --write"  # regenerates the whole file
    data["seed"] = seed
    dom = data.setdefault("domains", {}).setdefault(floor.domain, {})
    dom["weights"] = weights
    dom["seed"] = seed
    dom["gamma"] = gamma
    dom["episodes_per_weight"] = 1
    pols = dom.setdefault("policies", {})
    pols[floor.policy] = {"nhgr": floor.nhgr, "mean": floor.mean, "std": floor.std, "seconds": round(seconds, 1),
                          "command": command, "computed": datetime.date.today().isoformat()}
    dom["not_computed"] = [p for p in all_policies if p not in pols]
    best = max(pols, key=lambda p: pols[p]["mean"])
    dom["best"] = best
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=False) + "\n")
    tmp.replace(path)
    return data


def _restricted(reference, contexts: Sequence[str]):
    from morl_trl.reporting.reference import DomainReference

    return DomainReference(reference.domain, {c: reference.bounds[c] for c in contexts},
                           {c: reference.specialist_fronts[c] for c in contexts})


def floor_at_weights(train_id: str, weights: int, contexts: Sequence[str], reference, *,
                     cache: str | Path | None = None, known: dict[str, dict[str, float]] | None = None,
                     shipped: dict | None = None) -> tuple[Floor | None, str]:
    """The best trivial policy of ``train_id`` at ``weights`` evaluation weights on ``contexts``,
    and a sentence saying where it comes from.

    A floor is only comparable with a NHGR at the same number of weights (a front of 8 episodes
    is not a front of 100). In order: the shipped ``floors.json`` when it was computed at ``weights`` and covers
    ``contexts``; the ``cache`` file (same layout) when it holds them; otherwise every trivial policy is evaluated
    here (seed 0) and written to ``cache``. ``known``: NHGR per context already evaluated at this protocol (e.g.
    ``{"random": ...}`` from the run's own random-policy evaluation), used instead of evaluating them again.
    ``None`` (and the reason) when the domain has no reference data.
    """
    contexts = list(contexts)
    if reference is None:
        return None, f"no floor: {train_id} has no reference data (bounds and specialist fronts), so no NHGR"

    def best_of(floors: dict) -> Floor | None:
        dom = floors.get("domains", {}).get(train_id, {})
        if dom.get("weights") != weights:
            return None
        entries = [f for f in floor_entries(floors, train_id) if set(contexts) <= set(f.nhgr)]
        if not entries or dom.get("not_computed"):
            return None
        best = max(entries, key=lambda f: float(np.mean([f.nhgr[c] for c in contexts])))
        return Floor(train_id, best.policy, {c: best.nhgr[c] for c in contexts})

    shipped = load_floors() if shipped is None else shipped
    found = best_of(shipped)
    if found is not None:
        return found, f"the shipped floors.json ({weights} weights, seed 0)"
    if cache is not None and Path(cache).is_file():
        found = best_of(load_floors(cache))
        if found is not None:
            return found, f"computed at this run's {weights} weights and {len(contexts)} contexts, seed 0 ({Path(cache).name})"
    from morl_trl.envs.registry import domain_of

    ref = _restricted(reference, contexts)
    names = list(trivial_policies(train_id))
    floors: list[Floor] = []
    for name in names:
        t0 = time.perf_counter()
        if known and name in known and set(contexts) <= set(known[name]):
            floor = Floor(train_id, name, {c: float(known[name][c]) for c in contexts})
        else:
            floor = evaluate_floor(train_id, name, ref, weights=weights, seed=0, contexts=contexts)
        floors.append(floor)
        if cache is not None:
            update_floors_file(cache, floor, weights=weights, seed=0, gamma=float(domain_of(train_id).gamma),
                               command=f"floor_at_weights({train_id!r}, {weights})",
                               seconds=time.perf_counter() - t0, all_policies=names)
    best = max(floors, key=lambda f: f.mean)
    where = f"computed at this run's {weights} weights and {len(contexts)} contexts, seed 0"
    return best, where + (f" (cached in {Path(cache).name})" if cache is not None else "")


def floors_main(argv: list[str] | None = None) -> int:
    """``morl-trl floors``: compute (and with ``--write`` ship) the trivial policies' NHGR."""
    import argparse
    import shlex

    from morl_trl.envs.registry import domain_of
    from morl_trl.reporting.reference import list_reference_domains, load_domain_reference

    p = argparse.ArgumentParser(
        prog="morl-trl floors",
        description="NHGR of trivial policies (random, every constant action / the zero action) per domain and "
        "context under the paper's protocol; --write merges them into the shipped floors.json.",
    )
    p.add_argument("--reference", help="the published data (minmax_values/, specialist_fronts/)")
    p.add_argument("--domain", action="append", help="a training id (repeatable; default every domain with data)")
    p.add_argument("--policy", action="append", help="a trivial policy name (repeatable; default all of the domain's)")
    p.add_argument("--weights", type=int, help="evaluation weights (default the paper's: 100, Mario 32)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--write", nargs="?", const=str(_default_path()), metavar="PATH",
                   help=f"merge the results into PATH (default the shipped {FLOORS_FILE}), after each policy")
    p.add_argument("--skip-done", action="store_true", help="with --write: skip policies already in the file")
    p.add_argument("--markdown", action="store_true",
                   help="only print the shipped floors as the docs' Markdown table (computes nothing)")
    args, rest = p.parse_known_args(argv)
    if args.markdown:
        print(floors_markdown())
        return 0
    if rest:
        p.error(f"unrecognized arguments: {' '.join(rest)}")
    if not args.reference:
        p.error("--reference DIR is required (the published data), unless --markdown")
    domains = args.domain or list_reference_domains(args.reference)
    command = "morl-trl floors " + " ".join(shlex.quote(a) for a in (argv or []))
    for train_id in domains:
        spec = domain_of(train_id)
        try:
            spec.env_cls()
        except ImportError as err:
            print(f"{train_id}: skipped ({err})", flush=True)
            continue
        reference = load_domain_reference(args.reference, train_id)
        names = list(trivial_policies(train_id))
        chosen = args.policy or names
        unknown = [n for n in chosen if n not in names]
        if unknown:
            raise ValueError(f"unknown trivial policies {unknown} for {train_id}; valid: {names}")
        weights = int(args.weights or spec.eval_weights)
        done = set()
        if args.write and args.skip_done:
            done = set(load_floors(args.write).get("domains", {}).get(train_id, {}).get("policies", {}))
        for name in chosen:
            if name in done:
                continue
            t0 = time.perf_counter()
            floor = evaluate_floor(train_id, name, reference, weights=weights, seed=args.seed)
            dt = time.perf_counter() - t0
            print(f"{train_id:30s} {name:16s} NHGR {floor.mean:.3f} ± {floor.std:.3f}  ({dt:.0f} s)", flush=True)
            if args.write:
                update_floors_file(args.write, floor, weights=weights, seed=args.seed, gamma=float(spec.gamma),
                                   command=command, seconds=dt, all_policies=names)
    return 0


def floors_markdown(floors: dict | None = None) -> str:
    """The docs' floors table: per domain, random, the best constant action and the paper's best algorithm."""
    from morl_trl.reporting.paper import PAPER_NHGR, PAPER_ORDER, domain_name

    floors = load_floors() if floors is None else floors
    doms = floors.get("domains", {})
    lines = ["| domain | weights | random | best constant action | paper's best algorithm | not computed |",
             "|---|---|---|---|---|---|"]
    for d in [d for d in PAPER_ORDER if d in doms] + sorted(d for d in doms if d not in PAPER_ORDER):
        entries = {f.policy: f for f in floor_entries(floors, d)}
        rnd = entries.get("random")
        consts = [f for n, f in entries.items() if n != "random"]
        best_const = max(consts, key=lambda f: f.mean) if consts else None
        paper = PAPER_NHGR.get(d, {})
        top = max(paper, key=lambda a: paper[a][0]) if paper else None
        cells = [domain_name(d), str(doms[d].get("weights", "")),
                 "n/a" if rnd is None else f"{rnd.mean:.2f} ± {rnd.std:.2f}",
                 "n/a" if best_const is None else f"{best_const.mean:.2f} ± {best_const.std:.2f} ({best_const.policy})",
                 "n/a" if top is None else f"{paper[top][0]:.2f} ± {paper[top][1]:.2f} ({top})",
                 ", ".join(doms[d].get("not_computed", [])) or "-"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)

