"""A run's management around a recipe's loop, in one ``with``: :meth:`Run.session <morl_trl.runs.Run.session>`.

Everything a training run does besides learning happens here, the same for every algorithm:

* entering: the run directory, ``config.json``, the logs and the progress bar (:meth:`~morl_trl.runs.Run.start`); a
  new run evaluates its untrained policy and writes a first checkpoint to resume from (if either fails the run
  directory is removed and a run it replaced is put back); a resumed run puts its env and collector back where the
  checkpoint left them (exactly where the domain can snapshot its simulator, else with fresh episodes and a note
  saying so) and, last, the global random generators;
* per batch (:meth:`~morl_trl.runs.Run.collected`, :meth:`~morl_trl.runs.Run.step`): the frame count, the episodes'
  returns, the losses, the progress bar, evaluations and checkpoints when due, and a first Ctrl-C: checkpoint, say
  how to resume, stop (:class:`~morl_trl.runs.interrupt.RunInterrupted`);
* leaving: at the end of the loop the last evaluation, the report and the final checkpoint
  (:meth:`~morl_trl.runs.Run.finish`); on a :class:`StopRun` from the loop (e.g. a non-finite loss) a checkpoint of
  the last good state and why, in ``log.txt`` and ``report.md``; on an ``OSError`` (a full disk) a message naming
  the last good checkpoint and how to resume; on a second Ctrl-C an immediate exit naming the same; always the
  collector's shutdown.

The recipe passes in what only it knows: ``snapshot()`` (its own state for a checkpoint:
modules, optimizers, env, collector), the evaluator, the buffer and the collector.

Example (a custom trainer's loop: three batches of a random policy, no learning; the run's
files go to a temporary folder):
    >>> import json, tempfile
    >>> from types import SimpleNamespace
    >>> from torchrl.collectors import Collector
    >>> from morl_trl.envs import domain_of, make_env
    >>> from morl_trl.evaluation import MultiContextEvaluator
    >>> from morl_trl.runs import Run
    >>> cfg = SimpleNamespace(algo="random", env_id="MOLavaGridDR-v0", seed=0, device="cpu", frames=96,
    ...     eval_interval=64, checkpoint_interval=1_000, keep_checkpoints=2, progress=False, logger="csv",
    ...     init_random_frames=96, eval_weights=2, run_dir=None)
    >>> cfg.to_dict = lambda: {"frames": cfg.frames}
    >>> cfg.save = lambda path: path.write_text(json.dumps(cfg.to_dict()))
    >>> env = make_env(cfg.env_id, num_envs=2, seed=0)
    >>> collector = Collector(env, None, frames_per_batch=32, total_frames=cfg.frames)
    >>> evaluator = MultiContextEvaluator("random", ["MOLavaGridRoom-v0"], weights=2, seed=0)
    >>> run = Run(cfg, Path(tempfile.mkdtemp()) / "run")
    >>> with run.session(domain_of(cfg.env_id), evaluator=evaluator, snapshot=lambda: {}, collector=collector):
    ...     for batch in collector:
    ...         frames = run.collected(batch)
    ...         run.step()  # (no losses, no updates)  # doctest: +ELLIPSIS
    start: random on MOLavaGridDR-v0, seed 0, cpu: frame budget 96 (96 to go, ...
    [eval @ 0 frames (... s)] mean over contexts: hypervolume 0, eum -1091
    [eval @ 64 frames (... s)] mean over contexts: hypervolume 0, eum -1091
    [eval @ 96 frames (... s)] mean over contexts: hypervolume 0, eum -1091
    # random on MOLavaGridDR-v0 (seed 0)
    ...
    >>> run.frames, sorted(p.name for p in (run.dir / "checkpoints").iterdir())
    (96, ['frames_000000000000', 'frames_000000000096', 'latest'])
    >>> [line.split(",")[0] for line in (run.dir / "eval" / "metrics.csv").read_text().splitlines()]
    ['frames', '0', '64', '96']
    >>> [line[20:].split(" (")[0] for line in (run.dir / "log.txt").read_text().splitlines()][1:]  # every evaluation, and how it ended
    ['[eval @ 0 frames', '[eval @ 64 frames', '[eval @ 96 frames', 'finished: 96 frames, 0 updates; the final checkpoint is frames_000000000096']
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Callable

from morl_trl._torchrl_compat import load_collector_state
from morl_trl.runs.atomic import DiskFullError, disk_error
from morl_trl.runs.checkpoint import damaged, find_checkpoint, set_rng_state
from morl_trl.runs.plain import first_line
from morl_trl.runs.env_state import load_context_sampler_state, load_env_state, transforms_of
from morl_trl.runs.interrupt import GracefulInterrupt, RunInterrupted, signal_name

__all__ = ["StopRun", "session", "restore_fresh_episodes", "resume_command", "latest_checkpoint_name"]


class StopRun(RuntimeError):
    """An error after which a run stops cleanly (e.g. a non-finite loss,
    :class:`~morl_trl.training.optim.NonFiniteLossError`): raised inside :meth:`Run.session
    <morl_trl.runs.Run.session>`, the last good state is checkpointed, ``log.txt`` and
    ``report.md`` say why, and the error is raised again with the checkpoint's path.

    Attributes:
        updates_done: set by the raiser when some updates of the batch were applied before it
            (they are counted in the run's updates).
    """


def resume_command(cfg, run_dir: Path) -> str:
    """The command that resumes the run (what an interrupted or stopped run prints)."""
    return f"morl-trl train {cfg.algo} {cfg.env_id} --resume {run_dir}"


def latest_checkpoint_name(run_dir: Path) -> str:
    """The name of the newest intact checkpoint of ``run_dir`` (``"none"`` without one)."""
    found = find_checkpoint(run_dir, only=("state.pt",))[0]
    return found.name if found is not None else "none"


def restore_fresh_episodes(env, state: dict, seed: int) -> None:
    """A resumed run whose simulators cannot continue their episodes: they restart from ``seed``
    (derived from the checkpoint, not the run's first seed, which would replay the first
    episodes); the transforms' generators and the domain randomization stream continue."""
    env.set_seed(seed)
    for t, saved in zip(transforms_of(env), state["env"]["transforms"]):
        if "generator" in saved:
            t.generator.set_state(saved["generator"])
    load_context_sampler_state(env, state["env"])


@contextmanager
def session(run, spec, reference=None, *, evaluator, snapshot: Callable[[], dict], buffer=None, collector=None,
            notes: list[str] = (), resume_command_text: str | None = None):
    """The body of :meth:`Run.session <morl_trl.runs.Run.session>` (see the module docstring)."""
    interrupt = GracefulInterrupt()  # (its handlers stay until the run has left: a second signal exits at once)
    with interrupt, _session(run, spec, reference, evaluator=evaluator, snapshot=snapshot, buffer=buffer,
                             collector=collector, notes=notes, resume_command_text=resume_command_text,
                             interrupt=interrupt) as out:
        yield out


@contextmanager
def _session(run, spec, reference=None, *, evaluator, snapshot, buffer, collector, notes, resume_command_text,
             interrupt):
    cfg = run.cfg
    resumed = run.restored
    state, env, device = resumed if resumed is not None else (None, None, None)
    command = resume_command_text or resume_command(cfg, run.dir)
    started = run.resume_from is not None
    ended = False
    run._session = dict(evaluator=evaluator, snapshot=snapshot, buffer=buffer, interrupt=interrupt, command=command)
    try:
        with run.start(spec, reference, notes=notes):
            if run.resume_from is None:  # a new run: the untrained policy, then a checkpoint to resume from
                try:
                    run.evaluate(evaluator)
                    run.checkpoint(snapshot(), buffer)
                except BaseException:
                    run.abort_start()  # (the run it replaces, if any, is put back)
                    raise
                run.started()  # the run it replaces is deleted now
                started = True
            elif state is not None:
                if env is not None:  # (restore(env=...): the env, and the collector, continue)
                    try:
                        _continue_env(run, spec, state, env, collector, device)
                    except (KeyError, TypeError, AttributeError, RuntimeError, IndexError, ValueError) as err:
                        raise damaged(run.resume_from, f"its env and collector state does not fit this run's "
                                                       f"({first_line(err)})") from None
                set_rng_state(state["rng"])  # last: nothing above draws from the global generators again
            try:
                yield run  # the recipe's loop
            except StopRun as err:
                run.updates += getattr(err, "updates_done", 0)
                path = run.stop(str(err), snapshot(), buffer)
                ended = True  # (log.txt's last line is written)
                raise type(err)(f"{err}; the last good state is checkpointed in {path}") from None
            run.finish(evaluator, snapshot(), buffer, random_baseline=bool(getattr(cfg, "eval_random_baseline", False)))
    except RunInterrupted:
        raise
    except OSError as err:  # a full disk, a folder made read-only, ...: stop, keep the last good checkpoint
        if not started:
            raise
        reason = err if isinstance(err, DiskFullError) else disk_error(err, "the run's files")
        msg = (f"stopped: {reason.strerror or reason} at {run.frames:,} frames; the last good checkpoint is "
               f"{latest_checkpoint_name(run.dir)}; once the cause is fixed, resume with: {command}")
        for say in (run.log.report_stop, run.log.note):  # (log.txt's last line)
            try:
                say(msg)
            except OSError:
                pass  # (the disk may still be full)
        raise type(reason)(reason.errno, msg) from None
    except BaseException as err:
        if not started or ended or run.log is None:
            raise
        last = latest_checkpoint_name(run.dir)
        # a second signal (it may surface as another error from where it landed): exit at once
        if isinstance(err, KeyboardInterrupt) or interrupt.count >= 2:
            signum = getattr(err, "signum", interrupt.signum)
            msg = f"interrupted; the last checkpoint is {last}; resume with: {command}"
            _last_line(run, f"stopped by a second {signal_name(signum)}: {msg}")
            raise RunInterrupted(msg, signum) from None
        first = (str(err).strip().splitlines() or [""])[0][:300]
        _last_line(run, f"stopped: {type(err).__name__}: {first} (at {run.frames:,} frames); the last checkpoint is "
                        f"{last}; once the cause is fixed, resume with: {command}")
        raise
    finally:
        run._session = None
        if collector is not None:
            collector.shutdown()


def _last_line(run, message: str) -> None:
    """The line that ends ``log.txt`` (why the run stopped), if it can still be written."""
    try:
        run.log.note(message)
    except OSError:
        pass


def _continue_env(run, spec, state: dict, env, collector, device) -> None:
    """A resumed run's env and collector: exactly where the checkpoint left them (:attr:`Run.exact
    <morl_trl.runs.Run.exact>`), else a note that the episodes restarted (:meth:`Run.restore
    <morl_trl.runs.Run.restore>` reseeded them) and why."""
    if run.exact:
        load_env_state(env, state["env"])
        if collector is not None:
            load_collector_state(collector, state, device)
    elif state["device"] != str(device):
        run.note(f"resumed with fresh episodes: the device changed from {state['device']} to {device}")
    else:
        run.note(f"resumed with fresh episodes: {spec.name} cannot snapshot its simulator")
