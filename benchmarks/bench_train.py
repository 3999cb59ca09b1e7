"""End-to-end training throughput of ``morl-trl train`` at the paper's settings, with the projected
wall time of the paper's full run, against MORL-Baselines' own training loop in the same run.

For each (algorithm, domain) pair and device this builds exactly what ``morl-trl train`` builds
(the recipe's training env, agent, replay buffer and TorchRL collector, from
``resolve_config(algo, env_id)``: the paper's batch sizes, 4 x 256 networks, prioritized replay
for Envelope, one gradient update per collected frame) and times the loop's body:
collect a batch → ``agent.learn`` (store + one update per frame) → schedules → policy sync.
Evaluation and checkpoints are left out (they run every 50k-100k frames). Timing starts once
learning has started (after ``init_random_frames`` and one batch of warm-up).

Pairs: Envelope / MO-LunarLander (DR), Envelope / MO-LavaGrid (DR), CAPQL / MO-Hopper (DR).
The projected time is the domain's training length (``DomainSpec.train_frames``) divided by
the measured frames/s.

The peer is MORL-Baselines' own ``train()`` loop (one env, one update per step) on the
MO-Gymnasium env closest to each domain (``mo-lunar-lander-v3``, ``mo-hopper-v5``; it has no
MO-LavaGrid), with the same networks, batch sizes and update settings, timed after its
``learning_starts``. It needs ``morl-baselines`` importable (see ``bench_losses.py``'s docstring
for the scratch venv); without it the table says so.

    python benchmarks/bench_train.py --quick               # ~3 min on one free CPU core
    python benchmarks/bench_train.py --quick --clock cpu   # on a shared machine: process CPU time
    python benchmarks/bench_train.py --device cuda         # + compile=true cudagraphs=true rows
    python benchmarks/bench_train.py --pairs capql:MOHopperDR-v5 --frames 2048
    python benchmarks/bench_train.py --tiny --peer none    # a seconds-long dry run (benchmarks/gpu/check.sh)

``--tiny`` shrinks the run (16 timed frames, 8 frames per batch, learning from the first batch, 2 x 16
networks, batches of 16) to check that every row runs, not to measure.

**One env, end to end** (``--one-env``): the small MO-Gymnasium cases of the parity benchmark
(``benchmarks/parity/common.py``: the same env, hyperparameters and networks for both libraries,
MORL-Baselines' own configuration of one env stepped once between updates), each trained
``--one-env-frames`` frames by ``morl_trl.train`` and by MORL-Baselines' class through its own
``train()`` (``benchmarks/parity/mb_runner.py``, in MB's virtual environment ``--mb-python``), one
after the other in this run. Ours is timed from its first collected batch to the end of its last
(the frame-0 and final evaluations, the report and the final checkpoint excluded; the loop's own
bookkeeping, logs and periodic checkpoints included); MB's ``train()`` minus the shared
evaluations hooked into it (as the parity benchmark does). No MB python: its column says so.

    python benchmarks/bench_train.py --one-env                       # one case per method, 2,000 frames each
    python benchmarks/bench_train.py --one-env envelope-dst --one-env-frames 500
    python benchmarks/bench_train.py --one-env --clock cpu       # each library's process CPU time: steadier when shared
    python benchmarks/bench_train.py --one-env envelope-dst --one-env-frames 30 --peer none   # a dry run ``--table FILE`` appends each row, tab-separated, to
``FILE`` as it is measured (what ``benchmarks/gpu/check.sh`` collects into its table).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import warnings
from pathlib import Path

import torch

CLOCK = time.perf_counter
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from morl_trl.envs import domain_of  # noqa: E402
from morl_trl.recipes import build_agent, build_training_env, resolve_config  # noqa: E402
from morl_trl.algorithms.registry import algorithm  # noqa: E402
from morl_trl.training.parts import make_collector, make_replay_buffer, run_discount  # noqa: E402

warnings.filterwarnings("ignore")

PAIRS = ("envelope:MOLunarLanderDR-v0", "envelope:MOLavaGridDR-v0", "capql:MOHopperDR-v5")
#: one parity case per learner (``--one-env`` without names): Envelope, GPI-LS, GPI-PD, PCN, CAPQL, MORL/D
#: (SB; SB+PSA learns the same way) and PGMORL, each on the smallest MO-Gymnasium env its parity cases use
ONE_ENV_CASES = ("envelope-dst", "gpi_ls-dst", "gpi_pd-dst", "pcn-fruit-tree", "capql-mountaincar",
                 "morld-mountaincar", "pgmorl-hopper")
PARITY = ROOT / "benchmarks" / "parity"
#: MORL-Baselines' virtual environment: the benchmark machine's, else run_parity.py's default
MB_PYTHONS = (Path("/tmp/mbvenv/bin/python"), Path.home() / ".cache" / "morl_trl" / "mb-1.3.0" / "bin" / "python")
PEER_ENVS = {"MOLunarLanderDR-v0": "mo-lunar-lander-v3", "MOHopperDR-v5": "mo-hopper-v5"}


TINY = dict(frames_per_batch=8, init_random_frames=8, buffer_size=1_024, hidden=(16, 16), batch_size=16)


def ours(algo: str, env_id: str, device: str, frames: int, **overrides) -> dict:
    """Frames/s and updates/s of the recipe's training loop, timed over ``frames`` frames after learning starts."""
    cfg = resolve_config(algo, env_id, device=device, logger="none", progress=False, **overrides)
    spec = domain_of(env_id)
    dev = torch.device(device)
    torch.manual_seed(cfg.seed)
    env = build_training_env(cfg, dev)
    agent = build_agent(cfg, env, gamma=run_discount(cfg, spec), device=dev)
    buffer = make_replay_buffer(cfg, dev)
    warm = getattr(cfg, "init_random_frames", 0) + cfg.frames_per_batch  # (PCN, PGMORL: no warm-up key)
    cfg.frames = warm + frames + cfg.frames_per_batch
    collector = make_collector(cfg, env, agent.explore_policy, dev)
    learn = algorithm(algo).on_batch
    done, updates, t0, timed = 0, 0, None, 0
    for batch in collector:
        done += batch.numel()
        _, n = learn(agent, batch, buffer, done)  # the recipe's own per-batch step (store, updates, schedules)
        collector.update_policy_weights_()
        if t0 is not None:
            timed += batch.numel()
            updates += n
            if timed >= frames:
                break
        elif done >= warm:
            if dev.type == "cuda":
                torch.cuda.synchronize()
            t0 = CLOCK()
    if dev.type == "cuda":
        torch.cuda.synchronize()
    wall = CLOCK() - t0
    collector.shutdown()
    captured = getattr(agent, "_captured", None)
    path = ("whole update in one graph" if getattr(captured, "_whole", None) is not None
            else "captured step" if captured is not None else "eager")
    return {"fps": timed / wall, "ups": updates / wall, "train_frames": spec.train_frames,
            "path": f"{path}; {type(getattr(buffer, '_sampler', None)).__name__}"}


def peer(algo: str, env_id: str, device: str, frames: int) -> dict | None:
    """MORL-Baselines' ``train()`` loop on the closest MO-Gymnasium env, or ``None`` when it has none."""
    import mo_gymnasium as mo_gym
    import numpy as np

    gym_id = PEER_ENVS.get(env_id)
    if gym_id is None:
        return None
    cfg = resolve_config(algo, env_id)
    env = mo_gym.make(gym_id)
    common = dict(learning_rate=cfg.lr, batch_size=cfg.batch_size, net_arch=list(cfg.hidden), log=False, seed=0,
                  device=device, buffer_size=cfg.buffer_size)
    if algo == "envelope":
        from morl_baselines.multi_policy.envelope.envelope import Envelope

        agent = Envelope(env, gamma=cfg.gamma or domain_of(env_id).gamma, num_sample_w=cfg.num_sampled_prefs,
                         per=cfg.prioritized, per_alpha=cfg.per_alpha, initial_homotopy_lambda=cfg.homotopy_lambda0,
                         final_homotopy_lambda=cfg.homotopy_lambda0, target_net_update_freq=cfg.target_update_period,
                         tau=1.0, learning_starts=cfg.init_random_frames, max_grad_norm=cfg.max_grad_norm,
                         initial_epsilon=cfg.eps_start, final_epsilon=cfg.eps_end, epsilon_decay_steps=cfg.eps_frames,
                         **common)

        def train(n, first):
            agent.train(n, reset_num_timesteps=first, eval_freq=10**12)
    else:
        from morl_baselines.multi_policy.capql.capql import CAPQL

        agent = CAPQL(env, gamma=cfg.gamma or domain_of(env_id).gamma, tau=cfg.tau, alpha=cfg.alpha, num_q_nets=2,
                      learning_starts=cfg.init_random_frames, **common)
        ref = np.zeros(agent.reward_dim)

        def train(n, first):
            agent.train(n, eval_env=env, ref_point=ref, eval_freq=10**12, reset_num_timesteps=first)
    train(cfg.init_random_frames + 64, True)
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    t0 = CLOCK()
    train(frames, False)
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    wall = CLOCK() - t0
    return {"fps": frames / wall, "env": gym_id}


def _parity_case(case: str, frames: int) -> dict:
    """The parity case ``case`` with a budget of ``frames`` frames (one evaluation, at the end)."""
    sys.path.insert(0, str(PARITY))
    from common import CASES

    if case not in CASES:
        raise SystemExit(f"unknown parity case {case!r}; valid: {sorted(CASES)}")
    c = dict(CASES[case])
    c["frames"] = c["eval_every"] = frames
    return c


def ours_one_env(case: str, frames: int, seed: int = 0) -> dict:
    """``morl_trl.train`` on the parity case: frames/s from the first collected batch to the end of the last.

    ``frames`` and the result count env steps as MB's ``global_step`` does: for PGMORL (the case's
    ``ours_frame_scale``, its population size) every member's steps, where ours counts one member's (the
    authors' count): ours trains ``frames / scale`` of its frames (``run_parity.ours_budget``), and its
    frames/s is multiplied back."""
    import contextlib
    import io
    import tempfile

    import morl_trl
    from torchrl.collectors import Collector

    from morl_trl.evaluation import MultiContextEvaluator
    from morl_trl.runs.run import Run

    c = _parity_case(case, frames)
    from run_parity import ours_budget  # (benchmarks/parity: on the path once _parity_case ran)

    ours_frames, _, scale = ours_budget(c)
    marks: dict = {"eval": 0.0}
    iterator, evaluate, finish = Collector.iterator, MultiContextEvaluator.evaluate, Run.finish

    def timed_iterator(self):
        marks.setdefault("start", CLOCK())
        marks["eval"] = 0.0  # (only the evaluations during collection count against the loop)
        yield from iterator(self)

    def timed_evaluate(self, *args, **kwargs):
        t = CLOCK()
        try:
            return evaluate(self, *args, **kwargs)
        finally:
            marks["eval"] += CLOCK() - t

    def timed_finish(self, *args, **kwargs):
        marks["end"], marks["frames"] = CLOCK(), self.frames
        marks["loop_eval"] = marks["eval"]
        return finish(self, *args, **kwargs)

    Collector.iterator, MultiContextEvaluator.evaluate, Run.finish = timed_iterator, timed_evaluate, timed_finish
    quiet = io.StringIO()  # (the run's own lines: start, evaluations, report)
    try:
        with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(quiet), contextlib.redirect_stderr(quiet):
            morl_trl.train(c["algo"], env=c["env"], seed=seed, frames=max(ours_frames, 1), eval_interval=10**9,
                           eval_weights=16, eval_episodes=1, gamma=c["gamma"], eval_random_baseline=False,
                           progress=False, run_dir=f"{tmp}/run", **c["ours"])
    finally:
        Collector.iterator, MultiContextEvaluator.evaluate, Run.finish = iterator, evaluate, finish
    wall = marks["end"] - marks["start"] - marks["loop_eval"]
    return {"fps": marks["frames"] * scale / wall, "frames": marks["frames"] * scale, "env": c["env"], "algo": c["algo"]}


def mb_python(choice: str | None) -> Path | None:
    """MORL-Baselines' python: ``choice``, else the first of :data:`MB_PYTHONS` that exists."""
    if choice is not None:
        return Path(choice) if Path(choice).exists() else None
    return next((p for p in MB_PYTHONS if p.exists()), None)


def mb_one_env(case: str, frames: int, python: Path, seed: int = 0, clock: str = "wall", prelude: str = "") -> dict:
    """MB's class of the parity case through its own ``train()`` (``mb_runner.run``), in MB's python;
    ``clock="cpu"``: its process's CPU time instead of wall time (``mb_runner``'s ``time.perf_counter``
    read as ``time.process_time``). ``prelude``: Python run in MB's process before the run (e.g. wrappers
    that count MB's calls); a dict it leaves in ``EXTRA`` comes back, as it is after the run, under ``"extra"``."""
    import json
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        code = ("import time; time.perf_counter = time.process_time\n" if clock == "cpu" else "")
        code += f"EXTRA = {{}}\n{prelude}\n"
        code += (f"import sys; sys.path.insert(0, {str(PARITY)!r}); import common; "
                f"common.CASES[{case!r}].update(frames={frames}, eval_every={frames}); import mb_runner; "
                f"from pathlib import Path; mb_runner.run({case!r}, {seed}, Path({tmp!r}) / 'mb.json'); "
                f"import json; Path({tmp!r}, 'extra.json').write_text(json.dumps(EXTRA))")
        env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
        # (in the temporary folder: MB's PCN saves weights/PCN_model.pt in the working directory)
        done = subprocess.run([str(python), "-c", code], env=env, capture_output=True, text=True, cwd=tmp)
        if done.returncode != 0:
            raise RuntimeError(f"MB's run failed: {done.stderr.strip().splitlines()[-1] if done.stderr.strip() else done.returncode}")
        result = json.loads((Path(tmp) / "mb.json").read_text())
        extra = json.loads((Path(tmp) / "extra.json").read_text())
    return {"fps": result["train_fps"], "frames": result["frames"], "extra": extra}


def one_env_main(args) -> int:
    """The ``--one-env`` table: ours vs MB frames/s per parity case, and the ratio (``--clock``: wall time,
    or each process's CPU time, for both libraries)."""
    python = None if args.peer == "none" else mb_python(args.mb_python)
    if args.peer == "none":
        peer_label = "none (--peer none)"
    elif python is None:
        peer_label = f"none (no MORL-Baselines python: {args.mb_python or ', '.join(map(str, MB_PYTHONS))})"
    else:
        peer_label = f"MORL-Baselines' own train() loop ({python})"
    print(f"torch {torch.__version__}, {torch.get_num_threads()} thread(s), {args.clock} clock; one env, "
          f"{args.one_env_frames} frames per case; peer: {peer_label}")
    seeds = args.one_env_seeds
    if len(seeds) > 1:
        print(f"seeds {' '.join(map(str, seeds))}: a row per seed, then the case's medians (f/s of each library, "
              f"and the median of the per-seed ratios)")
    print(f"{'case':<20} {'env':<30} {'ours f/s':>9} {'MB f/s':>9} {'ours/MB':>8}")
    for case in args.one_env:
        rows = []  # (ours f/s, MB f/s or None, ratio or None, peer text, ratio text)
        for seed in seeds:
            r = ours_one_env(case, args.one_env_frames, seed=seed)
            m_fps = rate = None
            if python is None:
                peer, ratio = "none", "-"
            else:
                try:
                    m_fps = mb_one_env(case, args.one_env_frames, python, seed=seed, clock=args.clock)["fps"]
                    rate = r["fps"] / m_fps
                    peer, ratio = f"{m_fps:.1f}", f"{rate:.2f}x"
                except RuntimeError as err:
                    peer, ratio = "failed", str(err)[:80]
            rows.append((r["fps"], m_fps, rate, peer, ratio))
            label = case if len(seeds) == 1 else f"{case} s{seed}"
            print(f"{label:<20} {r['env']:<30} {r['fps']:>9.1f} {peer:>9} {ratio:>8}", flush=True)
        fps = statistics.median(row[0] for row in rows)
        if len(seeds) == 1:
            peer, ratio = rows[0][3], rows[0][4]
        else:
            mb_fps = [row[1] for row in rows if row[1] is not None]
            rates = [row[2] for row in rows if row[2] is not None]
            peer = f"{statistics.median(mb_fps):.1f}" if mb_fps else "none" if python is None else "failed"
            ratio = f"{statistics.median(rates):.2f}x" if rates else "-"
            print(f"{case + ' median':<20} {r['env']:<30} {fps:>9.1f} {peer:>9} {ratio:>8}", flush=True)
        _table(args.table, "train-one-env", case, "cpu", "eager", "frames/s", f"{fps:.1f}",
               "" if python is None else peer, "" if python is None else ratio,
               r["env"] if len(seeds) == 1 else f"{r['env']}; median over seeds {' '.join(map(str, seeds))}")
    return 0


def _table(path, stage, name, device, variant, unit, value, peer, ratio, note) -> None:
    """Appends one tab-separated row to ``path`` (``None``: nothing)."""
    if path:
        with open(path, "a") as f:
            f.write("\t".join(str(x) for x in (stage, name, device, variant, unit, value, peer, ratio, note)) + "\n")


def _hours(train_frames: int, fps: float) -> str:
    h = train_frames / fps / 3600
    return f"{h:,.1f} h" if h >= 1 else f"{h * 60:,.0f} min"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="time 128 frames per pair (default: --frames)")
    p.add_argument("--frames", type=int, default=512, help="frames timed per pair after learning starts")
    p.add_argument("--device", default="cpu", help="cpu, cuda, or 'all' (cpu and, when present, cuda)")
    p.add_argument("--pairs", nargs="+", default=list(PAIRS), help="algo:env_id pairs")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads (the recipe's default: 1)")
    p.add_argument("--peer", choices=["auto", "none"], default="auto")
    p.add_argument("--no-capture", action="store_true", help="on cuda, skip the compile/cudagraphs rows")
    p.add_argument("--capture", nargs="*", default=None,
                   choices=["compile", "cudagraphs", "both", "whole", "whole+compile"],
                   help="captured rows on cuda beside the eager one (default: all); whole: sampling and "
                        "priority writes in the CUDA graph too (capture_sampling, Envelope)")
    p.add_argument("--tiny", action="store_true", help="a seconds-long dry run: every row runs, nothing is measured")
    p.add_argument("--table", default=None, help="append each row, tab-separated, to this file")
    p.add_argument("--clock", choices=["wall", "cpu"], default="wall",
                   help="wall time (default), or this process's CPU time: steadier on a shared CPU machine "
                        "(with --threads 1); meaningless on cuda, where the device works while the host waits")
    p.add_argument("--one-env", nargs="*", default=None, metavar="CASE",
                   help=f"ours vs MB end to end on parity cases (default: {' '.join(ONE_ENV_CASES)}) instead of the pairs")
    p.add_argument("--one-env-frames", type=int, default=2_000, help="frames per --one-env case")
    p.add_argument("--one-env-seeds", type=int, nargs="+", default=[0],
                   help="seeds per --one-env case (default: 0); with several, a row per seed and the medians: a case "
                        "whose work per frame depends on the data (GPI-PD's dynamics fits stop early) reads differently "
                        "from seed to seed")
    p.add_argument("--mb-python", default=None, help="MORL-Baselines' python for --one-env (default: the first of "
                                                     + ", ".join(map(str, MB_PYTHONS)) + " that exists)")
    args = p.parse_args(argv)
    global CLOCK
    CLOCK = time.perf_counter if args.clock == "wall" else time.process_time
    if args.one_env is not None:
        args.one_env = args.one_env or list(ONE_ENV_CASES)
        torch.set_num_threads(args.threads)
        return one_env_main(args)
    frames = 16 if args.tiny else 128 if args.quick else args.frames
    tiny = TINY if args.tiny else {}
    torch.set_num_threads(args.threads)
    devices = ["cpu", "cuda"] if args.device == "all" else [args.device]
    devices = [d for d in devices if d != "cuda" or torch.cuda.is_available()]
    if args.device in ("cuda", "all") and not torch.cuda.is_available():
        print("no CUDA device here: the cuda rows are missing")
    have_peer = False
    if args.peer == "auto":
        try:
            from importlib.metadata import version

            import morl_baselines  # noqa: F401

            have_peer = True
            peer_label = f"MORL-Baselines {version('morl-baselines')} train() loop"
        except ImportError as err:
            peer_label = f"none (morl-baselines not importable: {err})"
    else:
        peer_label = "none (--peer none)"
    print(f"torch {torch.__version__}, {torch.get_num_threads()} thread(s), {args.clock} clock; {frames} frames timed per row after "
          f"learning starts; peer: {peer_label}")
    print(f"{'algo':<9} {'domain':<20} {'device':<6} {'capture':<10} {'frames/s':>9} {'updates/s':>10} "
          f"{'paper run':>10} {'projected':>10} | {'peer env':<20} {'peer f/s':>9} {'ratio':>7} {'projected':>10}")
    for pair in args.pairs:
        algo, env_id = pair.split(":")
        for device in devices:
            variants = [("eager", {})]
            modes = {"compile": {"compile": True}, "cudagraphs": {"cudagraphs": True},
                     "both": {"compile": True, "cudagraphs": True},
                     "whole": {"cudagraphs": True, "capture_sampling": True},
                     "whole+compile": {"compile": True, "cudagraphs": True, "capture_sampling": True}}
            if device == "cuda" and not args.no_capture:
                chosen = args.capture if args.capture is not None else list(modes)
                # whole: prioritized replay's sampling in the graph (Envelope); elsewhere it is cudagraphs/both
                variants += [(m, modes[m]) for m in chosen if not m.startswith("whole") or algo == "envelope"]
            peer_row = None
            if have_peer and (device == "cpu" or torch.cuda.is_available()):
                peer_row = peer(algo, env_id, device, frames)
            for label, overrides in variants:
                try:
                    r = ours(algo, env_id, device, frames, **tiny, **overrides)
                except Exception as err:  # a capture mode that fails here is reported, not fatal
                    msg = f"{type(err).__name__}: {str(err).splitlines()[0][:300] if str(err) else ''}"
                    print(f"{algo:<9} {env_id:<20} {device:<6} {label:<10} failed: {msg}", flush=True)
                    _table(args.table, "train", f"{algo}/{env_id}", device, label, "frames/s", "FAILED", "", "", msg)
                    continue
                line = (f"{algo:<9} {env_id:<20} {device:<6} {label:<10} {r['fps']:>9.1f} {r['ups']:>10.1f} "
                        f"{r['train_frames'] / 1e6:>9.1f}M {_hours(r['train_frames'], r['fps']):>10} | ")
                if peer_row is not None:
                    line += (f"{peer_row['env']:<20} {peer_row['fps']:>9.1f} {r['fps'] / peer_row['fps']:>6.2f}x "
                             f"{_hours(r['train_frames'], peer_row['fps']):>10}")
                else:
                    line += "no peer" if have_peer else "-"
                print(line, flush=True)
                _table(args.table, "train", f"{algo}/{env_id}", device, label, "frames/s", f"{r['fps']:.1f}",
                       f"{peer_row['fps']:.1f}" if peer_row else "", f"{r['fps'] / peer_row['fps']:.2f}x" if peer_row else "",
                       f"{r['ups']:.1f} updates/s; {r['path']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
