"""mkdocs hook: tables generated from the code at build time, so the pages cannot drift from it.

A page writes a marker comment and the build replaces it:

* ``<!-- morl:ids -->`` every domain: training id, objectives, evaluation ids, reference data;
* ``<!-- morl:params ID -->`` the context parameters of a domain (default, randomization range,
  valid bounds), from ``context_space(ID)``;
* ``<!-- morl:contexts ID -->`` the evaluation contexts of a domain, parameter by parameter;
* ``<!-- morl:floors -->`` the shipped floors (``morl-trl floors --markdown``);
* ``<!-- morl:settings ALGO -->`` the defaults ``morl-trl train ALGO ID`` resolves per domain.

A marker that cannot be rendered fails the build (no silent gap in the docs).
"""

from __future__ import annotations

import re

_MARKER = re.compile(r"<!--\s*morl:(\w+)\s*([^\s>]*)\s*-->")


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _reference_domains() -> set[str]:
    from morl_trl.reporting.reference import PACKAGED_REFERENCE, list_reference_domains

    return set(list_reference_domains(PACKAGED_REFERENCE))


def ids_table() -> str:
    from morl_trl.envs.registry import list_domains

    refs = _reference_domains()
    lines = ["| domain | training id | objectives | evaluation ids | reference data (NHGR) |", "|---|---|---|---|---|"]
    for d in list_domains():
        evals = ", ".join(f"`{e}`" for e in d.evaluation_ids)
        if d.train_id in refs:
            ref = "shipped: NHGR, EUGR"
        else:
            ref = "**none**: hypervolume and EUM only (the authors published no bounds or specialist fronts for it)"
        objs = ", ".join(d.objective_names)
        lines.append(f"| {d.name} | `{d.train_id}` | {objs} | {evals} | {ref} |")
    return "\n".join(lines)


def params_table(env_id: str) -> str:
    from morl_trl.envs.registry import context_space

    cs = context_space(env_id)
    lines = ["| parameter | default | randomized in (DR) | valid bounds |", "|---|---|---|---|"]
    lava = [n for n in cs.names if n.startswith("lava_")]
    default = cs.default_tensor().tolist()
    for i, n in enumerate(cs.names):
        if n in lava[1:]:
            continue
        name = f"`{n}`"
        if n == lava[0] if lava else False:
            name = f"`{lava[0]}` … `{lava[-1]}` ({len(lava)} cells, 1 = lava)"
        lines.append(f"| {name} | {_fmt(default[i])} | [{_fmt(cs.low[i])}, {_fmt(cs.high[i])}] | "
                     f"[{_fmt(cs.valid_low[i])}, {_fmt(cs.valid_high[i])}] |")
    return "\n".join(lines)


def contexts_table(env_id: str) -> str:
    from morl_trl.envs.registry import context_space, domain_of

    spec = domain_of(env_id)
    cs = context_space(env_id)
    ids = list(spec.evaluation_ids)
    short = [i.replace(spec.train_id.split("DR")[0].split("ZeroShot")[0], "").rsplit("-v", 1)[0].lstrip("-") or i for i in ids]
    values = {i: dict(zip(cs.names, spec.context_of(i).tolist())) if hasattr(spec, "context_of") else {} for i in ids}
    lava = [n for n in cs.names if n.startswith("lava_")]
    rows = [n for n in cs.names if n not in lava]
    lines = ["| parameter | " + " | ".join(short) + " |", "|---|" + "---|" * len(ids)]
    if lava:
        counts = [str(int(sum(values[i][n] for n in lava))) for i in ids]
        lines.append("| lava cells | " + " | ".join(counts) + " |")
    for n in rows:
        lines.append(f"| `{n}` | " + " | ".join(_fmt(values[i][n]) for i in ids) + " |")
    lines.append("")
    lines.append("Ids: " + ", ".join(f"`{i}`" for i in ids) + ".")
    return "\n".join(lines)


def floors_table() -> str:
    from morl_trl.reporting.floors import floors_markdown

    return floors_markdown()


# (config key, label) shown for every algorithm, then the algorithm's own keys
_COMMON = [("frames", "frames"), ("lr", "lr"), ("batch_size", "batch"), ("buffer_size", "buffer"),
           ("hidden", "network"), ("init_random_frames", "random frames"), ("gamma", "gamma")]
_OWN = {
    "envelope": ["eps_start", "eps_end", "eps_frames", "num_sampled_prefs", "homotopy_lambda0", "target_update_period"],
    "capql": ["alpha", "tau"],
    "mosac": ["alpha", "learn_alpha", "tau"],
    "mosac_discrete": ["alpha", "learn_alpha", "target_update_period"],
    "morld": ["pop_size", "exchange_every", "morld_schedule", "morld_update_passes", "weight_adaptation",
              "update_frequency"],
    "morld_psa": ["pop_size", "exchange_every", "morld_schedule", "morld_update_passes", "weight_adaptation",
                  "psa_delta"],
    "sac": ["alpha", "learn_alpha", "tau"],
    "pcn": ["pcn_scaling_factor", "pcn_er_episodes", "pcn_step_episodes", "pcn_model_updates", "pcn_noise"],
    "pgmorl": ["pgmorl_pop", "pgmorl_warmup", "pgmorl_evo_iterations", "pgmorl_eval_obs"],
    "gpi_ls": ["gpi_iteration_frames", "gpi_num_nets", "gpi_dropout"],
    "gpi_pd": ["gpi_iteration_frames", "gpi_num_nets", "gpi_dropout"],
}
# keys an algorithm's loop does not read (an on-policy or episodic learner)
_UNUSED = {"pgmorl": {"batch_size", "buffer_size", "init_random_frames"}, "pcn": {"buffer_size", "init_random_frames"}}
_PAPER_DOMAINS = ["MOLunarLanderDR-v0", "MOHopperDR-v5", "MOHalfCheetahDR-v5", "MOHumanoidDR-v5",
                  "MOLavaGridDR-v0", "MOSuperMarioBrosZeroShot-v2"]


# ours, not in the paper's grid: the domains whose action space they fit
_NOT_IN_PAPER = {"mosac": ["MOHopperDR-v5", "MOHalfCheetahDR-v5", "MOHumanoidDR-v5"],
                 "mosac_discrete": ["MOLunarLanderDR-v0", "MOLavaGridDR-v0"]}


def _paper_domains(algo: str) -> list[str]:
    """The domains the paper ran ``algo`` on: the blocks of examples/grid/paper.toml."""
    import tomllib
    from pathlib import Path

    if algo in _NOT_IN_PAPER:
        return _NOT_IN_PAPER[algo]
    spec = tomllib.loads((Path(__file__).parents[2] / "examples" / "grid" / "paper.toml").read_text())
    out = [d for b in spec["block"] if algo in b["algorithms"] for d in b["domains"]]
    return [d for d in _PAPER_DOMAINS if d in out]


def settings_table(algo: str) -> str:
    from morl_trl.recipes import resolve_config

    from morl_trl.envs.registry import domain_of

    skip = _UNUSED.get(algo, set())
    keys = [(k, label) for k, label in _COMMON if k not in skip] + [(k, k) for k in _OWN.get(algo, [])]
    rows = []
    for env_id in _paper_domains(algo):
        cfg = resolve_config(algo, env_id)
        values = {k: getattr(cfg, k, "-") for k, _ in keys}
        if values.get("gamma") is None:
            values["gamma"] = domain_of(env_id).gamma  # None: the domain's discount
        rows.append([f"`{env_id}`"] + [_fmt(values[k]) for k, _ in keys])
    if not rows:
        raise ValueError(f"no domain resolves a config for {algo!r}")
    lines = ["| domain | " + " | ".join(label for _, label in keys) + " |", "|---|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    lines.append("")
    lines.append(f"(`morl-trl train {algo} ID --print-config` prints every key.)")
    return "\n".join(lines)


_RENDER = {"ids": ids_table, "params": params_table, "contexts": contexts_table, "floors": floors_table,
           "settings": settings_table}


def render(markdown: str) -> str:
    def sub(m: re.Match) -> str:
        kind, arg = m.group(1), m.group(2)
        if kind not in _RENDER:
            raise ValueError(f"unknown docs marker morl:{kind}; valid: {sorted(_RENDER)}")
        fn = _RENDER[kind]
        return fn(arg) if arg else fn()

    return _MARKER.sub(sub, markdown)


def on_page_markdown(markdown, page, config, files, **kwargs):
    return render(markdown)
