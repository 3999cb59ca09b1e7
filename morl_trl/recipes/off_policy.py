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
import time
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs.utils import ExplorationType

from morl_trl.data import prioritized_sampler
from morl_trl.envs import DomainSpec, domain_of, make_env
from morl_trl.evaluation import MultiContextEvaluator
from morl_trl.recipes.agent import Agent, NonFiniteLossError
from morl_trl.recipes.config import TrainConfig
from morl_trl.runs.checkpoint import latest_checkpoint, load_checkpoint, rng_state, save_checkpoint, set_rng_state
from morl_trl.runs.run_log import RunLog
from morl_trl.transforms import compose_policy_env, compose_training_env

__all__ = ["train", "evaluate_run", "make_training_env", "make_replay_buffer", "make_collector", "make_evaluator"]


# ---------------------------------------------------------------------- the pieces of a run
def make_training_env(cfg: TrainConfig, device: torch.device):
    """``make_env(cfg.env_id)`` (contexts drawn per sub-env and episode for a DR id) + the
    policy's history + a Dirichlet preference per sub-env and episode + vector returns."""
    spec = domain_of(cfg.env_id)
    env = make_env(cfg.env_id, num_envs=cfg.num_envs, device=device, seed=cfg.seed)
    gamma = cfg.gamma if cfg.gamma is not None else spec.gamma
    return compose_training_env(env, gamma=gamma, history_len=cfg.history_len, preference_seed=cfg.seed + 1,
                                preference_mode=cfg.preference_distribution, preference_resample=cfg.preference_resample)


def make_replay_buffer(cfg: TrainConfig, device: torch.device) -> TensorDictReplayBuffer:
    """A TorchRL buffer on ``device``: prioritized (keyed by ``"td_error"``) when ``cfg.prioritized``."""
    storage = LazyTensorStorage(cfg.buffer_size, device=device)
    if cfg.prioritized:
        sampler = prioritized_sampler(cfg.buffer_size, alpha=cfg.per_alpha, beta=cfg.per_beta, device=device)
        return TensorDictReplayBuffer(storage=storage, sampler=sampler, batch_size=cfg.batch_size,
                                      priority_key="td_error")
    return TensorDictReplayBuffer(storage=storage, batch_size=cfg.batch_size)


def make_collector(cfg: TrainConfig, env, policy, device: torch.device, *, frames_done: int = 0) -> Collector:
    """TorchRL's ``Collector`` for the frames still to go (uniformly random before ``init_random_frames``)."""
    per_batch = cfg.frames_per_batch

    def whole_batches(frames: int) -> int:  # the collector works in whole batches anyway
        return -(-max(frames, 0) // per_batch) * per_batch

    return Collector(
        env,
        policy,
        frames_per_batch=per_batch,
        total_frames=max(whole_batches(cfg.frames - frames_done), per_batch),
        init_random_frames=whole_batches(cfg.init_random_frames - frames_done),
        device=device,
        exploration_type=ExplorationType.RANDOM,
        auto_register_policy_transforms=False,  # our policies are feed-forward: no InitTracker needed
    )


def make_evaluator(cfg: TrainConfig, agent: Agent, spec: DomainSpec, reference=None) -> MultiContextEvaluator:
    """The multi-context evaluator on the policy stack of training (same env, same history)."""
    device = agent.device

    def env_factory(num_envs: int, seed: int):
        return compose_policy_env(make_env(spec.evaluation_ids[0], num_envs=num_envs, seed=seed, device=device),
                                  history_len=cfg.history_len)

    return MultiContextEvaluator(
        agent.eval_policy,
        list(cfg.eval_contexts) if cfg.eval_contexts else spec.train_id,
        weights=cfg.eval_weights,
        episodes=cfg.eval_episodes,
        gamma=cfg.gamma if cfg.gamma is not None else spec.gamma,
        env_factory=env_factory,
        reference=reference,
        exploration_type=agent.eval_exploration,
        device=device,
        seed=cfg.seed,
    )


def _load_reference(cfg: TrainConfig, spec: DomainSpec):
    if not cfg.reference_dir:
        return None
    from morl_trl.reporting.reference import load_domain_reference

    return load_domain_reference(cfg.reference_dir, spec.train_id)


def _set_threads(cfg: TrainConfig) -> None:
    if cfg.num_threads:
        torch.set_num_threads(cfg.num_threads)


def _seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def _transform_generators(env) -> dict[int, torch.Generator]:
    """The random generators of the env's transforms (domain randomization, preferences), by position."""
    transforms = list(env.transform) if hasattr(env.transform, "__iter__") else [env.transform]
    return {i: t.generator for i, t in enumerate(transforms) if isinstance(getattr(t, "generator", None), torch.Generator)}


def _eval_line(summary: dict) -> str:
    agg = summary["aggregate"]
    parts = [f"{m} {agg[m]:.4g}" for m in ("nhgr", "normalized_hypervolume", "hypervolume", "eum") if m in agg]
    return f"[eval @ {summary['frames']:,} frames] mean over contexts: " + ", ".join(parts)


def _default_run_dir(cfg: TrainConfig) -> Path:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"{cfg.algo}_{cfg.env_id}_s{cfg.seed}_{stamp}"


def train(cfg: TrainConfig, *, resume: str | Path | None = None) -> dict:
    """Run (or resume) a training run; returns the last evaluation summary.

    Example:
        >>> from morl_trl.recipes import resolve_config, train
        >>> cfg = resolve_config("envelope", "MOLavaGridDR-v0", quick=True, frames=2_000)  # doctest: +SKIP
        >>> summary = train(cfg)                                                            # doctest: +SKIP
    """
    if resume is not None:
        run_dir = Path(resume)
        saved = run_dir / "config.json"
        if not saved.is_file():
            raise ValueError(f"cannot resume: {str(run_dir)!r} has no config.json (not a run directory)")
        cfg = TrainConfig.load(saved)
    else:
        run_dir = Path(cfg.run_dir) if cfg.run_dir else _default_run_dir(cfg)
        run_dir.mkdir(parents=True, exist_ok=True)
        cfg.run_dir = str(run_dir)
        cfg.save(run_dir / "config.json")
    _set_threads(cfg)
    _seed_everything(cfg.seed)
    device = torch.device(cfg.device)
    spec = domain_of(cfg.env_id)
    gamma = cfg.gamma if cfg.gamma is not None else spec.gamma

    from morl_trl.recipes import build_agent

    env = make_training_env(cfg, device)
    agent = build_agent(cfg, env, gamma=gamma, device=device)
    buffer = make_replay_buffer(cfg, device)
    log = RunLog(run_dir, cfg, spec)
    log.reference = _load_reference(cfg, spec)
    evaluator = make_evaluator(cfg, agent, spec, log.reference)

    frames, updates, next_eval, next_ckpt = 0, 0, 0, cfg.checkpoint_interval
    ckpt = latest_checkpoint(run_dir) if resume is not None else None
    if ckpt is not None:
        state = load_checkpoint(ckpt, buffer)
        agent.load_state_dict(state["agent"])
        env.load_state_dict(state["env_transforms"])
        frames, updates = state["frames"], state["updates"]
        next_eval, next_ckpt = state["next_eval"], state["next_ckpt"]
        # episodes in flight are lost; the simulators restart from a seed derived from the
        # checkpoint (not the run's first seed, which would replay the first episodes)
        env.set_seed(cfg.seed + frames)
        for i, gen in _transform_generators(env).items():
            gen.set_state(state["transform_generators"][i])
        set_rng_state(state["rng"])
        agent.on_frames(frames)
        log.note(f"resumed from {ckpt.name} at {frames} frames")

    def checkpoint(tag_frames: int) -> None:
        state = dict(
            agent=agent.state_dict(), env_transforms=env.state_dict(),
            transform_generators={i: g.get_state() for i, g in _transform_generators(env).items()},
            frames=frames, updates=updates,
            next_eval=next_eval, next_ckpt=next_ckpt, rng=rng_state(), config=cfg.to_dict(),
        )
        save_checkpoint(run_dir, tag_frames, state, buffer)

    collector = make_collector(cfg, env, agent.explore_policy, device, frames_done=frames)
    updates_per_batch = cfg.updates_per_batch or cfg.frames_per_batch
    bar = tqdm(total=cfg.frames, initial=frames, unit="frame", disable=not cfg.progress, dynamic_ncols=True)
    t_start, frames_start, last_nhgr = time.perf_counter(), frames, float("nan")
    summary: dict = {}
    try:
        for batch in collector:
            if frames >= next_eval:  # evaluate the policy the batch was collected with (frame 0 included)
                summary = log.evaluation(frames, evaluator.evaluate())
                last_nhgr = summary.get("nhgr_mean", float("nan"))
                next_eval += cfg.eval_interval
                tqdm.write(_eval_line(summary))
            buffer.extend(batch.reshape(-1))
            frames += batch.numel()
            log.training_episodes(frames, batch)
            if frames >= cfg.init_random_frames:
                for _ in range(updates_per_batch):
                    try:
                        losses = agent.update(buffer)
                    except NonFiniteLossError as err:
                        log.note(f"stopped: {err}")
                        raise
                    updates += 1
                if updates % 50 == 0 or updates_per_batch > 1:
                    log.losses(frames, losses)
            agent.on_frames(frames)
            collector.update_policy_weights_()
            fps = (frames - frames_start) / max(time.perf_counter() - t_start, 1e-9)
            bar.update(batch.numel())
            bar.set_postfix(fps=f"{fps:,.0f}", nhgr=f"{last_nhgr:.3f}" if not math.isnan(last_nhgr) else "-")
            if frames >= next_ckpt:
                next_ckpt += cfg.checkpoint_interval
                checkpoint(frames)
        summary = log.evaluation(frames, evaluator.evaluate())
        checkpoint(frames)
        if cfg.eval_random_baseline:
            log.random_result = evaluator.evaluate("random")
        log.report(summary, fps=(frames - frames_start) / max(time.perf_counter() - t_start, 1e-9))
    finally:
        bar.close()
        collector.shutdown()
        log.close()
    return summary


def evaluate_run(run_dir: str | Path, *, reference_dir: str | None = None, weights: int | None = None) -> dict:
    """Re-evaluate the latest checkpoint of a run on its domain's evaluation suite."""
    run_dir = Path(run_dir)
    if not (run_dir / "config.json").is_file():
        raise ValueError(f"{str(run_dir)!r} is not a run directory (no config.json)")
    cfg = TrainConfig.load(run_dir / "config.json")
    if reference_dir is not None:
        cfg.reference_dir = reference_dir
    if weights is not None:
        cfg.eval_weights = weights
    ckpt = latest_checkpoint(run_dir)
    if ckpt is None:
        raise ValueError(f"{str(run_dir)!r} has no checkpoint to evaluate")
    _set_threads(cfg)
    _seed_everything(cfg.seed)
    device = torch.device(cfg.device)
    spec = domain_of(cfg.env_id)
    from morl_trl.recipes import build_agent

    env = make_training_env(cfg, device)
    agent = build_agent(cfg, env, gamma=cfg.gamma if cfg.gamma is not None else spec.gamma, device=device)
    agent.load_state_dict(load_checkpoint(ckpt)["agent"])
    log = RunLog(run_dir, cfg, spec, tag="reevaluation")
    log.reference = _load_reference(cfg, spec)
    frames = int(ckpt.name.split("_")[-1])
    summary = log.evaluation(frames, make_evaluator(cfg, agent, spec, log.reference).evaluate())
    log.report(summary, fps=None)
    log.close()
    return summary
