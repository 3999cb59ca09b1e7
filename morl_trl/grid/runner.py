"""Run a grid on Ray Tune: one trial per unfinished cell, each a ``morl-trl train`` run.

Ray Tune does the scheduling (resources per trial, CPUs and fractional GPUs, so several small runs share one GPU),
the retries (a trial whose worker dies is started again, up to ``max_failures`` times) and the cluster
(``address``); our checkpoints do the rest: a trial resumes its cell's run from the newest intact checkpoint
(``train(cfg, resume=run_dir)``), so a killed worker loses at most the frames since that checkpoint. Running the
same grid again skips the finished cells and resumes the others. A cell whose run raises (a non-finite loss, a bad
config) is recorded as failed with its error and the grid goes on; it is not retried in the same invocation (the
next one tries it again, from its checkpoint).

On a cluster, the grid directory must be on a filesystem every node sees (each trial writes its
run directory there).

Example:
    >>> from morl_trl.grid import GridSpec, run_grid   # doctest: +SKIP
    >>> spec = GridSpec.from_dict({"algorithms": ["envelope"], "domains": ["MOLavaGridDR-v0"],
    ...                            "seeds": [0, 1], "quick": True})                       # doctest: +SKIP
    >>> states = run_grid(spec, "grids/mine")                                             # doctest: +SKIP
"""

from __future__ import annotations

import json
import os
import sys
import time
import traceback
from collections.abc import Callable
from pathlib import Path

from morl_trl.grid.spec import Cell, GridSpec
from morl_trl.runs.atomic import atomic_write_text
from morl_trl.grid.status import CellState, format_status, grid_status, read_cell_record, write_cell_record

__all__ = ["run_grid", "run_cell", "GridProgress"]


def run_cell(cell: Cell, run_dir: Path) -> dict:
    """Train ``cell`` in ``run_dir``: resume from its newest intact checkpoint when it has one,
    else start it (replacing a start killed before its first checkpoint). Returns the summary."""
    from morl_trl.recipes import train
    from morl_trl.runs import find_checkpoint

    cfg = cell.config(run_dir)
    if (run_dir / "config.json").is_file() and find_checkpoint(run_dir)[0] is not None:
        return train(cfg, resume=run_dir, trust_code=list(cfg.domain_modules))  # (the grid file names them)
    return train(cfg, overwrite=True)


#: seconds a trial waits for an earlier attempt's process to let go of its cell
LOCK_WAIT_S = 120.0


def _lock_cell(grid_dir: Path, name: str, wait_s: float = LOCK_WAIT_S):
    """An exclusive lock on ``cells/<name>.lock`` (released when its process dies, even by SIGKILL),
    so two attempts never write one run directory: a worker of a killed grid can outlive its
    driver for a few seconds. Returns the open file holding the lock."""
    import fcntl

    (grid_dir / "cells").mkdir(parents=True, exist_ok=True)
    fh = open(grid_dir / "cells" / f"{name}.lock", "a+")  # noqa: SIM115 - held for the trial's lifetime
    deadline = time.monotonic() + wait_s
    while True:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return fh
        except BlockingIOError:
            if time.monotonic() > deadline:
                fh.close()
                raise RuntimeError(f"another process still holds cell {name} after {wait_s:.0f} s (a worker of an "
                                   f"earlier grid run?); run the grid again once it has stopped") from None
            time.sleep(0.2)


def _trainable(config: dict) -> None:
    """The Tune trial of one cell (runs in a Ray worker)."""
    from ray import tune

    cell = Cell(**config["cell"])
    grid_dir = Path(config["grid_dir"])
    run = config.get("run_cell") or run_cell
    lock = _lock_cell(grid_dir, cell.name)
    try:
        _run_trial(cell, grid_dir, run, tune)
    finally:
        lock.close()  # (releases the lock)


def _run_trial(cell: Cell, grid_dir: Path, run, tune) -> None:
    record = read_cell_record(grid_dir, cell.name)
    write_cell_record(grid_dir, cell.name, status="running", attempts=int(record.get("attempts", 0)) + 1,
                      error=None, host=os.uname().nodename, pid=os.getpid())
    t0 = time.perf_counter()
    try:
        summary = run(cell, grid_dir / "runs" / cell.name)
    except Exception as err:  # noqa: BLE001 - recorded, reported, and the grid goes on
        wall = float(read_cell_record(grid_dir, cell.name).get("wall_s") or 0.0) + time.perf_counter() - t0
        write_cell_record(grid_dir, cell.name, status="failed", error=f"{type(err).__name__}: {err}",
                          traceback=traceback.format_exc(), wall_s=wall)
        tune.report({"failed": 1, "frames": 0, "nhgr_mean": float("nan")})
        return
    wall = float(read_cell_record(grid_dir, cell.name).get("wall_s") or 0.0) + time.perf_counter() - t0
    write_cell_record(grid_dir, cell.name, status="done", error=None, wall_s=wall)
    tune.report({"failed": 0, "frames": int(summary.get("frames", 0)),
                 "nhgr_mean": float(summary.get("nhgr_mean", float("nan")))})


class GridProgress:
    """Live progress of the grid (cells done / running / failed, frames per cell) every
    ``interval`` seconds and at each change, and ``status.json`` in the grid directory; as a
    Ray Tune callback (:meth:`as_callback`), fed by Tune's trial events."""

    def __init__(self, grid_dir: Path, cells: list[Cell], targets: dict[str, int], *, interval: float = 30.0,
                 stream=None) -> None:
        self.grid_dir, self.cells, self.targets = Path(grid_dir), cells, targets
        self.interval, self.stream = interval, stream if stream is not None else sys.stdout
        self.running: set[str] = set()
        self.t0 = time.perf_counter()
        self._last = 0.0

    def states(self) -> list[CellState]:
        return grid_status(self.grid_dir, [(c.name, self.targets[c.name]) for c in self.cells], running=self.running)

    def show(self, per_cell: bool = True) -> None:
        states = self.states()
        atomic_write_text(self.grid_dir / "status.json", json.dumps([s.as_dict() for s in states], indent=1))
        if self.stream is not False:
            print(format_status(states, time.perf_counter() - self.t0, per_cell=per_cell), file=self.stream, flush=True)
        self._last = time.perf_counter()

    @staticmethod
    def _name(trial) -> str:
        return trial.config["cell"]["name"] if "name" in trial.config["cell"] else Cell(**trial.config["cell"]).name

    def on_trial_start(self, iteration, trials, trial, **info):
        self.running.add(self._name(trial))
        self.show(per_cell=False)

    def on_trial_recover(self, iteration, trials, trial, **info):
        name = self._name(trial)
        self.running.discard(name)
        if self.stream is not False:
            print(f"grid: {name}: its worker failed; retrying from its newest checkpoint", file=self.stream, flush=True)

    def on_trial_complete(self, iteration, trials, trial, **info):
        self.running.discard(self._name(trial))
        self.show(per_cell=False)

    def on_trial_error(self, iteration, trials, trial, **info):
        name = self._name(trial)
        self.running.discard(name)
        err = getattr(trial, "error_file", None)
        write_cell_record(self.grid_dir, name, status="failed",
                          error=f"its worker failed {trial.num_failures} time(s) (Ray: see {err})")
        self.show(per_cell=False)

    def on_step_begin(self, iteration, trials, **info):
        if time.perf_counter() - self._last >= self.interval:
            self.show()

    def on_experiment_end(self, trials, **info):
        self.running.clear()
        self.show()

    def as_callback(self):
        """A ``ray.tune.Callback`` forwarding Tune's events to this object."""
        from ray import tune

        def forward(event):
            return lambda _cb, *a, **k: getattr(self, event)(*a, **k)

        return type("_Callback", (tune.Callback,), {event: forward(event) for event in _EVENTS})()


_EVENTS = ("on_trial_start", "on_trial_recover", "on_trial_complete", "on_trial_error", "on_step_begin",
           "on_experiment_end")  # the Tune events a progress object follows


def check_grid_options(cells: list[Cell], *, address=None, num_cpus=None, num_gpus=None, max_concurrent=None,
                       max_failures=2, progress_interval=30.0) -> None:
    """``ValueError`` (naming the option and what is valid) before anything is written or started: negative counts,
    and cells that reserve more than an embedded Ray has (they would wait as pending forever)."""
    def _count(name, value, low, optional=True):
        if value is None and optional:
            return
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= low:
            raise ValueError(f"{name} is {value!r}; valid: a number >= {low}" + (" (or leave it out)" if optional else ""))

    _count("--max-concurrent (max_concurrent)", max_concurrent, 1)
    _count("--max-failures (max_failures)", max_failures, 0, optional=False)
    _count("--num-cpus (num_cpus)", num_cpus, 1)
    _count("--num-gpus (num_gpus)", num_gpus, 0)
    if not (isinstance(progress_interval, (int, float)) and progress_interval > 0):
        raise ValueError(f"--progress-interval is {progress_interval!r}; valid: seconds > 0")
    if address:  # a cluster may grow (autoscaling): Ray decides
        return
    import ray
    import torch

    if ray.is_initialized():  # (a Ray started by the caller: what it has)
        res = ray.cluster_resources()
        have = {"cpus": float(res.get("CPU", 0)), "gpus": float(res.get("GPU", 0))}
    else:
        have = {"cpus": float(num_cpus if num_cpus is not None else os.cpu_count() or 1),
                "gpus": float(num_gpus if num_gpus is not None else torch.cuda.device_count())}
    for c in cells:
        for kind, need in (("cpus", c.cpus), ("gpus", c.gpus)):
            if need > have[kind]:
                flag = {"cpus": "--cpus-per-run / resources.cpus", "gpus": "--gpus-per-run / resources.gpus"}[kind]
                raise ValueError(f"cell {c.name} reserves {kind} = {need:g} but this machine's Ray has {have[kind]:g}: "
                                 f"it would wait forever; lower {flag} (or give --num-{kind} / --address of a "
                                 f"cluster that has them)")


def _init_ray(address: str | None, num_cpus: int | None, num_gpus: float | None) -> bool:
    """Connect to (``address``) or start an embedded Ray; ``True`` if this call started it."""
    import ray

    if ray.is_initialized():
        return False
    if address:
        ray.init(address=address, include_dashboard=False, log_to_driver=False)
    else:  # sized to the machine unless told
        ray.init(num_cpus=num_cpus, num_gpus=num_gpus, include_dashboard=False, log_to_driver=False)
    return True


def run_grid(spec: GridSpec, grid_dir: str | Path, *, address: str | None = None, num_cpus: int | None = None,
             num_gpus: float | None = None, max_concurrent: int | None = None, max_failures: int = 2,
             progress_interval: float = 30.0, stream=None,
             run_cell: Callable[[Cell, Path], dict] | None = None) -> list[CellState]:
    """Run every unfinished cell of ``spec`` under ``grid_dir`` on Ray Tune; returns every cell's state.

    ``address``: an existing Ray cluster (``"auto"`` or ``"ray://host:port"``); default an embedded Ray started
    here (``num_cpus`` / ``num_gpus`` cap what it sees; default the machine's), shut down at the end.
    ``max_concurrent``: at most this many runs at once (default: as many as the resources allow). ``max_failures``:
    retries of a trial whose worker died. ``stream=False`` prints nothing. ``run_cell(cell, run_dir)`` replaces
    :func:`run_cell` (it must be importable by the workers).
    """
    os.environ.setdefault("TUNE_DISABLE_AUTO_CALLBACK_LOGGERS", "1")  # our runs log themselves: no TensorBoard/CSV
    os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")
    from ray import tune
    from ray.tune.logger import JsonLoggerCallback

    cells = spec.check()
    check_grid_options(cells, address=address, num_cpus=num_cpus, num_gpus=num_gpus, max_concurrent=max_concurrent,
                       max_failures=max_failures, progress_interval=progress_interval)
    grid_dir = Path(grid_dir).resolve()
    grid_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(grid_dir / "grid.json", json.dumps(spec.to_dict(), indent=1))
    targets = {c.name: c.config(check_device=False).frames for c in cells}
    before = grid_status(grid_dir, [(c.name, targets[c.name]) for c in cells], running=set())
    todo = [c for c, s in zip(cells, before) if s.status != "done"]
    out = stream if stream is not None else sys.stdout
    say = (lambda msg: print(msg, file=out, flush=True)) if stream is not False else (lambda msg: None)
    done = len(cells) - len(todo)
    resumed = sum(1 for s in before if s.status in ("started", "failed", "running") and s.frames > 0)
    say(f"grid {spec.name}: {len(cells)} cells in {grid_dir}: {done} finished (skipped), {len(todo)} to run"
        + (f" ({resumed} resume from their checkpoints)" if resumed else ""))
    if not todo:
        return before
    for c in todo:
        write_cell_record(grid_dir, c.name, status="pending" if not (grid_dir / "runs" / c.name).exists()
                          else "started")
    started = _init_ray(address, num_cpus, num_gpus)
    try:
        trainable = tune.with_resources(_trainable, lambda config: {"cpu": config["cell"]["cpus"],
                                                                    "gpu": config["cell"]["gpus"]})
        cell_dicts = [dict(algo=c.algo, env_id=c.env_id, seed=c.seed, overrides=c.overrides, cpus=c.cpus,
                           gpus=c.gpus, quick=c.quick) for c in todo]
        param_space = {"cell": tune.grid_search(cell_dicts), "grid_dir": str(grid_dir)}
        if run_cell is not None:
            param_space["run_cell"] = run_cell
        progress = GridProgress(grid_dir, cells, targets, interval=progress_interval, stream=out if stream is not False
                                else False)
        tuner = tune.Tuner(
            trainable, param_space=param_space,
            tune_config=tune.TuneConfig(max_concurrent_trials=max_concurrent, reuse_actors=True,
                                        trial_dirname_creator=lambda t: t.trial_id,
                                        trial_name_creator=lambda t: Cell(**t.config["cell"]).name),
            run_config=tune.RunConfig(
                name=f"{spec.name}-{time.strftime('%Y%m%d-%H%M%S')}", storage_path=str(grid_dir / "tune"),
                failure_config=tune.FailureConfig(max_failures=max_failures),
                callbacks=[progress.as_callback(), JsonLoggerCallback()], verbose=0))  # (Tune reads its result.json)
        tuner.fit()
    finally:
        if started:
            import ray

            ray.shutdown()
    return grid_status(grid_dir, [(c.name, targets[c.name]) for c in cells], running=set())
