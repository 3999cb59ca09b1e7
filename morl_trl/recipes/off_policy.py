"""The training loop of every algorithm: the paper's experimental loop (§6), read top to bottom.

Train a generalist under domain randomization, evaluate it periodically on the evaluation
suite, checkpoint, report. This is what ``morl-trl train`` runs:

1. the parts (:mod:`morl_trl.recipes.parts`): the training env, the agent of the algorithm
   (:func:`~morl_trl.recipes.algorithms.build_agent`: its modules, loss and optimizers, from its
   recipe module, e.g. :mod:`morl_trl.recipes.envelope`), the evaluator, the replay buffer and
   TorchRL's collector;
2. the loop: collect a batch, ``agent.learn`` (store + the algorithm's updates: for Envelope
   :meth:`Agent.update <morl_trl.recipes.agent.Agent.update>` with
   :class:`~morl_trl.objectives.EnvelopeQLoss`), the schedules, then evaluate and checkpoint
   when due.

Everything about the run itself (directory, resume, logs, checkpoints, progress bar, report,
a clean stop) is :class:`morl_trl.runs.Run`.
"""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import torch

from morl_trl._torchrl_compat import collector_state, load_collector_state, reset_collector
from morl_trl.envs import make_env
from morl_trl.recipes.agent import Agent
from morl_trl.recipes.algorithms import build_agent, build_training_env
from morl_trl.recipes.config import TrainConfig, resume_config
from morl_trl.recipes.optim import NonFiniteLossError
from morl_trl.recipes.parts import (
    load_reference,
    make_collector,
    make_evaluator,
    make_replay_buffer,
    make_training_env,
    no_reference_note,
    run_discount,
    run_domain,
)
from morl_trl.preferences import check_simplex
from morl_trl.runs.atomic import DiskFullError, disk_error
from morl_trl.runs.checkpoint import checkpoint_format, checkpoint_frames, find_checkpoint, load_checkpoint, set_rng_state
from morl_trl.runs.env_state import env_state, load_context_sampler_state, load_env_state, transforms_of
from morl_trl.runs.interrupt import GracefulInterrupt, RunInterrupted
from morl_trl.runs.lock import RunLock
from morl_trl.runs.run import Run
from morl_trl.runs.run_dir import check_writable
from morl_trl.runs.run_log import RunLog
from morl_trl.transforms import compose_policy_env

__all__ = ["train", "run_training", "evaluate_run", "EXIT_NON_FINITE_LOSS", "make_training_env", "make_replay_buffer",
           "make_collector", "make_evaluator"]

#: what ``morl-trl train`` exits with when a non-finite loss stopped the run (after it wrote
#: a checkpoint of the last good state); 2 is bad input, 1 an unexpected error.
EXIT_NON_FINITE_LOSS = 3


def build(cfg: TrainConfig, device: torch.device):
    """``(training env, agent, reference, evaluator)`` of a run: what training and re-evaluation share."""
    spec = run_domain(cfg)
    env = build_training_env(cfg, device)
    agent = build_agent(cfg, env, gamma=run_discount(cfg, spec), device=device)
    reference = load_reference(cfg, spec)
    return env, agent, reference, make_evaluator(cfg, agent, spec, reference)


def _set_threads(cfg: TrainConfig) -> None:
    if cfg.num_threads:
        torch.set_num_threads(cfg.num_threads)


def _seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def train(cfg: TrainConfig | None = None, *, resume: str | Path | None = None, overwrite: bool = False,
          trust_pickle: bool = False) -> dict:
    """Run (or resume) a training run; returns the last evaluation summary
    (:func:`morl_trl.train` returns the run directory, summary, config and the trained policy).

    * A new run refuses a non-empty ``cfg.run_dir`` unless ``overwrite`` (which replaces its
      contents once everything is built); a failed start leaves no run directory behind.
    * ``resume=run_dir`` continues from the newest intact checkpoint (damaged ones are skipped
      with a warning; none intact: ``ValueError``). ``cfg`` (optional) may change only the keys
      of :data:`~morl_trl.recipes.config.RESUME_MAY_CHANGE`; a run that already reached
      ``frames`` is left as it is. Every log is first cut back to the checkpoint's frame; for
      domains that can snapshot their simulator (MO-LavaGrid, MuJoCo) the run continues exactly as an
      uninterrupted one, others restart their episodes.
    * A non-finite loss stops the run: the last good state is checkpointed, log.txt and
      report.md say so, and :class:`NonFiniteLossError` is raised.

    Example:
        >>> from morl_trl.recipes import resolve_config, train
        >>> cfg = resolve_config("envelope", "MOLavaGridDR-v0", quick=True, frames=2_000)  # doctest: +SKIP
        >>> summary = train(cfg)                                                            # doctest: +SKIP
    """
    return run_training(cfg, resume=resume, overwrite=overwrite, trust_pickle=trust_pickle)[0]


def run_training(cfg: TrainConfig | None = None, *, resume: str | Path | None = None,
                 overwrite: bool = False, trust_pickle: bool = False) -> tuple[dict, Agent | None, Path, TrainConfig]:
    """:func:`train`, returning ``(summary, agent, run_dir, config)``: the trained :class:`Agent`
    in memory (``None`` when a resumed run had nothing left to do), where the run was written
    and the config it ran with."""
    if resume is not None and (Path(resume) / "config.json").is_file():
        check_writable(Path(resume))
        lock = RunLock(resume, "training").acquire()  # one writer: a second one is refused, naming this process
    else:
        lock = None
    try:
        return _run_training(cfg, resume, overwrite, trust_pickle, lock)
    finally:
        if lock is not None:
            lock.release()


def _run_training(cfg, resume, overwrite, trust_pickle, lock):
    run = Run.open(cfg, resume=resume, overwrite=overwrite, load_config=TrainConfig.load, resume_config=resume_config)
    run.trust_pickle = trust_pickle
    cfg = run.cfg
    if run.resume_from is not None and checkpoint_format(run.resume_from) < 2 and not trust_pickle:
        load_checkpoint(run.resume_from)  # refused (naming convert-run and --trust-pickle) before anything is built
    if run.done:
        print(f"{run.dir} already reached {run.frames:,} frames (frames = {cfg.frames:,}): nothing to do; "
              f"pass a larger frames (--frames) to extend it", flush=True)
        return {"frames": run.frames, "finished": True}, None, run.dir, cfg
    _set_threads(cfg)
    _seed_everything(cfg.seed)
    device = torch.device(cfg.device)
    spec = run_domain(cfg)

    # 1. the parts (everything is built before the run directory is touched: a failed start writes nothing)
    env, agent, reference, evaluator = build(cfg, device)
    check_buffer_memory(cfg, env, device)
    buffer = make_replay_buffer(cfg, device)
    state = run.restore(buffer, map_location=device)  # (a resumed run: its checkpoint)
    if state is not None:
        agent.load_state_dict(state["agent"])
    exact = state is not None and state["env"]["simulator"] is not None and state["device"] == str(device)
    if state is not None and not exact:
        # the simulators cannot continue their episodes: they restart from a seed derived from
        # the checkpoint (not the run's first seed, which would replay the first episodes);
        # the transforms' generators continue their streams
        env.set_seed(cfg.seed + run.frames)
        for t, saved in zip(transforms_of(env), state["env"]["transforms"]):
            if "generator" in saved:
                t.generator.set_state(saved["generator"])
        load_context_sampler_state(env, state["env"])  # the domain randomization stream continues
    collector = make_collector(cfg, env, agent.explore_policy, device, frames_done=run.frames,
                               frames_to_go=agent.frames_to_collect(run.frames))
    if agent.before_batch():
        reset_collector(collector)

    notes = [] if reference is not None else [no_reference_note(spec)]
    if cfg.frames < cfg.init_random_frames and run.frames < cfg.frames:
        notes.append(f"warning: frames ({cfg.frames:,}) is below init_random_frames ({cfg.init_random_frames:,}): the "
                     f"run takes uniformly random actions only and never learns; raise frames or lower init_random_frames")

    def snapshot() -> dict:  # what a checkpoint holds besides the run's own counters
        return dict(agent=agent.state_dict(), env=env_state(env), **collector_state(collector), device=str(device))

    interrupt = GracefulInterrupt()
    started = state is not None
    try:
        with run.start(spec, reference, notes=notes), interrupt:
            if state is None:  # a new run: the untrained policy, then a checkpoint to resume from
                try:
                    run.evaluate(evaluator)
                    run.checkpoint(snapshot(), buffer)
                except BaseException:
                    run.abort_start()  # (the run it replaces, if any, is put back)
                    raise
                run.started()  # the run it replaces is deleted now
                started = True
            else:
                if exact:
                    load_env_state(env, state["env"])
                    load_collector_state(collector, state, device)
                elif state["device"] != str(device):
                    run.note(f"resumed with fresh episodes: the device changed from {state['device']} to {device}")
                else:
                    run.note(f"resumed with fresh episodes: {spec.name} cannot snapshot its simulator")
                agent.on_frames(run.frames)
                set_rng_state(state["rng"])  # last: nothing above draws from the global generators again

            # 2. the loop. One iteration = one batch: collect, store, update, then evaluate and
            # checkpoint the policy trained on `run.frames` frames. A checkpoint is the state at the
            # end of a batch (after its evaluation), so the batch after it is the same whether the
            # run resumes or not.
            for batch in collector:
                frames = agent.frames_of(batch)  # (PGMORL: one member's frames, as the authors count)
                run.frames += frames
                run.log.training_episodes(run.frames, batch)
                try:
                    losses, updates = agent.learn(batch, buffer, run.frames)  # store + the algorithm's updates
                except NonFiniteLossError as err:
                    run.updates += getattr(err, "updates_done", 0)
                    path = run.stop(str(err), snapshot(), buffer)
                    raise NonFiniteLossError(f"{err}; the last good state is checkpointed in {path}") from None
                agent.on_frames(run.frames)  # the schedules (epsilon, homotopy)
                if agent.before_batch():  # (MORL/D's round robin: the next member starts on a reset env)
                    reset_collector(collector)
                collector.update_policy_weights_()
                run.batch_done(frames, losses, updates, epsilon=agent.epsilon)
                if run.eval_due():
                    run.evaluate(evaluator)
                if run.checkpoint_due():
                    run.checkpoint(snapshot(), buffer)
                if interrupt.requested and run.frames < cfg.frames:  # Ctrl-C: checkpoint, say how to resume
                    path = run.checkpoint(snapshot(), buffer, interrupted=True)
                    msg = (f"interrupted at {run.frames:,} frames; checkpointed in {path.name}; resume with: "
                           f"{_resume_command(cfg, run.dir)}")
                    run.note(msg)
                    run.log.report_stop(msg)
                    raise RunInterrupted(msg)
            run.finish(evaluator, snapshot(), buffer, random_baseline=cfg.eval_random_baseline)
    except RunInterrupted:
        raise
    except OSError as err:  # a full disk, a folder made read-only, ...: stop, keep the last good checkpoint
        if not started:
            raise
        reason = err if isinstance(err, DiskFullError) else disk_error(err, "the run's files")
        msg = (f"stopped: {reason.strerror or reason} at {run.frames:,} frames; the last good checkpoint is "
               f"{_latest_name(run.dir)}; once the cause is fixed, resume with: {_resume_command(cfg, run.dir)}")
        for say in (run.log.note, run.log.report_stop):
            try:
                say(msg)
            except OSError:
                pass  # (the disk may still be full)
        raise type(reason)(reason.errno, msg) from None
    except BaseException as err:
        # a second Ctrl-C (it may surface as another error from where it landed): exit at once
        if started and (isinstance(err, KeyboardInterrupt) or interrupt.count >= 2):
            raise KeyboardInterrupt(f"interrupted; the last checkpoint is {_latest_name(run.dir)}; resume with: "
                                    f"{_resume_command(cfg, run.dir)}") from None
        raise
    finally:
        collector.shutdown()
    return run.summary, agent, run.dir, cfg


def _latest_name(run_dir: Path) -> str:
    found = find_checkpoint(run_dir, only=("state.pt",))[0]
    return found.name if found is not None else "none"


def _resume_command(cfg: TrainConfig, run_dir: Path) -> str:
    return f"morl-trl train {cfg.algo} {cfg.env_id} --resume {run_dir}"


def check_buffer_memory(cfg: TrainConfig, env, device: torch.device) -> None:
    """``ValueError`` before anything is written when ``cfg.buffer_size`` transitions of ``env``
    cannot fit in the memory ``device`` has available (the storage is allocated at the first
    write, so without this check a too large buffer fails only once the run has started)."""
    fake = env.fake_tensordict()
    rows = max(fake.numel(), 1)
    row_bytes = sum(v.element_size() * v.numel() for v in fake.values(include_nested=True, leaves_only=True)
                    if isinstance(v, torch.Tensor)) / rows
    need = row_bytes * cfg.buffer_size
    available = _available_memory(device)
    if available is not None and need > available:
        raise ValueError(f"config key 'buffer_size' (buffer) is {cfg.buffer_size:,}; its transitions need about "
                         f"{need / 2**30:.1f} GiB ({row_bytes:,.0f} bytes each) but {device} has "
                         f"{available / 2**30:.1f} GiB available: lower buffer_size")


def _available_memory(device: torch.device) -> float | None:
    if device.type == "cuda":
        try:
            return float(torch.cuda.mem_get_info(device)[0])
        except (RuntimeError, AssertionError):
            return None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        return None
    return None


def evaluate_run(run_dir: str | Path, *, reference_dir: str | None = None, weights: int | None = None,
                 video: bool = False, video_weight=None, video_format: str = "auto", trust_pickle: bool = False) -> dict:
    """Re-evaluate the latest checkpoint of a run on its domain's evaluation suite.

    With ``video``, also record one episode per evaluation context with ``video_weight``
    (default equal weights) through TorchRL's ``VideoRecorder`` into
    ``<run>/logs/reevaluation/videos/<context>_<frames>.<gif|mp4>`` (see
    :class:`~morl_trl.runs.video.VideoCSVLogger`); the paths are in ``summary["videos"]``.
    """
    run_dir = Path(run_dir)
    if not (run_dir / "config.json").is_file():
        raise ValueError(f"{str(run_dir)!r} is not a run directory (no config.json)")
    cfg = TrainConfig.load(run_dir / "config.json")
    if reference_dir is not None:
        cfg.reference_dir = reference_dir
    if weights is not None:
        cfg.eval_weights = weights
        cfg.validate()  # (--weights named as the config key it sets)
    ckpt, skipped = find_checkpoint(run_dir, only=("state.pt",))  # (evaluating needs no replay buffer)
    for path, why in skipped:
        print(f"warning: skipped damaged checkpoint {path.name}: {why}", flush=True)
    if ckpt is None:
        raise ValueError(f"{str(run_dir)!r} has no intact checkpoint to evaluate")
    state = load_checkpoint(ckpt, map_location=cfg.device, trust_pickle=trust_pickle)  # (refused before any write)
    check_writable(run_dir)
    _set_threads(cfg)
    _seed_everything(cfg.seed)
    device = torch.device(cfg.device)
    spec = run_domain(cfg)
    _, agent, reference, evaluator = build(cfg, device)
    agent.load_state_dict(state["agent"])
    frames = checkpoint_frames(ckpt)
    if video and video_weight is not None:  # (checked before anything is written)
        k = len(spec.objective_names)
        w = torch.as_tensor(video_weight, dtype=torch.float32)
        if w.numel() != k:
            raise ValueError(f"the video weight has {w.numel()} entries; {spec.name} has {k} objectives "
                             f"{list(spec.objective_names)}")
        check_simplex(w, k, name="video weight")
    with RunLock(run_dir, "evaluating"):  # (a training of this run, or another evaluation, is refused)
        result = evaluator.evaluate()  # everything that can fail before a row is written
        log = RunLog(run_dir, cfg, spec, tag="reevaluation")
        log.reference = reference
        try:
            summary = log.evaluation(frames, result)
            log.report(summary, fps=None)
        finally:
            log.close()
        if video:
            summary["videos"] = record_videos(cfg, agent, evaluator.context_names, run_dir, frames,
                                              weight=video_weight, video_format=video_format)
    return summary


def record_videos(cfg: TrainConfig, agent: Agent, contexts, run_dir: Path, frames: int, *, weight=None,
                  video_format: str = "auto") -> list[str]:
    """One clip per context (see :func:`evaluate_run`); returns the files written."""
    from morl_trl.evaluation import record_context_videos
    from morl_trl.runs.video import VideoCSVLogger

    logger = VideoCSVLogger("reevaluation", str(run_dir / "logs"), video_format=video_format)

    def env_factory(context: str):
        env = make_env(context, num_envs=1, seed=cfg.seed, device=agent.device)
        return compose_policy_env(env, history_len=cfg.history_len)

    record_context_videos(agent.eval_policy, env_factory, contexts, logger, weight=weight, step=frames,
                          exploration_type=agent.eval_exploration)
    for path in logger.written:
        print(f"video: {path}", flush=True)
    return list(logger.written)
