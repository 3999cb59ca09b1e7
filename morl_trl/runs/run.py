"""A training run's management, in one object every recipe uses the same way: :class:`Run`.

The run directory (a new run refuses a non-empty one unless it may overwrite it; ``--resume``
continues the newest intact checkpoint), ``config.json``, the logs (:class:`~morl_trl.runs.RunLog`),
the evaluation and checkpoint schedules, checkpoints (:mod:`morl_trl.runs.checkpoint`), the
progress bar, the report, Ctrl-C and a clean stop. What the recipe keeps is the learning: build
the env, its modules and the collector, then the loop inside :meth:`Run.session`::

    run = Run.open(cfg, resume=..., overwrite=..., load_config=TrainConfig.load, resume_config=resume_config)
    ...build env, modules, evaluator, buffer (nothing is written before this point)...
    state = run.restore(buffer, map_location=device, env=env)  # a resumed run: the checkpoint's state
    ...load the modules' state from it, build the collector...
    with run.session(spec, reference, evaluator=evaluator, snapshot=snapshot, buffer=buffer, collector=collector):
        for batch in collector:
            frames = run.collected(batch)             # count the frames, log the finished episodes
            ...the algorithm's per-frame work (it may raise StopRun, e.g. a non-finite loss)...
            run.step(losses, updates, epsilon=eps)    # log, progress; evaluate / checkpoint when due; Ctrl-C

:mod:`morl_trl.runs.session` says what the session does on entry, on exit and on each way a run can stop.

Every write to the run directory goes through this object (and the :class:`RunLog` it holds),
so run-wide policies (locks, atomic writes, Ctrl-C) have one place to live: :meth:`start`,
:meth:`checkpoint`, :meth:`stop` and :meth:`__exit__`.

The config is any object with ``to_dict()``, ``save(path)``, ``validate()``, ``run_dir``, ``frames``,
``eval_interval``, ``checkpoint_interval``, ``keep_checkpoints``, ``progress``, ``logger``, ``algo``, ``env_id``,
``seed`` and, optionally, ``eval_random_baseline`` (the recipes' ``TrainConfig``).

Example:
    >>> from types import SimpleNamespace
    >>> cfg = SimpleNamespace(frames=100, eval_interval=50, checkpoint_interval=40)
    >>> run = Run(cfg, Path("unused"))
    >>> run.frames = 40
    >>> run.eval_due(), run.checkpoint_due()
    (True, True)
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable

from tqdm.auto import tqdm

from morl_trl.runs.estimate import DurationEstimate, hms
from morl_trl.runs.checkpoint import (RUN_STATE, check_rng_state, damaged, checkpoint_buffer, checkpoint_frames,
                                      find_checkpoint, load_checkpoint, rng_state, save_checkpoint)
from morl_trl.runs.interrupt import RunInterrupted
from morl_trl.runs.plain import first_line
from morl_trl.runs.lock import RunLock
from morl_trl.runs.run_dir import NewRunDir, check_new_run_dir
from morl_trl.runs.run_log import RunLog, check_logger
from morl_trl.runs.session import restore_fresh_episodes, session

__all__ = ["Run", "RUN_DIR_PATTERN", "default_run_dir", "eval_line", "start_line"]


#: the pattern of :func:`default_run_dir` (what docs/getting-started.md shows; tests/docs checks both)
RUN_DIR_PATTERN = "runs/<algo>_<env id>_s<seed>_<YYYYmmdd-HHMMSS>"


def default_run_dir(cfg) -> Path:
    """``runs/<algo>_<env id>_s<seed>_<YYYYmmdd-HHMMSS>`` (:data:`RUN_DIR_PATTERN`), a fresh one: a
    second run started within the same second gets ``-2`` (``-3``, ...) after the time.

    Example:
        >>> from types import SimpleNamespace
        >>> default_run_dir(SimpleNamespace(algo="envelope", env_id="MOLavaGridDR-v0", seed=0)).parent
        PosixPath('runs')
    """
    stamp = time.strftime("%Y%m%d-%H%M%S")
    base = Path("runs") / f"{cfg.algo}_{cfg.env_id}_s{cfg.seed}_{stamp}"
    path, n = base, 1
    while path.exists():
        n += 1
        path = base.with_name(f"{base.name}-{n}")
    return path


def eval_line(summary: dict, seconds: float | None = None) -> str:
    """The one line an evaluation prints and writes to ``log.txt`` (with how long it took)."""
    agg = summary["aggregate"]
    parts = [f"{m} {agg[m]:.4g}" for m in ("nhgr", "normalized_hypervolume", "hypervolume", "eum") if m in agg]
    took = "" if seconds is None else f" ({seconds:.1f} s)"
    return f"[eval @ {summary['frames']:,} frames{took}] mean over contexts: " + ", ".join(parts)


def start_line(cfg, frames: int, resumed: bool) -> str:
    """The first line of a run in log.txt: what it will do and how much (the duration follows once measured)."""
    evals = max(0, (cfg.frames - frames) // max(cfg.eval_interval, 1)) + 1
    what = "resume" if resumed else "start"
    count = "1 evaluation" if evals == 1 else f"about {evals} evaluations"
    return (f"{what}: {cfg.algo} on {cfg.env_id}, seed {cfg.seed}, {cfg.device}: frame budget {cfg.frames:,} "
            f"({cfg.frames - frames:,} to go, {getattr(cfg, 'init_random_frames', 0):,} of them random before learning), "
            f"{count} of {cfg.eval_weights} weights; the estimated duration follows once the "
            f"learning speed is measured")


#: the progress bar: tqdm's without its frame-rate ETA (the postfix holds the run's own estimate)
BAR_FORMAT = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}, {rate_fmt}{postfix}]"


class Run:
    """One training run: its directory, config, logs, schedules, checkpoints, progress and report.

    Make one with :meth:`open` (it validates and reads, writes nothing), then :meth:`restore` (a resumed run's
    checkpoint) and ``with run.session(...)`` around the loop (see the module docstring; :meth:`start` alone opens
    the run directory and logs without the session's first evaluation, resume, stop and Ctrl-C handling).

    Attributes:
        cfg: the config the run runs with (a resumed run's saved one, with what a resume may change).
        dir: the run directory.
        frames, updates: collected frames and gradient updates so far.
        summary: the last evaluation summary (``{}`` before the first).
        log: the :class:`RunLog` (from :meth:`start` on).
        resume_from: the checkpoint a resumed run continues from (``None`` for a new run).
    """

    def __init__(self, cfg, run_dir: Path, *, resume_from: Path | None = None, overwrite: bool = False,
                 notes: list[str] | None = None) -> None:
        self.cfg = cfg
        self.dir = Path(run_dir)
        self.resume_from = resume_from
        self.overwrite = overwrite
        self.notes = list(notes or [])
        self.frames, self.updates = 0, 0
        self.next_eval, self.next_ckpt, self.last_eval = 0, cfg.checkpoint_interval, -1
        self.summary: dict = {}
        self.log: RunLog | None = None
        self.reference = None
        self._bar = None
        self._clock = (time.perf_counter(), 0)
        self._eval_seconds: list[float] = []
        self._eta = None
        self.trust_pickle = False
        self.echo_report = True  # False: the report prints its one-line summary, not its tables
        self.lock: RunLock | None = None
        self._starting: NewRunDir | None = None
        self.restored: tuple | None = None  # (state, env, device) of restore(env=...), for the session
        self.exact = False
        self._session: dict | None = None
        self._batch_frames = 0

    # ------------------------------------------------------------------ before anything is written
    @classmethod
    def open(cls, cfg=None, *, resume: str | Path | None = None, overwrite: bool = False,
             load_config: Callable[[Path], Any], resume_config: Callable[[Any, dict, str], Any]) -> "Run":
        """A new run of ``cfg`` (its ``run_dir`` must be empty, or a run to replace with
        ``overwrite``), or, with ``resume=run_dir``, the continuation of that run from its newest
        intact checkpoint (``cfg``, optional, may change what ``resume_config`` allows). Reads only.

        Raises:
            ValueError: a non-empty run directory without ``overwrite``; nothing to resume from.
        """
        if resume is None:
            if cfg is None:
                raise ValueError("train() needs a config (or resume=<run dir>)")
            cfg.validate()
            run_dir = Path(cfg.run_dir) if cfg.run_dir else default_run_dir(cfg)
            check_new_run_dir(run_dir, overwrite)
            check_logger(cfg.logger)
            return cls(cfg, run_dir, overwrite=overwrite)
        if overwrite:
            raise ValueError("resume continues a run and overwrite replaces it: choose one")
        run_dir = Path(resume)
        saved = run_dir / "config.json"
        if not saved.is_file():
            raise ValueError(f"cannot resume: {str(run_dir)!r} has no config.json (not a run directory)")
        saved_cfg = load_config(saved)
        cfg = saved_cfg if cfg is None else resume_config(saved_cfg, cfg.to_dict(), "the given config")
        cfg.run_dir = saved_cfg.run_dir
        changed = {k: (getattr(saved_cfg, k), getattr(cfg, k)) for k in saved_cfg.to_dict()
                   if getattr(saved_cfg, k) != getattr(cfg, k)}
        ckpt, skipped = find_checkpoint(run_dir)
        notes = [f"warning: skipped damaged checkpoint {p.name}: {why}" for p, why in skipped]
        if changed:
            notes.append("resumed with " + ", ".join(f"{k} {a!r} -> {b!r}" for k, (a, b) in changed.items()))
        if ckpt is None:
            what = "; ".join(f"{p.name}: {why}" for p, why in skipped) or "there is none"
            raise ValueError(f"cannot resume {str(run_dir)!r}: no intact checkpoint ({what}); "
                             f"start it again with overwrite=True")
        run = cls(cfg, run_dir, resume_from=ckpt, notes=notes)
        run.frames = checkpoint_frames(ckpt)
        if not run.done:
            check_logger(cfg.logger)
        return run

    @property
    def done(self) -> bool:
        """A resumed run that already reached ``cfg.frames`` (nothing to do)."""
        return self.resume_from is not None and self.frames >= self.cfg.frames

    def restore(self, buffer=None, map_location=None, *, env=None) -> dict | None:
        """A resumed run: the checkpoint's state (``buffer`` refilled when it holds one), with
        the run's counters and schedules continued from it. ``None`` for a new run.

        With the training ``env`` (call it before building the collector), the run continues
        exactly where the checkpoint left it (:attr:`exact`: the domain snapshots its simulator
        and the device is the checkpoint's; :meth:`session` then puts the env and the collector
        back), else the simulators restart their episodes from a seed derived from the
        checkpoint (:func:`~morl_trl.runs.session.restore_fresh_episodes`) and the session says so."""
        if self.resume_from is None:
            return None
        state = load_checkpoint(self.resume_from, buffer, map_location=map_location, trust_pickle=self.trust_pickle,
                                keys=RUN_STATE)
        self.frames, self.updates, self.last_eval = state["frames"], state["updates"], state["last_eval"]
        self.next_eval, self.next_ckpt = state["next_eval"], state["next_ckpt"]
        check_rng_state(self.resume_from, state["rng"])
        if env is not None:
            try:
                self.exact = state["env"]["simulator"] is not None and state["device"] == str(map_location)
                if not self.exact:
                    restore_fresh_episodes(env, state, self.cfg.seed + self.frames)
            except (KeyError, TypeError, AttributeError, RuntimeError, IndexError, ValueError) as err:
                raise damaged(self.resume_from, f"its env state does not fit this run's env ({first_line(err)})"
                              ) from None
        self.restored = (state, env, map_location)
        return state

    def session(self, spec, reference=None, *, evaluator, snapshot, buffer=None, collector=None,
                notes: list[str] = (), resume_command: str | None = None):
        """The run around the recipe's loop (``with run.session(...):``; see :mod:`morl_trl.runs.session`).

        Args:
            spec: the run's domain (its objectives, for the logs and report).
            reference: the domain's reference data (NHGR), or ``None``.
            evaluator: evaluated (``evaluator.evaluate()``) at the start of a new run, when due and at the end.
            snapshot: ``snapshot() -> dict``, the recipe's own state for a checkpoint (modules,
                optimizers, env, collector, device); the run adds its counters, RNG and config.
            buffer: the replay buffer checkpointed with it (``None``: none).
            collector: put back on an exact resume, shut down at the end.
            notes: lines for ``log.txt`` after the run's own.
            resume_command: the command an interrupted run prints (default
                ``morl-trl train ALGO ENV_ID --resume RUN_DIR``).
        """
        return session(self, spec, reference, evaluator=evaluator, snapshot=snapshot, buffer=buffer,
                       collector=collector, notes=notes, resume_command_text=resume_command)

    # ------------------------------------------------------------------ the run directory
    def start(self, spec, reference=None, *, notes: list[str] = ()) -> "Run":
        """Create (or, with ``overwrite``, replace) the run directory, save ``config.json``, open the logs, write the
        notes, cut a resumed run's logs back to its checkpoint, show the progress bar. A failed start leaves no new
        run directory behind. Use as ``with run.start(...)``. ``notes`` go to log.txt after :meth:`open`'s own."""
        cfg = self.cfg
        if self.resume_from is None:  # everything is built: the directory swaps in (an old run is set aside)
            self._starting = NewRunDir(self.dir, self.overwrite)
            self.lock = self._starting.start()
        try:
            if self.resume_from is None:
                cfg.run_dir = str(self.dir)
                cfg.save(self.dir / "config.json")
            self.log = RunLog(self.dir, cfg, spec)
            self.log.echo_report = self.echo_report
        except BaseException:
            if self._starting is not None:
                self._starting.abort()
            raise
        self.reference = self.log.reference = reference
        self.log.note(start_line(cfg, self.frames, self.resume_from is not None))  # (log.txt exists on every run)
        for note in [*self.notes, *notes]:
            self.log.note(note)
        if self.resume_from is not None:
            if cfg.to_dict() != type(cfg).load(self.dir / "config.json").to_dict():
                cfg.save(self.dir / "config.json")  # what the run continues with (e.g. a larger frames)
            cut = self.log.truncate(self.frames)
            self.log.note(f"resumed from {self.resume_from.name} at {self.frames} frames "
                          f"(logs cut back to it: {cut} rows/files removed)")
            if checkpoint_buffer(self.resume_from) == "pruned":
                self.log.note(f"warning: {self.resume_from.name} holds no replay buffer (only the newest checkpoint "
                              f"keeps it): the run continues with an empty replay buffer")
        # (the time left is the run's own estimate, evaluations included, not tqdm's frame-rate one)
        self._bar = tqdm(total=cfg.frames, initial=self.frames, unit="frame", disable=not cfg.progress,
                         dynamic_ncols=True, bar_format=BAR_FORMAT)
        self._clock = (time.perf_counter(), self.frames)
        self._eta = DurationEstimate(cfg, self.frames)
        self._show_progress()
        return self

    def note(self, message: str) -> None:
        """A line in ``log.txt`` (and above the progress bar)."""
        self.log.note(message)

    def __enter__(self) -> "Run":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        # (the one place a run ends, however it ends: a Ctrl-C handler hooks in here)
        self.close()

    def started(self) -> None:
        """A new run wrote its first checkpoint: the run it replaces (``overwrite``) is deleted now."""
        if self._starting is not None:
            self._starting.commit()

    def abort_start(self) -> None:
        """A new run failed before its first checkpoint: remove it, put back the run it replaced."""
        if self._starting is not None:
            self._starting.abort()
            self._starting = None

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
        if self.log is not None:
            self.log.close()
        if self.lock is not None:
            self.lock.release()

    # ------------------------------------------------------------------ per batch
    def fps(self) -> float:
        """Frames per second since :meth:`start`."""
        t0, f0 = self._clock
        return (self.frames - f0) / max(time.perf_counter() - t0, 1e-9)

    def batch_done(self, frames: int, losses=None, updates: int = 0, *, epsilon: float | None = None) -> None:
        """After a batch of ``frames`` frames and ``updates`` updates: count them, log the losses
        (every 50 updates, or every batch of several; with the frame rate and ``epsilon``),
        advance the progress bar, say the estimated duration once it is measured."""
        self.updates += updates
        if losses is not None and (self.updates % 50 == 0 or updates > 1):
            self.log.losses(self.frames, losses, frames_per_second=self.fps(), epsilon=epsilon)
        if self.frames > self._bar.total:  # (a last batch past the budget: the bar stays a bar)
            self._bar.total = self.frames
        self._bar.update(frames)
        self._eta.batch(self.frames)
        line = self._eta.first_line(self.frames, self.next_eval)
        if line is not None:
            self.log.note(line)
        self._show_progress()

    def _show_progress(self, refresh: bool = False) -> None:
        """The bar's postfix: the estimated time left (once measured) and the latest evaluation's NHGR."""
        if self.frames >= self.cfg.frames:
            parts = ["finishing"]  # (the last evaluation, the report)
        else:
            left = self._eta.seconds_left(self.frames, self.next_eval)
            parts = ["left: measuring" if left is None else f"~{hms(left)} left"]
        nhgr = self.summary.get("nhgr_mean", float("nan"))
        if self.summary:
            parts.append(f"NHGR {nhgr:.3f} @ {self.summary['frames']:,}" if nhgr == nhgr
                         else f"evaluated @ {self.summary['frames']:,}")
        self._bar.set_postfix_str(", ".join(parts), refresh=refresh)

    def collected(self, batch, frames: int | None = None, *, log: bool = True) -> int:
        """A collected ``batch`` (inside :meth:`session`): count its ``frames`` (default ``batch.numel()``; PGMORL
        counts one member's) and log its finished episodes' returns (``log``). Returns the run's frames so far."""
        self._batch_frames = batch.numel() if frames is None else frames
        self.frames += self._batch_frames
        if log:
            self.log.training_episodes(self.frames, batch)
        return self.frames

    def step(self, losses=None, updates: int = 0, *, epsilon: float | None = None) -> None:
        """The end of a batch (inside :meth:`session`, after :meth:`collected` and the updates):
        :meth:`batch_done`, then an evaluation and a checkpoint when due, then, after a Ctrl-C, a
        checkpoint and :class:`~morl_trl.runs.interrupt.RunInterrupted` naming the command that resumes."""
        session = self._session
        self.batch_done(self._batch_frames, losses, updates, epsilon=epsilon)
        if self.eval_due():
            self.evaluate(session["evaluator"])
        if self.checkpoint_due():
            self.checkpoint(session["snapshot"](), session["buffer"])
        interrupt = session["interrupt"]
        if interrupt.requested and self.frames < self.cfg.frames:  # a signal: checkpoint, say how to resume
            path = self.checkpoint(session["snapshot"](), session["buffer"], interrupted=True)
            msg = f"interrupted at {self.frames:,} frames; checkpointed in {path.name}; resume with: {session['command']}"
            self.log.report_stop(msg)
            self.note(f"stopped by {interrupt.signal_name}: {msg}")  # (the last line of log.txt)
            raise RunInterrupted(msg, interrupt.signum)

    def eval_due(self) -> bool:
        return self.frames >= self.next_eval

    def checkpoint_due(self) -> bool:
        """Whether a periodic checkpoint is due (the end of the run has its own, :meth:`finish`)."""
        return self.frames >= self.next_ckpt and self.frames < self.cfg.frames

    # ------------------------------------------------------------------ evaluations, checkpoints, the end
    def evaluate(self, evaluator, *args) -> dict:
        """Evaluate now (``evaluator.evaluate(*args)``), log it and move the schedule on."""
        t0 = time.perf_counter()
        self.summary = self.log.evaluation(self.frames, evaluator.evaluate(*args))
        seconds = time.perf_counter() - t0
        self._eval_seconds.append(seconds)
        self.last_eval = self.frames
        while self.next_eval <= self.frames:
            self.next_eval += self.cfg.eval_interval
        self.log.note(eval_line(self.summary, seconds))  # (log.txt holds every evaluation)
        if self._eta is not None:
            self._eta.evaluated(self.frames, seconds)
            if 0 < self.frames < self.cfg.frames and self._eta.said:  # (renewed after each evaluation)
                line = self._eta.line(self.frames, self.next_eval)
                if line is not None:
                    self.log.note(line)
        if self._bar is not None:
            self._show_progress(refresh=True)  # (the latest evaluation at once, the last one included)
        return self.summary

    def checkpoint(self, snapshot: dict, buffer=None, **flags) -> Path:
        """Write a checkpoint of the recipe's ``snapshot`` (agent, env, collector, device...), the
        run's counters, RNG states and config, and ``buffer`` (when not empty); move the schedule on."""
        self.log.flush()  # every log row up to this frame is written before the checkpoint
        if not flags:  # a periodic one (the final and the stop checkpoints leave the schedule as it is)
            while self.next_ckpt <= self.frames:
                self.next_ckpt += self.cfg.checkpoint_interval
        state = dict(snapshot, frames=self.frames, updates=self.updates, next_eval=self.next_eval,
                     next_ckpt=self.next_ckpt, last_eval=self.last_eval, rng=rng_state(), config=self.cfg.to_dict(),
                     **flags)
        return save_checkpoint(self.dir, self.frames, state, buffer if buffer is not None and len(buffer) else None,
                               keep=self.cfg.keep_checkpoints)

    def finish(self, evaluator, snapshot: dict, buffer=None, *, random_baseline: bool = False) -> dict:
        """The end of the run: a last evaluation (unless this frame was evaluated), the random
        baseline (``random_baseline``), the report, the final checkpoint."""
        if self.last_eval != self.frames:
            self.evaluate(evaluator)
        if random_baseline:
            self.log.random_result = evaluator.evaluate("random")
        if self.log.last_result is not None:
            self.log.report(self.summary, fps=self.fps())
        path = self.checkpoint(snapshot, buffer, finished=True)
        self.log.note(f"finished: {self.frames:,} frames, {self.updates:,} updates; the final checkpoint is "
                      f"{path.name}")  # (the last line of log.txt)
        return self.summary

    def stop(self, error: str, snapshot: dict, buffer=None) -> Path:
        """Stop the run cleanly on ``error`` (e.g. a non-finite loss): checkpoint the last good
        state, say why in log.txt and report.md; returns the checkpoint's path."""
        path = self.checkpoint(snapshot, buffer, stopped=error)
        reason = f"{error} (at {self.frames:,} frames, after {self.updates} updates)"
        if self.log.last_result is not None:
            self.log.report(self.summary, fps=self.fps())
        self.log.report_stop(f"stopped: {reason}; the last good state is checkpointed in {path.name}")
        command = (self._session or {}).get("command")
        self.log.note(f"stopped: {reason}; the last good state is checkpointed in {path}"
                      + (f"; once the cause is fixed, resume with: {command}" if command else ""))
        return path
