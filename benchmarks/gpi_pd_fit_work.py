"""GPI-PD end to end on one env, with the dynamics fits' work counted: ours beside MORL-Baselines'.

``bench_train --one-env gpi_pd-dst`` compares frames/s, but most of a GPI-PD frame is the refit of the dynamics
ensemble (every 250 frames at MB's defaults), and each fit runs until its holdout loss stops improving: how many
epochs it runs depends on the data each library collected, not on its speed. This prints, per seed and library,
frames/s (process CPU time, one thread; training only, as ``bench_train --one-env``), the number of fits, the
ensemble's minibatch steps over all fits, the CPU seconds inside the fits, and frames/s with the fits taken out;
then the ratios ours / MB of frames/s, of frames/s outside the fits, and of the CPU time per fitted minibatch step.

    python benchmarks/gpi_pd_fit_work.py                      # gpi_pd-dst, 2,000 frames, seeds 0 1 2
    python benchmarks/gpi_pd_fit_work.py --seeds 0 --frames 1000
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

sys.path.insert(0, str(ROOT / "benchmarks"))
import bench_train  # noqa: E402  (the one-env runs of both libraries)

# MB's side: bench_train.mb_one_env's run of the case with this prelude, which times MB's ensemble fits and counts
# their minibatch steps (_compute_loss calls inside fit) in EXTRA (returned under "extra")
_MB_PRELUDE = """
import time
from morl_baselines.common.model_based import probabilistic_ensemble as pe
EXTRA.update(fits=0, steps=0, fit_s=0.0)
_inside = [False]
_loss, _fit = pe.ProbabilisticEnsemble._compute_loss, pe.ProbabilisticEnsemble.fit
def _counted_loss(self, x, y):
    EXTRA["steps"] += _inside[0]
    return _loss(self, x, y)
def _timed_fit(self, *a, **k):
    EXTRA["fits"] += 1
    _inside[0], start = True, time.process_time()
    try:
        return _fit(self, *a, **k)
    finally:
        _inside[0] = False
        EXTRA["fit_s"] += time.process_time() - start
pe.ProbabilisticEnsemble._compute_loss, pe.ProbabilisticEnsemble.fit = _counted_loss, _timed_fit
"""


def ours(case: str, frames: int, seed: int) -> dict:
    """Our recipe's run of the case (``bench_train.ours_one_env``) with ``fit_dynamics`` timed and its steps counted."""
    import morl_trl.algorithms.gpi.recipe as recipe
    import morl_trl.objectives.dynamics as dynamics

    work = {"fits": 0, "steps": 0, "fit_s": 0.0}
    fit, nll, clock = recipe.fit_dynamics, dynamics.DynamicsLoss.nll, bench_train.CLOCK
    bench_train.CLOCK = time.process_time
    inside = [False]

    def counted_nll(self, x, y):
        work["steps"] += inside[0]
        return nll(self, x, y)

    def timed_fit(*args, **kwargs):
        work["fits"] += 1
        inside[0], start = True, time.process_time()
        try:
            return fit(*args, **kwargs)
        finally:
            inside[0] = False
            work["fit_s"] += time.process_time() - start

    recipe.fit_dynamics, dynamics.DynamicsLoss.nll = timed_fit, counted_nll
    try:
        fps = bench_train.ours_one_env(case, frames, seed=seed)["fps"]
    finally:
        recipe.fit_dynamics, dynamics.DynamicsLoss.nll, bench_train.CLOCK = fit, nll, clock
    return {"fps": fps, **work}


def mb(case: str, frames: int, seed: int, python: str) -> dict:
    """MB's run of the case in its own python (``bench_train.mb_one_env``), the ensemble's fits timed and counted."""
    r = bench_train.mb_one_env(case, frames, Path(python), seed=seed, clock="cpu", prelude=_MB_PRELUDE)
    return {"fps": r["fps"], **r["extra"]}


def outside_fits(r: dict, frames: int) -> float:
    """Frames/s with the fits' CPU time taken out of the run's."""
    return frames / (frames / r["fps"] - r["fit_s"])


def row(lib: str, seed: int, r: dict, frames: int) -> str:
    per_step = r["fit_s"] / r["steps"] * 1e3 if r["steps"] else float("nan")
    return (f"{seed:>4} {lib:<5} {r['fps']:>8.1f} {r['fits']:>5} {r['steps']:>7} {r['fit_s']:>8.1f} {per_step:>8.2f} "
            f"{outside_fits(r, frames):>12.1f}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", default="gpi_pd-dst", help="a GPI-PD parity case (benchmarks/parity/common.py)")
    p.add_argument("--frames", type=int, default=2_000)
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--mb-python", default=None, help="MORL-Baselines' python (default: bench_train's)")
    args = p.parse_args(argv)
    import torch

    torch.set_num_threads(1)
    python = bench_train.mb_python(args.mb_python)
    if python is None:
        raise SystemExit("no MORL-Baselines python: python benchmarks/parity/run_parity.py --mb-venv /tmp/mbvenv "
                         "--mb-venv-only")
    print(f"{args.case}, {args.frames} frames, process CPU time, 1 thread; MB: {python}")
    print(f"{'seed':>4} {'lib':<5} {'f/s':>8} {'fits':>5} {'steps':>7} {'fit s':>8} {'ms/step':>8} {'f/s outside':>12}")
    for seed in args.seeds:
        a, b = ours(args.case, args.frames, seed), mb(args.case, args.frames, seed, str(python))
        print(row("ours", seed, a, args.frames))
        print(row("MB", seed, b, args.frames))
        print(f"{'':>4} ours / MB: f/s {a['fps'] / b['fps']:.2f}x, outside the fits "
              f"{outside_fits(a, args.frames) / outside_fits(b, args.frames):.2f}x, fitted steps "
              f"{a['steps'] / max(b['steps'], 1):.2f}x, CPU per fitted step "
              f"{(a['fit_s'] / max(a['steps'], 1)) / (b['fit_s'] / max(b['steps'], 1)):.2f}x", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
