"""The ``morl-trl`` command line: every entry point of the package, in one place.

Each subcommand is a small function that parses its own arguments and imports what it needs
only when it runs (``morl-trl envs`` loads no simulator, no training code).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import sys
import time
from pathlib import Path

__all__ = ["main", "COMMANDS"]


def plain(text: str | None) -> str | None:
    """Docstring reStructuredText as plain text for ``--help``: ``x`` -> x, :func:`~a.b` -> b."""
    if not text:
        return text
    text = re.sub(r":\w+:`~?([^`<]*?)(?:\s*<[^>]*>)?`", lambda m: m.group(1).rsplit(".", 1)[-1] if "~" in m.group(0)
                  else m.group(1), text)
    return re.sub(r"``([^`]+)``", r"\1", text)


class _Parser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` whose description and argument help are shown without reST markup."""

    def __init__(self, *args, description: str | None = None, **kwargs) -> None:
        super().__init__(*args, description=plain(description), **kwargs)

    def add_argument(self, *args, **kwargs):
        if isinstance(kwargs.get("help"), str):
            kwargs["help"] = plain(kwargs["help"])
        return super().add_argument(*args, **kwargs)


def version() -> str:
    """The package's version, from its installed metadata (``unknown`` when it is not installed)."""
    from importlib.metadata import PackageNotFoundError, version as _version

    try:
        return _version("morl-trl")
    except PackageNotFoundError:
        return "unknown"


def parse_overrides(items: list[str]) -> dict:
    """``["lr=1e-3", "hidden=[64,64]", "device=cuda"]`` -> config overrides. Values are TOML
    (numbers, booleans, lists, quoted strings); a value that is not TOML is taken as a string."""
    import tomllib

    out = {}
    for item in items:
        key, sep, raw = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"override {item!r} is not KEY=VALUE (e.g. lr=1e-3, hidden=[64,64], prioritized=false)")
        key = key.rsplit(".", 1)[-1]  # a grouped key (optim.lr) names the same flat key
        try:
            value = tomllib.loads(f"v = {raw.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw.strip()
        out[key] = value
    return out


def _default_reference() -> str | None:
    """``$MORL_TRL_REFERENCE`` or ``../shared/reference`` when it holds the published data."""
    for cand in (os.environ.get("MORL_TRL_REFERENCE"), "../shared/reference"):
        if cand and (Path(cand) / "minmax_values").is_dir():
            return cand
    return None


# ---------------------------------------------------------------------- train / evaluate
def _add_trust_code(p) -> None:
    p.add_argument("--trust-code", action="append", default=[], metavar="PKG.MODULE",
                   help="import this domain module named by the run's config (it runs that module's code: only for "
                        "a run you trust); repeatable. Without it, only modules already imported or registered by an "
                        "installed package's entry point are")


def train_main(argv: list[str]) -> int:
    """``morl-trl train``: the config the command line gives, then the algorithm's loop in the opened run."""
    from morl_trl.cli_args import check_algorithm, join_negative_values, split_positionals
    from morl_trl.recipes.config import ALGORITHMS  # (the config package imports no torch: --help answers at once)

    p = _train_parser(ALGORITHMS)
    args = p.parse_intermixed_args(join_negative_values(argv, ("--ref-point",)))
    names, moved = split_positionals([args.algo, args.env_id])
    args.algo, args.env_id = (names + [None, None])[:2]
    if not args.resume and args.env_id is None:
        p.error("the following arguments are required: ALGO, ENV_ID (or --resume RUN_DIR alone)")
    if args.algo is not None:
        check_algorithm(args.algo, ALGORITHMS)
    args.overrides = parse_overrides([*moved, *args.overrides, *args.set_])
    ref_point = _ref_point(args.ref_point)
    cfg = _resume_config(args) if args.resume else _new_config(args, ref_point)
    if args.print_config:
        print(cfg.to_toml())
        return 0
    from morl_trl.algorithms.registry import algorithm
    from morl_trl.recipes import NonFiniteLossError, open_run

    with open_run(cfg, resume=args.resume, overwrite=args.overwrite, trust_pickle=args.trust_pickle,
                  trust_code=args.trust_code) as run:
        if not run.done:
            try:
                algorithm(run.cfg.algo).train(run)  # the algorithm's own loop, e.g. train_envelope
            except NonFiniteLossError as err:
                return _stopped(err)
    return 0


def _new_config(args, ref_point):
    """The config of a new run: the algorithm's, the record's for the env, --quick, --config, the
    KEY=VALUE overrides, then the flags (each layer wins over the one before)."""
    _check_config_env_id(args)
    _check_keys(args.overrides, args.algo)
    from morl_trl.recipes import resolve_config

    reference = args.reference or _default_reference()
    flags = dict(frames=args.frames, seed=args.seed, device=args.device, run_dir=args.run_dir, reference_dir=reference,
                 logger=args.logger, progress=False if args.no_progress else None,
                 ref_point=ref_point, domain_modules=tuple(args.domain_module) or None)
    overrides = {**args.overrides, **{k: v for k, v in flags.items() if v is not None}}  # flags win
    return resolve_config(args.algo, args.env_id, quick=args.quick, config_file=args.config, **overrides)


def _train_parser(algorithms) -> "_Parser":
    """``morl-trl train``'s arguments."""
    from morl_trl.cli_args import frame_count

    p = _Parser(
        prog="morl-trl train",
        description="Train a generalist under domain randomization, evaluate it on the evaluation suite, report.",
    )
    p.add_argument("algo", nargs="?", metavar="ALGO",
                   help=f"algorithm: {', '.join(algorithms)} (with --resume: the run's, may be left out)")
    p.add_argument("env_id", nargs="?", metavar="ENV_ID",
                   help="training env id, e.g. MOLunarLanderDR-v0 (morl-trl envs lists them) or any MO-Gymnasium id "
                        "(with --resume: the run's, may be left out)")
    p.add_argument("overrides", nargs="*", metavar="KEY=VALUE",
                   help="config overrides, e.g. lr=1e-3 hidden=[64,64] prioritized=false (TOML values; they win "
                        "over --config, and the flags below win over them)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="set_",
                   help="a config override, as KEY=VALUE after the env id (repeatable)")
    p.add_argument("--frames", type=frame_count, help="environment frames to train for: 300000, 3e5, 300k, 3M")
    p.add_argument("--seed", type=int, help="one seed for contexts, preferences, networks and evaluation")
    p.add_argument("--device", help="cpu, cuda, ...")
    p.add_argument("--config", help="a .toml/.json file of config overrides")
    p.add_argument("--quick", action="store_true", help="a preset that finishes in a few CPU minutes")
    p.add_argument("--run-dir", help="where to write the run (default runs/<algo>_<env>_s<seed>_<time>)")
    p.add_argument("--reference", help="the published data (bounds, specialist fronts) for NHGR; "
                   "default $MORL_TRL_REFERENCE or ../shared/reference if present")
    p.add_argument("--logger", choices=("csv", "tensorboard", "wandb", "none"))
    p.add_argument("--resume", metavar="RUN_DIR",
                   help="continue a run from its newest intact checkpoint (damaged ones are skipped with a "
                   "warning); logs are first cut back to that checkpoint. ALGO and ENV_ID may be left out (the "
                   "run's config.json names them); given, they and --seed, --config and --quick values must match "
                   "the run's config.json (a difference is an error); --frames "
                   "(total frames: extend the run), --device, --logger and --no-progress may change. A run that "
                   "already reached its frames is left as it is")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the contents of a non-empty --run-dir (without it, a non-empty run dir is an error)")
    p.add_argument("--trust-pickle", action="store_true",
                   help="with --resume: accept a checkpoint of the old pickled format (loading it can run code "
                   "stored in it; only for a run you trust). `morl-trl convert-run RUN` converts it once instead")
    _add_trust_code(p)
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--ref-point", metavar="X1,X2,...",
                   help="hypervolume reference point, one number per objective, e.g. --ref-point -1,-1,-1 (default: "
                        "the env's; a MO-Gymnasium id's by the rule in docs/tutorials/mo-gymnasium.md)")
    p.add_argument("--domain-module", action="append", default=[], metavar="PKG.MODULE",
                   help="import this module first: it registers your own domains (its SPECS); repeatable")
    p.add_argument("--print-config", action="store_true", help="print the complete resolved config (grouped TOML) and exit")
    return p


def _check_keys(overrides: dict, algo: str) -> None:
    """The command line's KEY=VALUE keys are config keys (a "did you mean" error otherwise), checked
    before the heavy stack is imported (a key of another algorithm is refused when resolving)."""
    from morl_trl.recipes.config import KEYS, RENAMED, valid_keys
    from morl_trl.recipes.config.keys import unknown_keys_message

    unknown = sorted(set(overrides) - set(KEYS) - set(RENAMED))
    if unknown:
        raise ValueError(unknown_keys_message(unknown, valid_keys(algo), "overrides", algo))


def _ref_point(text: str | None) -> tuple[float, ...] | None:
    """``--ref-point 0,-25`` as a tuple of floats (a clear error for anything else)."""
    if text is None:
        return None
    try:
        return tuple(float(x) for x in text.replace(" ", "").strip("[]()").split(","))
    except ValueError:
        raise ValueError(f"--ref-point {text!r}: give one number per objective, comma-separated, e.g. 0,-25") from None


def _check_config_env_id(args) -> None:
    """A --config file that names another env id than the command line's is an error (not a silent switch)."""
    if not args.config:
        return
    from morl_trl.recipes.config import load_config_file

    named = load_config_file(args.config).get("env_id")
    if named is not None and named != args.env_id:
        raise ValueError(f"config file {args.config!r} is for env_id {named!r} but the command line gives "
                         f"{args.env_id!r}: give the same id (or drop env_id from the file)")


def _resume_config(args):
    """The run's config.json, checked against what the command line gives (see ``--resume``)."""
    from morl_trl.recipes.config import TrainConfig, load_config_file, quick_preset, resume_config

    run_dir = Path(args.resume)
    if args.overwrite:
        raise ValueError("--resume continues a run and --overwrite replaces it: choose one")
    if args.run_dir and Path(args.run_dir).resolve() != run_dir.resolve():
        raise ValueError(f"--run-dir {args.run_dir!r} and --resume {args.resume!r} name different directories")
    if not (run_dir / "config.json").is_file():
        raise ValueError(f"cannot resume: {str(run_dir)!r} has no config.json (not a run directory)")
    cfg = TrainConfig.load(run_dir / "config.json")
    from_file = load_config_file(args.config) if args.config else {}
    named = {k: v for k, v in {"algo": args.algo, "env_id": args.env_id}.items() if v is not None}
    cfg = resume_config(cfg, named, "the command line")  # (left out: the run's)
    if args.quick:  # (what the file or --set gives wins over the preset, as when the run was started)
        given = {*from_file, *args.overrides, "frames"}
        cfg = resume_config(cfg, {k: v for k, v in quick_preset(cfg.algo).items() if k not in given},
                            "the --quick preset")
    if from_file:
        cfg = resume_config(cfg, from_file, f"config file {args.config!r}")
    if args.overrides:
        cfg = resume_config(cfg, args.overrides, "the command line's overrides")
    flags = dict(frames=args.frames, seed=args.seed, device=args.device, logger=args.logger,
                 reference_dir=args.reference, progress=False if args.no_progress else None,
                 ref_point=_ref_point(args.ref_point))
    return resume_config(cfg, {k: v for k, v in flags.items() if v is not None}, "the command line")


def _stopped(err) -> int:
    """A non-finite loss stopped the run cleanly (its last good state is checkpointed): one line, exit 3."""
    from morl_trl.recipes.off_policy import EXIT_NON_FINITE_LOSS

    print(f"morl-trl train: stopped: {err}", file=sys.stderr)
    return EXIT_NON_FINITE_LOSS


def evaluate_main(argv: list[str]) -> int:
    p = _Parser(prog="morl-trl evaluate",
                                description="Re-evaluate a run's latest checkpoint on its evaluation suite.")
    p.add_argument("run_dir")
    p.add_argument("--reference", help="the published data for NHGR/EUGR (default as in train)")
    p.add_argument("--weights", type=int, help="number of evaluation weights (default: the run's)")
    p.add_argument("--video", action="store_true",
                   help="also record one episode per evaluation context (TorchRL VideoRecorder) into "
                        "RUN_DIR/logs/reevaluation/videos/<context>_<frames>.gif (.mp4 when torchcodec is installed)")
    p.add_argument("--video-weight", metavar="W1,W2,...",
                   help="the preference of the recorded episodes (default: equal weights)")
    p.add_argument("--video-format", choices=("auto", "gif", "mp4", "pt"), default="auto",
                   help="clip format (default auto: mp4 if torchcodec is installed, else gif)")
    p.add_argument("--trust-pickle", action="store_true",
                   help="accept a checkpoint of the old pickled format (loading it can run code stored in it; only "
                   "for a run you trust). `morl-trl convert-run RUN` converts it once instead")
    _add_trust_code(p)
    args = p.parse_args(argv)
    from morl_trl.recipes import evaluate_run

    weight = None
    if args.video_weight:
        try:
            weight = [float(x) for x in args.video_weight.split(",")]
        except ValueError:
            raise ValueError(f"--video-weight {args.video_weight!r}: give comma-separated numbers, e.g. 0.5,0.5") from None
    evaluate_run(args.run_dir, reference_dir=args.reference or _default_reference(), weights=args.weights,
                 video=args.video, video_weight=weight, video_format=args.video_format, trust_pickle=args.trust_pickle,
                 trust_code=args.trust_code)
    return 0


def export_main(argv: list[str]) -> int:
    p = _Parser(prog="morl-trl export",
                description="Write a run's trained policy (networks and acting state, config, preference spec; no "
                            "optimizer state, no replay buffer) to one file that load_policy reads. Reads the newest "
                            "complete checkpoint, also while the run trains.")
    p.add_argument("run_dir")
    p.add_argument("--out", required=True, help="the file to write, e.g. policy.pt")
    p.add_argument("--checkpoint", help="a checkpoint's frame count or name (default: the newest intact one)")
    p.add_argument("--trust-pickle", action="store_true",
                   help="accept a checkpoint of the old pickled format (only for a run you trust)")
    _add_trust_code(p)
    args = p.parse_args(argv)
    from morl_trl.recipes.policy import export_policy

    checkpoint = int(args.checkpoint) if args.checkpoint and args.checkpoint.isdigit() else args.checkpoint
    import warnings

    with warnings.catch_warnings(record=True) as said:  # (a skipped damaged checkpoint: one line each)
        warnings.simplefilter("always")
        out = export_policy(args.run_dir, args.out, checkpoint, trust_pickle=args.trust_pickle,
                            trust_code=args.trust_code)
    for w in said:
        print(f"warning: {w.message}", file=sys.stderr)
    print(f"wrote {out} ({out.stat().st_size / 2**20:.2f} MiB)")
    return 0


def convert_run_main(argv: list[str]) -> int:
    p = _Parser(prog="morl-trl convert-run",
                description="Rewrite a run's checkpoints of the old pickled format (before 2026-11-26) as tensors "
                            "and plain data, once, so that loading the run never unpickles anything. This loads "
                            "the old pickles one last time: convert only a run you trust.")
    p.add_argument("run_dir")
    args = p.parse_args(argv)
    from morl_trl.recipes.convert import convert_run

    done = convert_run(args.run_dir)
    print(f"converted {len(done)} checkpoint(s) of {args.run_dir}" + (f": {', '.join(done)}" if done else
                                                                       " (all were already in the current format)"))
    return 0


# ---------------------------------------------------------------------- envs / demo
def envs_main(argv: list[str]) -> int:
    _Parser(prog="morl-trl envs", description="List domains and evaluation suites.").parse_args(argv)
    from morl_trl.envs import list_domains
    from morl_trl.reporting.reference import PACKAGED_REFERENCE, list_reference_domains

    with_reference = set(list_reference_domains(PACKAGED_REFERENCE))
    for spec in list_domains():
        print(f"{spec.name}  train: {spec.train_id}  objectives: {list(spec.objective_names)}")
        print(f"    context ({spec.context_space.dim}): {', '.join(group_names(spec.context_space.names))}")
        print(f"    evaluation suite: {', '.join(spec.evaluation_ids)}")
        if spec.train_id not in with_reference:
            print("    reference data: none (the authors published no bounds or specialist fronts): "
                  "hypervolume and EUM, no NHGR")
        extra = [i for i in spec.contexts if i not in spec.evaluation_ids]
        if extra:
            print(f"    other fixed contexts: {', '.join(extra)}")
    return 0


def group_names(names, min_run: int = 3) -> list[str]:
    """Runs of consecutive numbered names sharing a prefix, shortened: ``lava_x2_y2..lava_x10_y10 (81)``."""
    def prefix(name: str) -> str | None:
        m = re.search(r"\d", name)
        return name[: m.start()] if m else None

    out, i, names = [], 0, list(names)
    while i < len(names):
        j, key = i + 1, prefix(names[i])
        while key is not None and j < len(names) and prefix(names[j]) == key:
            j += 1
        if j - i >= min_run:
            out.append(f"{names[i]}..{names[j - 1]} ({j - i})")
        else:
            out.extend(names[i:j])
        i = j
    return out


def demo_main(argv: list[str]) -> int:
    parser = _Parser(
        prog="morl-trl demo", description="Build every domain, step it under random contexts, print vector returns.")
    parser.add_argument("--num-envs", type=int, default=4)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    import torch

    from morl_trl.envs import list_domains, make_env

    torch.manual_seed(args.seed)
    for spec in list_domains():
        try:
            spec.env_cls()
        except ImportError:
            print(f"{spec.train_id:34s} (skipped: its extra is not installed)")
            continue
        env = make_env(spec.train_id, num_envs=args.num_envs, seed=args.seed)
        t0 = time.perf_counter()
        td = env.rollout(args.steps, break_when_any_done=False)  # random policy
        dt = time.perf_counter() - t0
        ret = td["next", "reward"].sum(-2)  # undiscounted return of each sub-env's trajectory
        names = ", ".join(spec.objective_names)
        print(f"{spec.train_id:34s} {args.num_envs}x{args.steps} steps in {dt:5.2f}s  objectives [{names}]")
        for i in range(min(args.num_envs, 2)):
            ctx = ", ".join(f"{v:.2f}" for v in td["context"][i, 0].tolist()[:4])
            vals = ", ".join(f"{v:9.2f}" for v in ret[i].tolist())
            print(f"    sub-env {i}: context [{ctx}{', ...' if td['context'].shape[-1] > 4 else ''}]  return [{vals}]")
    return 0


# ---------------------------------------------------------------------- the paper's table
def reference_table_main(argv: list[str] | None = None) -> int:
    """``morl-trl reference-table DATA_DIR``: the paper's NHGR table from the published fronts
    (:func:`morl_trl.reporting.table.reference_table`)."""
    import csv
    from pathlib import Path

    from morl_trl.reporting.table import format_table, reference_table

    parser = _Parser(
        prog="morl-trl reference-table",
        description="Recompute the paper's NHGR table (mean ± pooled std, IQM, optimality gap) from published fronts.",
    )
    parser.add_argument("data_dir", help="reference folder with minmax_values/, specialist_fronts/, generalist_fronts/")
    parser.add_argument("--domain", action="append", help="restrict to this domain id (repeatable)")
    parser.add_argument("--ci", action="store_true", help="add stratified-bootstrap 95%% CIs of IQM and optimality gap")
    parser.add_argument("--reps", type=int, default=50_000, help="bootstrap replicates for --ci (default 50000)")
    parser.add_argument("--seed", type=int, default=0, help="bootstrap seed")
    parser.add_argument("--no-eugr", action="store_true", help="skip EUGR")
    parser.add_argument("--csv", type=Path, help="also write the rows to this CSV file")
    parser.add_argument("--no-manifest", action="store_true",
                        help="read data in the published layout without checking it against the published "
                        "files' manifest (row counts, SHA-256)")
    args = parser.parse_args(argv)
    try:
        rows = reference_table(
            args.data_dir, args.domain, eugr=not args.no_eugr, ci_reps=args.reps if args.ci else 0, seed=args.seed,
            manifest=None if args.no_manifest else "published",
        )
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    try:
        print(format_table(rows), flush=True)
    except BrokenPipeError:  # e.g. piped into `head`
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    if args.csv:
        dicts = [r.as_dict() for r in rows]
        keys = list(dict.fromkeys(k for d in dicts for k in d))
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        with args.csv.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=keys)
            w.writeheader()
            w.writerows(dicts)
    return 0


def reference_pack_main(argv: list[str]) -> int:
    p = _Parser(
        prog="morl-trl reference-pack",
        description="Copy the bounds and specialist fronts from a folder in the published layout into the "
                    "package (the constants NHGR uses on any install), or into --out.")
    p.add_argument("source", help="folder with minmax_values/ and specialist_fronts/ (e.g. ../shared/reference)")
    p.add_argument("--out", help="destination folder (default: the package's own copy)")
    args = p.parse_args(argv)
    from morl_trl.reporting.reference import PACKAGED_REFERENCE, pack_reference

    written = pack_reference(args.source, args.out or PACKAGED_REFERENCE)
    print(f"wrote {len(written)} files to {args.out or PACKAGED_REFERENCE}")
    return 0


def reference_manifest_main(argv: list[str] | None = None) -> int:
    """``morl-trl reference-manifest DIR``: check a reference folder against the shipped
    manifest (row count and SHA-256 of every published file), or ``--write`` it from DIR."""
    from morl_trl.reporting.reference import MANIFEST_PATH, build_manifest, verify_reference, write_manifest

    parser = argparse.ArgumentParser(
        prog="morl-trl reference-manifest",
        description="Check a reference data folder against the manifest of the published files (row counts, "
        "SHA-256), or write that manifest from a folder (--write).",
    )
    parser.add_argument("data_dir", help="reference folder with minmax_values/, specialist_fronts/, generalist_fronts/")
    parser.add_argument("--write", action="store_true", help=f"write the manifest of DATA_DIR (default to {MANIFEST_PATH})")
    parser.add_argument("--output", type=Path, help="where --write writes (default: the package's manifest)")
    args = parser.parse_args(argv)
    if args.write:
        manifest = build_manifest(args.data_dir)
        path = write_manifest(manifest, args.output or MANIFEST_PATH)
        print(f"wrote the manifest of {len(manifest['files'])} files under {args.data_dir} to {path}")
        return 0
    problems = verify_reference(args.data_dir)
    if problems:
        for line in problems[:20]:
            print(line, file=sys.stderr)
        more = f" (first 20 shown)" if len(problems) > 20 else ""
        print(f"morl-trl reference-manifest: error: {args.data_dir}: {len(problems)} difference(s) from the "
              f"published data{more}", file=sys.stderr)
        return 2
    print(f"{args.data_dir}: every file matches the manifest of the published data")
    return 0


def floors_main(argv: list[str] | None = None) -> int:
    """``morl-trl floors --reference DIR [--write]``: the trivial policies' NHGR per domain and context
    (:mod:`morl_trl.reporting.floors`)."""
    from morl_trl.reporting.floors import floors_main as run

    return run(argv)


# ---------------------------------------------------------------------- the experiment grid
def grid_main(argv: list[str]) -> int:
    """``morl-trl grid [SPEC] ...`` runs a grid on Ray; ``grid report DIR`` / ``grid status DIR``."""
    if argv and argv[0] == "report":
        return grid_report_main(argv[1:])
    if argv and argv[0] == "status":
        return grid_status_main(argv[1:])
    from morl_trl.cli_args import frame_count

    p = _Parser(
        prog="morl-trl grid",
        description="Run the cartesian product of algorithms, domains and seeds on Ray (Tune), each cell a "
                    "morl-trl train run under DIR/runs/; re-running the same command skips finished cells and "
                    "resumes the others from their checkpoints; then print the paper's table from the runs. "
                    "Also: morl-trl grid report DIR, morl-trl grid status DIR.",
    )
    p.add_argument("spec", nargs="?", help="a grid spec (.toml/.json; e.g. examples/grid/paper.toml)")
    p.add_argument("--quick", action="store_true",
                   help="without SPEC: the built-in quick grid (envelope and mosac_discrete on MO-LunarLander, 2 seeds, "
                        "short --quick runs); with SPEC: the --quick preset for every cell")
    p.add_argument("--algos", help="comma-separated algorithms (with --domains: replaces the spec's blocks)")
    p.add_argument("--domains", help="comma-separated training env ids")
    p.add_argument("--seeds", help="comma-separated seeds, or a range 0-4")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="set_",
                   help="a config override for every cell (repeatable)")
    p.add_argument("--frames", type=frame_count, help="frames of every cell: 300000, 3e5, 300k, 3M")
    p.add_argument("--dir", help="the grid directory (default grids/<spec name>)")
    p.add_argument("--address", help="an existing Ray cluster (e.g. auto, ray://host:10001); default: an embedded "
                   "Ray on this machine")
    p.add_argument("--num-cpus", type=int, help="CPUs the embedded Ray may use (default: the machine's)")
    p.add_argument("--num-gpus", type=float, help="GPUs the embedded Ray may use (default: the machine's)")
    p.add_argument("--cpus-per-run", type=float, help="CPUs reserved per run (default 1)")
    p.add_argument("--gpus-per-run", type=float, help="GPUs reserved per run, a fraction shares one GPU (e.g. 0.25; "
                   "a run with a GPU trains on cuda)")
    p.add_argument("--max-concurrent", type=int, help="at most this many runs at once")
    p.add_argument("--max-failures", type=int, default=2, help="retries of a run whose worker died (default 2)")
    p.add_argument("--progress-interval", type=float, default=30.0, help="seconds between progress lines")
    p.add_argument("--reference", help="the published data for each run's report (baseline columns)")
    p.add_argument("--no-report", action="store_true", help="do not print the table at the end")
    args = p.parse_args(argv)
    from morl_trl.grid.spec import QUICK_GRID, GridSpec, read_grid_file

    if args.spec:
        data, source = read_grid_file(args.spec), f"grid spec {args.spec!r}"
        if args.quick:
            data["quick"] = True
    elif args.quick:
        data, source = json.loads(json.dumps(QUICK_GRID)), "the quick grid"
    elif args.algos and args.domains:
        data, source = {}, "the command line"
    else:
        raise ValueError("give a grid spec file, --quick, or --algos and --domains")
    if args.algos or args.domains:
        if not (args.algos and args.domains):
            raise ValueError("--algos and --domains go together (they replace the spec's blocks)")
        data.pop("block", None)
        data["algorithms"] = [a.strip() for a in args.algos.split(",") if a.strip()]
        data["domains"] = [d.strip() for d in args.domains.split(",") if d.strip()]
    if args.seeds:
        data["seeds"] = _seed_list(args.seeds)
    overrides = dict(data.get("overrides", {}))
    overrides.update(parse_overrides(args.set_))
    if args.frames is not None:
        overrides["frames"] = args.frames
    if args.reference:
        overrides["reference_dir"] = str(Path(args.reference).resolve())
    data["overrides"] = overrides
    resources = dict(data.get("resources", {}))
    if args.cpus_per_run is not None:
        resources["cpus"] = args.cpus_per_run
    if args.gpus_per_run is not None:
        resources["gpus"] = args.gpus_per_run
    data["resources"] = resources
    spec = GridSpec.from_dict(data, source)
    grid_dir = Path(args.dir or Path("grids") / spec.name)
    from morl_trl.grid import run_grid

    states = run_grid(spec, grid_dir, address=args.address, num_cpus=args.num_cpus, num_gpus=args.num_gpus,
                      max_concurrent=args.max_concurrent, max_failures=args.max_failures,
                      progress_interval=args.progress_interval)
    if not args.no_report and any(s.status == "done" for s in states):
        from morl_trl.grid import grid_report

        grid_report(grid_dir)
    bad = [s for s in states if s.status != "done"]
    if bad:
        print(f"morl-trl grid: {len(bad)} of {len(states)} cells not done: "
              + ", ".join(f"{s.name} ({s.status})" for s in bad) + f"; see {grid_dir}/cells/; run the same command "
              "again to resume them", file=sys.stderr)
        return 1
    return 0


def _seed_list(text: str) -> list[int]:
    try:
        if "-" in text and "," not in text:
            lo, hi = (int(x) for x in text.split("-", 1))
            return list(range(lo, hi + 1))
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"--seeds {text!r}: give comma-separated ints (0,1,2) or a range (0-4)") from None


def grid_report_main(argv: list[str]) -> int:
    p = _Parser(prog="morl-trl grid report",
                description="The paper's table (NHGR mean ± std, IQM, optimality gap, EUGR per algorithm and "
                            "domain; the paper's values and the floors beside them) and learning curves per domain, "
                            "from a grid's finished cells, into DIR/report.md.")
    p.add_argument("grid_dir")
    p.add_argument("--reference", help="reference data (bounds, specialist fronts; default: the shipped copies)")
    p.add_argument("--floors", choices=("auto", "shipped", "none"), default="auto",
                   help="auto: the shipped floors at the paper's weights, else evaluated at the runs' weights; "
                        "shipped: only the shipped ones; none")
    p.add_argument("--ci", action="store_true", help="add stratified-bootstrap 95%% CIs of IQM and optimality gap")
    args = p.parse_args(argv)
    from morl_trl.grid import grid_report

    grid_report(args.grid_dir, reference_dir=args.reference, floors=args.floors, ci_reps=50_000 if args.ci else 0)
    return 0


def grid_status_main(argv: list[str]) -> int:
    p = _Parser(prog="morl-trl grid status", description="Where each cell of a grid stands (from its files).")
    p.add_argument("grid_dir")
    args = p.parse_args(argv)
    from morl_trl.grid import format_status, grid_status

    print(format_status(grid_status(args.grid_dir)))
    return 0


# ---------------------------------------------------------------------- config
def config_main(argv: list[str]) -> int:
    from morl_trl.recipes.config import ALGORITHMS

    p = _Parser(prog="morl-trl config",
                description="Print the resolved config of ALGO on ENV_ID (TOML), or compare it with the authors' "
                            "record (--compare-authors: one row per setting they ran).")
    p.add_argument("algo", choices=ALGORITHMS, help="algorithm")
    p.add_argument("env_id", help="training env id, e.g. MOLunarLanderDR-v0")
    p.add_argument("overrides", nargs="*", metavar="KEY=VALUE", help="config overrides, as for morl-trl train")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="set_")
    p.add_argument("--config", help="a .toml/.json file of config overrides")
    p.add_argument("--quick", action="store_true", help="the --quick preset")
    p.add_argument("--compare-authors", action="store_true",
                   help="one row per setting of the authors' record for this pair: their name and value, our key "
                        "and value, and same / deliberate / not applicable / differs")
    p.add_argument("--format", choices=("text", "json"), default="text",
                   help="text (TOML config, or a table with --compare-authors) or json")
    args = p.parse_intermixed_args(argv)
    from morl_trl.recipes import resolve_config

    overrides = parse_overrides([*args.overrides, *args.set_])
    cfg = resolve_config(args.algo, args.env_id, quick=args.quick, config_file=args.config, **overrides)
    if not args.compare_authors:
        print(json.dumps(cfg.to_dict(), indent=1) if args.format == "json" else cfg.to_toml())
        return 0
    from morl_trl.recipes.fidelity import compare, format_rows

    rows = compare(args.algo, args.env_id, cfg)
    print(json.dumps([r.as_dict() for r in rows], indent=1, default=str) if args.format == "json"
          else format_rows(rows))
    return 0


# name -> (function, help)
COMMANDS = {
    "train": (train_main, "train a generalist across contexts, evaluate it, report"),
    "config": (config_main, "print an algorithm's resolved config (TOML); --compare-authors: beside the authors' record"),
    "evaluate": (evaluate_main, "re-evaluate a run's checkpoint on its evaluation suite"),
    "demo": (demo_main, "build every domain, step it under random contexts, print vector returns"),
    "envs": (envs_main, "list domains, their contexts and evaluation suites"),
    "reference-table": (reference_table_main, "reproduce the paper's NHGR table from the published fronts"),
    "reference-pack": (reference_pack_main, "ship the bounds and specialist fronts of a reference folder in the package"),
    "reference-manifest": (reference_manifest_main, "check reference data against the published files' manifest "
                           "(or --write it)"),
    "floors": (floors_main, "NHGR of trivial policies (random, constant actions) per domain: the honest floors"),
    "export": (export_main, "write a run's trained policy to one small file (load_policy reads it)"),
    "convert-run": (convert_run_main, "rewrite a run's old pickled checkpoints as tensors + plain data (once)"),
    "grid": (grid_main, "run algorithms x domains x seeds on Ray, resumable; grid report DIR: the paper's table"),
}


# Errors raised by the Python API name its arguments (``overwrite=True``, ``resume=DIR``, ...);
# on the command line the same things are flags: the message is reworded, never rewritten.
_API_TO_FLAG = (
    (re.compile(r"\boverwrite=True\b"), "--overwrite"),
    (re.compile(r"\bresume="), "--resume "),
    (re.compile(r"\brun_dir=(?=\W|$)"), "--run-dir"),
    (re.compile(r"\brun_dir="), "--run-dir "),
    (re.compile(r"\bframes=(?=\W|$)"), "--frames"),
    (re.compile(r"\bframes="), "--frames "),
    (re.compile(r"\bref_point=\[\.\.\.\]"), "--ref-point"),
)


def cli_wording(message: str) -> str:
    """``message`` (an API error) with the Python arguments it names spelled as this CLI's flags."""
    for pattern, flag in _API_TO_FLAG:
        message = pattern.sub(flag, message)
    return message


def _lock_errors() -> tuple[type[Exception], ...]:
    """``RunLockedError`` where the run code was imported (evaluated only when an error is matched:
    ``--help`` and argument errors answer without importing it, nor torch)."""
    lock = sys.modules.get("morl_trl.runs.lock")
    return (lock.RunLockedError,) if lock is not None else ()


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _Parser(prog="morl-trl", description=__doc__.splitlines()[0])
    parser.add_argument("command", choices=sorted(COMMANDS), help="; ".join(f"{k}: {v[1]}" for k, v in COMMANDS.items()))
    parser.add_argument("--version", action="version", version=f"morl-trl {version()}")
    if not argv or argv[0] in ("-h", "--help"):
        parser.print_help()
        return 0
    if argv[0] in ("-V", "--version"):
        print(f"morl-trl {version()}")
        return 0
    if argv[0] not in COMMANDS:
        from morl_trl._suggest import did_you_mean

        parser.error(f"unknown command {argv[0]!r}{did_you_mean(argv[0], COMMANDS, cutoff=0.6)}; valid: "
                     f"{sorted(COMMANDS)}")
    try:
        return int(COMMANDS[argv[0]][0](argv[1:]) or 0)
    except (ValueError, *_lock_errors()) as err:  # bad input: say what is wrong and what is valid, no traceback
        print(f"morl-trl {argv[0]}: error: {cli_wording(str(err))}", file=sys.stderr)
        return 2
    except OSError as err:  # the machine's (a full disk, a read-only folder): what could not be done, no traceback
        print(f"morl-trl {argv[0]}: error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as err:  # Ctrl-C, SIGTERM, SIGHUP: one line (a run says where it checkpointed, how to resume)
        print(f"morl-trl {argv[0]}: {err or 'interrupted'}", file=sys.stderr)
        code = getattr(err, "exit_code", 130)  # 130 (SIGINT), 143 (SIGTERM), 129 (SIGHUP)
        # exiting already: another signal (e.g. during a library's exit hook) ends the process at once, quietly
        for name in ("SIGINT", "SIGTERM", "SIGHUP"):
            if hasattr(signal, name):
                signal.signal(getattr(signal, name), lambda *_: os._exit(code))
        return code


if __name__ == "__main__":
    sys.exit(main())
