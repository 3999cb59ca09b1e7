"""``morl-trl train``: open the run, then run the algorithm's loop; and ``morl-trl evaluate``.

:func:`run_training` opens the :class:`~morl_trl.runs.Run` (:func:`open_run`: a new run, or the
continuation of one), seeds the process and hands the run to the algorithm's loop, found in the one registry
(:data:`~morl_trl.algorithms.registry.REGISTRY`: Envelope's
:func:`~morl_trl.algorithms.envelope.recipe.train_envelope`, the actor-critics'
:func:`~morl_trl.algorithms.actor_critic.recipe.train_actor_critic`, GPI's, PCN's, PGMORL's, MORL/D's), which
reads top to bottom: the env, the agent, the evaluator, the replay buffer, TorchRL's collector, then
per batch its ``on_batch`` (store + the updates due) and ``run.step`` (evaluate and checkpoint when due).

Everything about the run itself (directory, resume, logs, checkpoints, progress bar, report,
Ctrl-C, a clean stop) is :class:`morl_trl.runs.Run` and its session.
"""

from __future__ import annotations

import contextlib
import random
from pathlib import Path

import numpy as np
import torch

from morl_trl.envs import make_env
from morl_trl.envs.trust import check_trusted
from morl_trl.training.agent import Agent
from morl_trl.algorithms.registry import algorithm, build_agent, build_training_env
from morl_trl.recipes.config import TrainConfig, resume_config
from morl_trl.training.parts import (
    load_agent_state,
    load_reference,
    make_collector,
    make_evaluator,
    make_replay_buffer,
    make_training_env,
    run_discount,
    run_domain,
)
from morl_trl.preferences import check_simplex
from morl_trl.runs.checkpoint import checkpoint_format, checkpoint_frames, find_checkpoint, load_checkpoint
from morl_trl.runs.lock import RunLock
from morl_trl.runs.run import Run
from morl_trl.runs.run_dir import check_writable
from morl_trl.runs.run_log import RunLog
from morl_trl.transforms import compose_policy_env

__all__ = ["train", "run_training", "open_run", "evaluate_run", "EXIT_NON_FINITE_LOSS",
           "make_training_env", "make_replay_buffer", "make_collector", "make_evaluator"]

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
          trust_pickle: bool = False, trust_code: bool | list[str] = False) -> dict:
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
    return run_training(cfg, resume=resume, overwrite=overwrite, trust_pickle=trust_pickle, trust_code=trust_code)[0]


def run_training(cfg: TrainConfig | None = None, *, resume: str | Path | None = None,
                 overwrite: bool = False, trust_pickle: bool = False, trust_code: bool | list[str] = False,
                 echo_report: bool = True) -> tuple[dict, Agent | None, Path, TrainConfig]:
    """:func:`train`, returning ``(summary, agent, run_dir, config)``: the trained :class:`Agent`
    in memory (``None`` when a resumed run had nothing left to do), where the run was written
    and the config it ran with. ``echo_report=False``: the end of the run prints the report's
    one-line summary instead of its tables (what ``morl_trl.train`` does)."""
    with open_run(cfg, resume=resume, overwrite=overwrite, trust_pickle=trust_pickle, trust_code=trust_code,
                  echo_report=echo_report) as run:
        if run.done:
            return {"frames": run.frames, "finished": True}, None, run.dir, run.cfg
        summary, agent = algorithm(run.cfg.algo).train(run)  # the algorithm's own loop
        return summary, agent, run.dir, run.cfg


@contextlib.contextmanager
def open_run(cfg: TrainConfig | None = None, *, resume: str | Path | None = None, overwrite: bool = False,
             trust_pickle: bool = False, trust_code: bool | list[str] = False, echo_report: bool = True):
    """The :class:`~morl_trl.runs.Run` of a new run or of the continuation of ``resume``, opened for its
    loop (``algorithm(run.cfg.algo).train(run)``): locked against a second writer while inside, the
    process seeded with ``cfg.seed``. ``run.done``: a resumed run that already reached its frames (said
    on stdout); there is nothing to train. The arguments are :func:`train`'s."""
    if resume is not None and (Path(resume) / "config.json").is_file():
        check_writable(Path(resume))
        lock = RunLock(resume, "training")  # one writer: a second one is refused, naming this process
    else:
        lock = contextlib.nullcontext()
    with lock:
        run = Run.open(cfg, resume=resume, overwrite=overwrite, load_config=TrainConfig.load,
                       resume_config=resume_config)
        if resume is not None:
            check_trusted(run.cfg.domain_modules, trust_code, source=repr(str(Path(resume) / "config.json")))
        run.trust_pickle = trust_pickle
        run.echo_report = echo_report
        cfg = run.cfg
        if run.resume_from is not None and checkpoint_format(run.resume_from) < 2 and not trust_pickle:
            load_checkpoint(run.resume_from)  # refused (naming convert-run and --trust-pickle) before anything is built
        if run.done:
            print(f"{run.dir} already reached {run.frames:,} frames (frames = {cfg.frames:,}): nothing to do; "
                  f"pass a larger frames (--frames) to extend it", flush=True)
        else:
            _set_threads(cfg)
            _seed_everything(cfg.seed)
        yield run


def evaluate_run(run_dir: str | Path, *, reference_dir: str | None = None, weights: int | None = None,
                 video: bool = False, video_weight=None, video_format: str = "auto", trust_pickle: bool = False,
                 trust_code: bool | list[str] = False) -> dict:
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
    check_trusted(cfg.domain_modules, trust_code, source=repr(str(run_dir / "config.json")))
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
    state = load_checkpoint(ckpt, map_location=cfg.device, trust_pickle=trust_pickle,  # (refused before any write)
                            keys={"agent": dict})
    check_writable(run_dir)
    _set_threads(cfg)
    _seed_everything(cfg.seed)
    device = torch.device(cfg.device)
    spec = run_domain(cfg)
    _, agent, reference, evaluator = build(cfg, device)
    load_agent_state(agent, state, ckpt, cfg.algo)
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
            if cfg.eval_random_baseline:  # (the training report's random-policy column, here too)
                log.random_result = evaluator.evaluate("random")
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
