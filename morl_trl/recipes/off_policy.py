"""The off-policy recipe: the paper's experimental loop (§6) for Envelope, CAPQL and MOSAC.

Train a generalist under domain randomization, evaluate it periodically on the evaluation
suite, checkpoint, report. This is the code ``morl-trl train`` runs; read it top to bottom:
environment -> agent -> collector + replay buffer -> updates -> evaluation / logging /
checkpoints. What is algorithm-specific (networks, policies, loss, optimizers) is built by
the algorithm's own module (:mod:`morl_trl.recipes.envelope`,
:mod:`morl_trl.recipes.actor_critic`); what every run needs (run directory, checkpoints,
logs, report) is :mod:`morl_trl.runs`.
"""

from __future__ import annotations

import math
import random
import shutil
import time
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs.utils import ExplorationType

from morl_trl.data import prioritized_sampler
from morl_trl.envs import DomainSpec, domain_of, load_domain_modules, make_env
from morl_trl.evaluation import MultiContextEvaluator
from morl_trl.recipes.agent import Agent, NonFiniteLossError
from morl_trl.recipes.config import TrainConfig, resume_config
from morl_trl.runs.checkpoint import (
    checkpoint_buffer,
    checkpoint_frames,
    find_checkpoint,
    load_checkpoint,
    rng_state,
    save_checkpoint,
    set_rng_state,
)
from morl_trl.runs.env_state import env_state, load_context_sampler_state, load_env_state, transforms_of
from morl_trl.runs.run_log import RunLog, check_logger
from morl_trl.transforms import compose_policy_env, compose_training_env

__all__ = ["train", "run_training", "evaluate_run", "EXIT_NON_FINITE_LOSS", "make_training_env", "make_replay_buffer", "make_collector", "make_evaluator"]


# ---------------------------------------------------------------------- the pieces of a run
def make_training_env(cfg: TrainConfig, device: torch.device):
    """``make_env(cfg.env_id)`` (contexts drawn per sub-env and episode for a DR id) + the
    policy's history + a preference per sub-env (``cfg.preference_distribution``, drawn per
    episode or, with ``preference_resample="step"``, every step) + vector returns."""
    spec = _domain(cfg)
    env = make_env(cfg.env_id, num_envs=cfg.num_envs, device=device, seed=cfg.seed)
    return compose_training_env(env, gamma=_gamma(cfg, spec), history_len=cfg.history_len, preference_seed=cfg.seed + 1,
                                preference_mode=cfg.preference_distribution, preference_resample=cfg.preference_resample)


def make_replay_buffer(cfg: TrainConfig, device: torch.device) -> TensorDictReplayBuffer:
    """A TorchRL buffer on ``device``: prioritized (keyed by ``"td_error"``) when ``cfg.prioritized``."""
    storage = LazyTensorStorage(cfg.buffer_size, device=device)
    if cfg.prioritized:
        sampler = prioritized_sampler(cfg.buffer_size, alpha=cfg.per_alpha, beta=cfg.per_beta, device=device)
        return TensorDictReplayBuffer(storage=storage, sampler=sampler, batch_size=cfg.batch_size,
                                      priority_key="td_error")
    return TensorDictReplayBuffer(storage=storage, batch_size=cfg.batch_size)


def make_collector(cfg: TrainConfig, env, policy, device: torch.device, *, frames_done: int = 0,
                   frames_to_go: int | None = None) -> Collector:
    """TorchRL's ``Collector`` for the frames still to go (``frames_to_go``, default ``cfg.frames -
    frames_done``; uniformly random before ``init_random_frames``)."""
    per_batch = cfg.frames_per_batch
    if frames_to_go is None:
        frames_to_go = cfg.frames - frames_done

    def whole_batches(frames: int) -> int:  # the collector works in whole batches anyway
        return -(-max(frames, 0) // per_batch) * per_batch

    return Collector(
        env,
        policy,
        frames_per_batch=per_batch,
        total_frames=max(whole_batches(frames_to_go), per_batch),
        init_random_frames=whole_batches(cfg.init_random_frames - frames_done),
        device=device,
        exploration_type=ExplorationType.RANDOM,
        auto_register_policy_transforms=False,  # our policies are feed-forward: no InitTracker needed
    )


def make_evaluator(cfg: TrainConfig, agent: Agent, spec: DomainSpec, reference=None) -> MultiContextEvaluator:
    """The multi-context evaluator on the policy stack of training (same env, same history)."""
    device = agent.device

    def env_factory(num_envs: int, seed: int):
        # the training id: the evaluator's contexts, given at every reset, replace the env's draws
        return compose_policy_env(make_env(cfg.env_id, num_envs=num_envs, seed=seed, device=device),
                                  history_len=cfg.history_len)

    return MultiContextEvaluator(
        agent.eval_policy,
        list(cfg.eval_contexts) if cfg.eval_contexts else spec.train_id,
        weights=cfg.eval_weights,
        episodes=cfg.eval_episodes,
        gamma=_gamma(cfg, spec),
        env_factory=env_factory,
        reference=reference,
        ref_point=cfg.ref_point,
        exploration_type=agent.eval_exploration,
        device=device,
        seed=cfg.seed,
    )


def _load_reference(cfg: TrainConfig, spec: DomainSpec):
    """The bounds and specialist fronts for NHGR/EUGR: ``cfg.reference_dir``'s, else the copies
    shipped with the package; ``None`` for a domain without published data."""
    from morl_trl.reporting.reference import PACKAGED_REFERENCE, list_reference_domains, load_domain_reference

    root = cfg.reference_dir or PACKAGED_REFERENCE
    if spec.train_id not in list_reference_domains(root):  # (e.g. the DMC domains: no published data)
        return None
    return load_domain_reference(root, spec.train_id)


def no_reference_note(spec: DomainSpec) -> str:
    """What a run of a domain without reference data says about NHGR."""
    if spec.foreign:
        from morl_trl.reporting.report import foreign_nhgr_note

        return foreign_nhgr_note(spec)
    return (f"NHGR unavailable for {spec.train_id}: no reference data (per-context bounds and specialist fronts) "
            f"exists for this domain, so the evaluation reports hypervolume and EUM only")


def _domain(cfg: TrainConfig) -> DomainSpec:
    """The run's domain, after importing the config's ``domain_modules`` (a user's own domains)."""
    load_domain_modules(cfg.domain_modules)
    return domain_of(cfg.env_id)


def _gamma(cfg: TrainConfig, spec: DomainSpec) -> float:
    """The run's discount: ``cfg.gamma``, else the domain's evaluation discount."""
    return cfg.gamma if cfg.gamma is not None else spec.gamma


def _build(cfg: TrainConfig, spec: DomainSpec, device: torch.device):
    """``(training env, agent, reference, evaluator)`` of a run: what training and re-evaluation share."""
    from morl_trl.recipes import build_agent, build_training_env

    env = build_training_env(cfg, device)
    agent = build_agent(cfg, env, gamma=_gamma(cfg, spec), device=device)
    reference = _load_reference(cfg, spec)
    return env, agent, reference, make_evaluator(cfg, agent, spec, reference)


def _set_threads(cfg: TrainConfig) -> None:
    if cfg.num_threads:
        torch.set_num_threads(cfg.num_threads)


def _seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def _eval_line(summary: dict) -> str:
    agg = summary["aggregate"]
    parts = [f"{m} {agg[m]:.4g}" for m in ("nhgr", "normalized_hypervolume", "hypervolume", "eum") if m in agg]
    return f"[eval @ {summary['frames']:,} frames] mean over contexts: " + ", ".join(parts)


def _default_run_dir(cfg: TrainConfig) -> Path:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"{cfg.algo}_{cfg.env_id}_s{cfg.seed}_{stamp}"


#: what ``morl-trl train`` exits with when a non-finite loss stopped the run (after it wrote
#: a checkpoint of the last good state); 2 is bad input, 1 an unexpected error.
EXIT_NON_FINITE_LOSS = 3


def _resume_point(cfg: TrainConfig | None, run_dir: Path) -> tuple[TrainConfig, Path, list[str]]:
    """The config to continue with and the newest intact checkpoint (with notes on skipped ones)."""
    saved = run_dir / "config.json"
    if not saved.is_file():
        raise ValueError(f"cannot resume: {str(run_dir)!r} has no config.json (not a run directory)")
    saved_cfg = TrainConfig.load(saved)
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
                         f"start it again with --overwrite")
    return cfg, ckpt, notes


def _prepare_run_dir(run_dir: Path, overwrite: bool) -> None:
    if run_dir.exists() and not run_dir.is_dir():
        raise ValueError(f"run directory {str(run_dir)!r} is a file")
    if run_dir.is_dir() and any(run_dir.iterdir()):
        held = sorted(p.name for p in run_dir.iterdir())
        if not overwrite:
            raise ValueError(f"run directory {str(run_dir)!r} is not empty (it holds {held[:5]}): continue it with "
                             f"--resume {run_dir}, replace it with --overwrite, or choose another --run-dir")
        if not (run_dir / "config.json").is_file():  # --overwrite deletes runs only, never any other folder
            raise ValueError(f"--overwrite replaces run directories only; {str(run_dir)!r} has no config.json "
                             f"(it holds {held[:5]}): choose another --run-dir")


def train(cfg: TrainConfig | None = None, *, resume: str | Path | None = None, overwrite: bool = False) -> dict:
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
    return run_training(cfg, resume=resume, overwrite=overwrite)[0]


def run_training(cfg: TrainConfig | None = None, *, resume: str | Path | None = None,
                 overwrite: bool = False) -> tuple[dict, Agent | None, Path, TrainConfig]:
    """:func:`train`, returning ``(summary, agent, run_dir, config)``: the trained :class:`Agent`
    in memory (``None`` when a resumed run had nothing left to do), where the run was written
    and the config it ran with."""
    notes: list[str] = []
    if resume is not None:
        if overwrite:
            raise ValueError("resume continues a run and overwrite replaces it: choose one")
        run_dir = Path(resume)
        cfg, ckpt, notes = _resume_point(cfg, run_dir)
        done = checkpoint_frames(ckpt)
        if done >= cfg.frames:
            msg = (f"{run_dir} already reached {done:,} frames (frames = {cfg.frames:,}): nothing to do; "
                   f"pass a larger --frames to extend it")
            print(msg, flush=True)
            return {"frames": done, "finished": True}, None, run_dir, cfg
    else:
        if cfg is None:
            raise ValueError("train() needs a config (or resume=<run dir>)")
        ckpt = None
        cfg.validate()
        run_dir = Path(cfg.run_dir) if cfg.run_dir else _default_run_dir(cfg)
        _prepare_run_dir(run_dir, overwrite)
    check_logger(cfg.logger)
    _set_threads(cfg)
    _seed_everything(cfg.seed)
    device = torch.device(cfg.device)
    spec = _domain(cfg)

    # everything is built before the run directory is touched: a failed start writes nothing
    env, agent, reference, evaluator = _build(cfg, spec, device)
    buffer = make_replay_buffer(cfg, device)

    frames, updates, next_eval, next_ckpt, last_eval = 0, 0, 0, cfg.checkpoint_interval, -1
    state = None
    if ckpt is not None:
        state = load_checkpoint(ckpt, buffer, map_location=device)
        agent.load_state_dict(state["agent"])
        frames, updates, last_eval = state["frames"], state["updates"], state["last_eval"]
        next_eval, next_ckpt = state["next_eval"], state["next_ckpt"]
    exact = (state is not None and state["env"]["simulator"] is not None and state["device"] == str(device))
    if state is not None and not exact:
        # the simulators cannot continue their episodes: they restart from a seed derived from
        # the checkpoint (not the run's first seed, which would replay the first episodes);
        # the transforms' generators continue their streams
        env.set_seed(cfg.seed + frames)
        for t, saved in zip(transforms_of(env), state["env"]["transforms"]):
            if "generator" in saved:
                t.generator.set_state(saved["generator"])
        load_context_sampler_state(env, state["env"])  # the domain randomization stream continues
    collector = make_collector(cfg, env, agent.explore_policy, device, frames_done=frames,
                               frames_to_go=agent.frames_to_collect(frames))

    created = not run_dir.exists()
    try:
        if resume is None:
            if overwrite and run_dir.exists():
                shutil.rmtree(run_dir)
            run_dir.mkdir(parents=True, exist_ok=True)
            cfg.run_dir = str(run_dir)
            cfg.save(run_dir / "config.json")
        log = RunLog(run_dir, cfg, spec)
    except BaseException:
        if created:
            shutil.rmtree(run_dir, ignore_errors=True)
        raise
    log.reference = reference
    if reference is None:
        notes.append(no_reference_note(spec))
    if cfg.frames < cfg.init_random_frames and frames < cfg.frames:
        notes.append(f"warning: frames ({cfg.frames:,}) is below init_random_frames ({cfg.init_random_frames:,}): "
                     f"the run takes uniformly random actions only and never learns; raise frames or lower "
                     f"init_random_frames")
    log.note(_start_line(cfg, frames, resume is not None))  # (also makes log.txt exist on every run)
    for note in notes:
        log.note(note)
    if resume is not None and cfg.to_dict() != TrainConfig.load(run_dir / "config.json").to_dict():
        cfg.save(run_dir / "config.json")  # what the run continues with (e.g. a larger frames)
    if state is not None:
        cut = log.truncate(frames)
        log.note(f"resumed from {ckpt.name} at {frames} frames (logs cut back to it: {cut} rows/files removed)")
        if checkpoint_buffer(ckpt) == "pruned":
            log.note(f"warning: {ckpt.name} holds no replay buffer (only the newest checkpoint keeps it): "
                     f"the run continues with an empty replay buffer")
        if exact:
            load_env_state(env, state["env"])
            collector._carrier = state["carrier"].to(device)
            collector._traj_pool.load_state_dict(state["traj_pool"])
        elif state["device"] != str(device):
            log.note(f"resumed with fresh episodes: the device changed from {state['device']} to {device}")
        else:
            log.note(f"resumed with fresh episodes: {spec.name} cannot snapshot its simulator")
        agent.on_frames(frames)
        set_rng_state(state["rng"])  # last: nothing above draws from the global generators again

    def checkpoint(tag_frames: int, **flags) -> Path:
        state = dict(
            agent=agent.state_dict(), env=env_state(env), carrier=collector._carrier.clone(),
            traj_pool=collector._traj_pool.state_dict(), frames=frames, updates=updates, next_eval=next_eval,
            next_ckpt=next_ckpt, last_eval=last_eval, rng=rng_state(), config=cfg.to_dict(), device=str(device),
            **flags,
        )
        return save_checkpoint(run_dir, tag_frames, state, buffer if len(buffer) else None,  # (empty at 0)
                               keep=cfg.keep_checkpoints)

    summary: dict = {}

    eval_seconds: list[float] = []

    def evaluate() -> None:
        nonlocal summary, last_eval, next_eval
        t0 = time.perf_counter()
        summary = log.evaluation(frames, evaluator.evaluate())
        eval_seconds.append(time.perf_counter() - t0)
        last_eval = frames
        while next_eval <= frames:
            next_eval += cfg.eval_interval
        tqdm.write(_eval_line(summary))

    bar = tqdm(total=cfg.frames, initial=frames, unit="frame", disable=not cfg.progress, dynamic_ncols=True)
    t_start, frames_start = time.perf_counter(), frames
    eta = _DurationEstimate(cfg, frames)

    def fps() -> float:
        return (frames - frames_start) / max(time.perf_counter() - t_start, 1e-9)

    try:
        if state is None:  # a new run: the untrained policy, then a checkpoint to resume from
            evaluate()
            checkpoint(frames)
        # One iteration = one batch: collect, store, update, then evaluate and checkpoint the
        # policy trained on `frames` frames. A checkpoint is the state at the end of a batch
        # (after its evaluation), so the batch after it is the same whether the run resumes or not.
        for batch in collector:
            frames += agent.frames_of(batch)  # (PGMORL: one member's frames, as the authors count)
            log.training_episodes(frames, batch)
            try:
                losses, done_updates = agent.learn(batch, buffer, frames)  # store + update (the algorithm's)
            except NonFiniteLossError as err:
                updates += getattr(err, "updates_done", 0)
                path = _stop(log, summary, fps(), f"{err} (at {frames:,} frames, after {updates} updates)",
                             lambda: checkpoint(frames, stopped=str(err)))
                raise NonFiniteLossError(f"{err}; the last good state is checkpointed in {path}") from None
            updates += done_updates
            if losses is not None and (updates % 50 == 0 or done_updates > 1):
                log.losses(frames, losses, frames_per_second=fps(), epsilon=_epsilon(agent))
            agent.on_frames(frames)
            collector.update_policy_weights_()
            bar.update(agent.frames_of(batch))
            line = eta.update(frames, eval_seconds, next_eval)
            if line is not None:
                log.note(line)
            last_nhgr = summary.get("nhgr_mean", float("nan"))  # (the frame rate is tqdm's own: frame/s)
            bar.set_postfix(nhgr=f"{last_nhgr:.3f}" if not math.isnan(last_nhgr) else "-")
            if frames >= next_eval:
                evaluate()
            if frames >= next_ckpt and frames < cfg.frames:  # (the end of the run has its own)
                while next_ckpt <= frames:
                    next_ckpt += cfg.checkpoint_interval
                checkpoint(frames)
        if last_eval != frames:
            evaluate()
        if cfg.eval_random_baseline:
            log.random_result = evaluator.evaluate("random")
        if log.last_result is not None:
            log.report(summary, fps=fps())
        checkpoint(frames, finished=True)
    finally:
        bar.close()
        collector.shutdown()
        log.close()
    return summary, agent, run_dir, cfg


def _start_line(cfg: TrainConfig, frames: int, resumed: bool) -> str:
    """The first line of a run: what it will do and how much (the duration follows once measured)."""
    evals = max(0, (cfg.frames - frames) // max(cfg.eval_interval, 1)) + 1
    what = "resume" if resumed else "start"
    return (f"{what}: {cfg.algo} on {cfg.env_id}, seed {cfg.seed}, {cfg.device}: frame budget {cfg.frames:,} "
            f"({cfg.frames - frames:,} to go, {cfg.init_random_frames:,} of them random before learning), about "
            f"{evals} evaluations of {cfg.eval_weights} weights; the estimated duration follows once the "
            f"learning speed is measured")


class _DurationEstimate:
    """Measures the learning speed over the first batches after the random warm-up and says once,
    in ``log.txt``, how long the rest of the run should take (tqdm's bar keeps an ETA after it)."""

    def __init__(self, cfg: TrainConfig, frames: int) -> None:
        self.cfg = cfg
        self.start: tuple[int, float] | None = None
        self.done = frames >= cfg.frames

    def update(self, frames: int, eval_seconds: list[float], next_eval: int) -> str | None:
        if self.done:
            return None
        now = time.perf_counter()
        if self.start is None:
            if frames > self.cfg.init_random_frames:
                self.start = (frames, now)
            return None
        seen, dt = frames - self.start[0], now - self.start[1]
        if frames >= self.cfg.frames:  # finished before a stable measurement: nothing to predict
            self.done = True
            return None
        if dt < 15.0 or seen <= 0:  # some seconds of learning: a stable rate
            return None
        self.done = True
        rate = seen / max(dt, 1e-9)
        left = max(self.cfg.frames - frames, 0)
        evals = (max(self.cfg.frames - next_eval, 0) // max(self.cfg.eval_interval, 1) + 1) if left else 0
        per_eval = float(np.mean(eval_seconds)) if eval_seconds else 0.0
        seconds = left / max(rate, 1e-9) + evals * per_eval
        return (f"estimated duration: {_hms(seconds)} more ({left:,} frames at {rate:,.0f} frames/s learning, "
                f"measured over {seen:,} frames, + {evals} evaluations of ~{per_eval:.0f} s)")


def _hms(seconds: float) -> str:
    seconds = int(round(seconds))
    h, rem = divmod(seconds, 3600)
    m, s = divmod(rem, 60)
    return f"{h} h {m:02d} min" if h else (f"{m} min {s:02d} s" if m else f"{s} s")


def _epsilon(agent) -> float | None:
    """The ε of an ε-greedy exploration module in the agent's exploration policy, if any."""
    from torchrl.modules import EGreedyModule

    policy = getattr(agent, "explore_policy", None)
    if policy is None or not hasattr(policy, "modules"):
        return None
    for m in policy.modules():
        if isinstance(m, EGreedyModule):
            return float(m.eps)
    return None


def _stop(log: RunLog, summary: dict, fps: float, reason: str, write_checkpoint) -> Path:
    """Stop a run cleanly: checkpoint the last good state, say so in log.txt and report.md."""
    path = write_checkpoint()
    log.note(f"stopped: {reason}; the last good state is checkpointed in {path}")
    if log.last_result is not None:
        log.report(summary, fps=fps)
    log.report_stop(f"stopped: {reason}; the last good state is checkpointed in {path.name}")
    return path


def evaluate_run(run_dir: str | Path, *, reference_dir: str | None = None, weights: int | None = None,
                 video: bool = False, video_weight=None, video_format: str = "auto") -> dict:
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
    ckpt, skipped = find_checkpoint(run_dir)
    for path, why in skipped:
        print(f"warning: skipped damaged checkpoint {path.name}: {why}", flush=True)
    if ckpt is None:
        raise ValueError(f"{str(run_dir)!r} has no intact checkpoint to evaluate")
    _set_threads(cfg)
    _seed_everything(cfg.seed)
    device = torch.device(cfg.device)
    spec = _domain(cfg)
    _, agent, reference, evaluator = _build(cfg, spec, device)
    agent.load_state_dict(load_checkpoint(ckpt, map_location=device)["agent"])
    log = RunLog(run_dir, cfg, spec, tag="reevaluation")
    log.reference = reference
    frames = checkpoint_frames(ckpt)
    summary = log.evaluation(frames, evaluator.evaluate())
    log.report(summary, fps=None)
    log.close()
    if video:
        summary["videos"] = record_videos(cfg, agent, evaluator.context_names, run_dir, frames, weight=video_weight,
                                          video_format=video_format)
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
