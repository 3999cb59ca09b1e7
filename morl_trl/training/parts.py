"""The parts every recipe builds from its config: the training env, the replay buffer, TorchRL's
collector, the multi-context evaluator, the run's discount and reference data.

Example:
    >>> from morl_trl.recipes import resolve_config
    >>> cfg = resolve_config("envelope", "MOLavaGridDR-v0", num_envs=2)
    >>> run_discount(cfg, domain_of(cfg.env_id))
    0.995
    >>> make_training_env(cfg, torch.device("cpu")).batch_size
    torch.Size([2])
"""

from __future__ import annotations

from pathlib import Path

import torch
from tensordict import TensorDict, TensorDictBase, is_tensor_collection
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs.utils import ExplorationType, set_exploration_type

from morl_trl._torchrl_compat import collector_state, tensordict_entries
from morl_trl.data import RunningMaxPrioritizedSampler, prioritized_sampler
from morl_trl.data.lean import LeanTensorDictReplayBuffer, leaf_pairs, tensordict_layout
from morl_trl.runs.checkpoint import DamagedCheckpointError
from morl_trl.runs.plain import first_line
from morl_trl.envs import DomainSpec, domain_of, load_domain_modules, make_env
from morl_trl.evaluation import MultiContextEvaluator
from morl_trl.runs.env_state import env_state
from morl_trl.transforms import compose_policy_env, compose_training_env

__all__ = ["load_agent_state", "run_domain", "run_discount", "make_training_env", "make_replay_buffer", "make_collector", "make_evaluator",
           "RecipeCollector",
           "evaluation_contexts", "policy_env_factory", "load_reference", "no_reference_note", "start_notes",
           "check_buffer_memory", "checkpoint_snapshot"]


def run_domain(cfg) -> DomainSpec:
    """The run's domain, after importing the config's ``domain_modules`` (a user's own domains)."""
    load_domain_modules(cfg.domain_modules)
    return domain_of(cfg.env_id)


def run_discount(cfg, spec: DomainSpec) -> float:
    """The run's discount: ``cfg.gamma``, else the domain's evaluation discount."""
    return cfg.gamma if cfg.gamma is not None else spec.gamma


def make_training_env(cfg, device: torch.device):
    """``make_env(cfg.env_id)`` (contexts drawn per sub-env and episode for a DR id) + the
    policy's history + a preference per sub-env (``cfg.preference_distribution``, drawn per
    episode or, with ``preference_resample="step"``, every step) + vector returns."""
    spec = run_domain(cfg)
    env = make_env(cfg.env_id, num_envs=cfg.num_envs, device=device, seed=cfg.seed)
    return compose_training_env(env, gamma=run_discount(cfg, spec), history_len=cfg.history_len,
                                # (GPI has no training preference of its own: its support loop sets w)
                                preference_seed=cfg.seed + 1,
                                preference_mode=getattr(cfg, "preference_distribution", "dirichlet"),
                                preference_resample=getattr(cfg, "preference_resample", "episode"))


def make_replay_buffer(cfg, device: torch.device) -> TensorDictReplayBuffer | None:
    """A TorchRL buffer on ``device`` (:class:`~morl_trl.data.lean.LeanTensorDictReplayBuffer`: TorchRL's
    ``TensorDictReplayBuffer`` with short sampling and priority paths): prioritized (keyed by
    ``"td_error"``) when ``cfg.prioritized``; ``None`` for an algorithm that keeps no transition buffer
    (no ``buffer_size`` key: PCN keeps whole episodes, PGMORL its on-policy batch)."""
    if getattr(cfg, "buffer_size", None) is None:
        return None
    storage = LazyTensorStorage(cfg.buffer_size, device=device)
    if cfg.prioritized and getattr(cfg, "per_running_max", False):  # MORL-Baselines' rule (the authors' Envelope)
        sampler = RunningMaxPrioritizedSampler(cfg.buffer_size, alpha=cfg.per_alpha, beta=cfg.per_beta, device=device)
    elif cfg.prioritized:
        sampler = prioritized_sampler(cfg.buffer_size, alpha=cfg.per_alpha, beta=cfg.per_beta, device=device)
    if cfg.prioritized:
        return LeanTensorDictReplayBuffer(storage=storage, sampler=sampler, batch_size=cfg.batch_size,
                                          priority_key="td_error")
    return LeanTensorDictReplayBuffer(storage=storage, batch_size=cfg.batch_size)


def _may_hold_private_keys(td) -> bool:
    """Whether ``td`` is anything but a plain nested :class:`~tensordict.TensorDict` free of entries whose
    name (at any depth) starts with ``"_"`` -- what TorchRL's collector excludes from its batches."""
    if type(td) is not TensorDict:
        return True
    for name, value in tensordict_entries(td).items():
        if name.startswith("_"):
            return True
        if not isinstance(value, torch.Tensor) or is_tensor_collection(value):
            if _may_hold_private_keys(value):
                return True
    return False


class RecipeCollector(Collector):
    """TorchRL's :class:`~torchrl.collectors.Collector` whose ``update_policy_weights_()`` skips the
    copy when the collector acts with the training policy itself (same module, hence same
    parameters: nothing to sync).

    TorchRL copies the source policy's weights onto the collector's policy on every call, even
    when both are one module: a ``TensorDict.from_module`` of each and an ``update_`` of every
    parameter onto itself, which in a one-env run (one frame per batch) cost as much as a
    sixth of collecting the frame. A collector that acts with a copy (another device) syncs
    as before, as does a call that passes weights.

    Example:
        >>> from morl_trl.recipes import build_agent, build_training_env, resolve_config
        >>> cfg = resolve_config("envelope", "deep-sea-treasure-v0", hidden=[8], frames=4, init_random_frames=0)
        >>> env = build_training_env(cfg, torch.device("cpu"))
        >>> agent = build_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
        >>> collector = make_collector(cfg, env, agent.explore_policy, torch.device("cpu"))
        >>> collector.shares_policy_weights, [batch.numel() for batch in collector]
        (True, [1, 1, 1, 1])
    """

    @property
    def shares_policy_weights(self) -> bool:
        """Whether the collector acts with the source policy module itself (``update_policy_weights_()`` has nothing to copy)."""
        target = getattr(self, "_policy_w_state_dict", None)
        return target is not None and target is getattr(self, "_orig_policy", None)

    def update_policy_weights_(self, policy_or_weights=None, **kwargs) -> None:
        if policy_or_weights is None and not kwargs and self.shares_policy_weights:
            self.increment_version()  # (what TorchRL's call does besides the copy)
            return
        super().update_policy_weights_(policy_or_weights, **kwargs)

    def _postproc(self, tensordict_out):
        """TorchRL's post-processing; a plain batch with no private (``"_"``-prefixed) entry, when neither
        trajectory splitting nor a ``postproc`` is set, is returned as is without listing its keys
        (TorchRL's exclusion of nothing: its key walk cost a tenth of a one-env frame)."""
        if (self.split_trajs or self.postproc is not None or not self._exclude_private_keys
                or _may_hold_private_keys(tensordict_out)):
            return super()._postproc(tensordict_out)
        return tensordict_out

    def _one_step_applies(self) -> bool:
        """Whether :meth:`rollout` may take the one-step path: one env step per batch, the carrier and
        the batch on the env's device, none of TorchRL's hooks, casts, trajectory ids or direct writes."""
        return (self.frames_per_batch == 1 and self._use_buffers and self.pre_collect_hook is None
                and not self.reset_at_each_iter and not self.track_traj_ids and self.replay_buffer is None
                and self.interruptor is None and not self._compact_next_keys and not self._truncated_keys
                and not self.compiled_policy and not self.cudagraphed_policy and not self._cast_to_policy_device
                and not self._cast_to_env_device and self._carrier.device is not None
                and self.storing_device == self._carrier.device and self.policy_device in (None, self.env_device))

    @torch.no_grad()
    def rollout(self) -> TensorDictBase:
        """TorchRL's rollout; for a batch of one env step (a one-env run collects one frame a batch) the
        same calls in the same order -- the policy (or ``rand_action`` during ``init_random_frames``),
        ``step_and_maybe_reset`` -- with the step written into the batch leaf by leaf instead of through
        ``torch.stack(..., out=batch)`` (the same values; the stack's TensorDict plumbing cost about a
        tenth of a one-env frame)."""
        if not self._one_step_applies():
            return super().rollout()
        carrier = self._carrier
        with set_exploration_type(self.exploration_type):
            if self._should_use_random_frames():
                self.env.rand_action(carrier)
            else:
                policy_output = self._wrapped_policy(carrier)
                if carrier is not policy_output:
                    carrier.update(policy_output, keys_to_update=self._policy_output_keys)
            env_output, env_next_output = self.env.step_and_maybe_reset(carrier)
        if carrier is not env_output:
            carrier.set("next", env_output.get("next"))
        if not self.no_cuda_sync:
            self._sync_storage()
        result = self._final_rollout
        layout = self.__dict__.get("_batch_layout")
        if layout is None or layout[0] is not result:
            layout = self._batch_layout = (result, tensordict_layout(result))
        time_dim = result.ndim - 1
        pairs = None if layout[1] is None else leaf_pairs(result, layout[1], carrier, time_dim,
                                                           target_dims=time_dim + 1, skip_index=False)
        if pairs is not None and all(dst.shape[:time_dim + 1] == result.batch_size
                                     and src.shape[:time_dim] == result.batch_size[:time_dim] for dst, src in pairs):
            for dst, src in pairs:
                dst.copy_(src.unsqueeze(time_dim))
        else:  # (TorchRL's stack, which raises or fills as it does)
            try:
                result = torch.stack([carrier], time_dim, out=result)
            except RuntimeError:
                with result.unlock_():
                    result = torch.stack([carrier], time_dim, out=result)
        self._carrier = env_next_output
        if self._carrier_has_no_device:
            self._carrier.clear_device_()
        return self._maybe_set_truncated(result)


def make_collector(cfg, env, policy, device: torch.device, *, frames_done: int = 0,
                   frames_to_go: int | None = None, track_traj_ids: bool = False,
                   return_same_td: bool = False) -> Collector:
    """TorchRL's ``Collector`` for the frames still to go (``frames_to_go``, default ``cfg.frames -
    frames_done``; uniformly random before ``init_random_frames``). ``track_traj_ids``: write TorchRL's
    ``("collector", "traj_ids")`` (no recipe reads them: off, one bookkeeping step less per frame).
    ``return_same_td``: TorchRL's option, every batch is the collector's own buffer, overwritten by the
    next one (no copy of the whole batch per iteration, which in a one-env run is a copy per frame):
    for a loop that is done with a batch (stored, logged) before it asks for the next."""
    if frames_to_go is None:
        frames_to_go = cfg.frames - frames_done
    per_batch = cfg.frames_per_batch

    def whole_batches(frames: int) -> int:  # the collector works in whole batches anyway
        return -(-max(frames, 0) // per_batch) * per_batch

    return RecipeCollector(
        env,
        policy,
        frames_per_batch=per_batch,
        total_frames=max(whole_batches(frames_to_go), per_batch),
        init_random_frames=whole_batches(getattr(cfg, "init_random_frames", 0) - frames_done),  # (PCN, PGMORL: none)
        device=device,
        exploration_type=ExplorationType.RANDOM,
        # PGMORL: every iteration starts from a reset, as the authors' member train() (mo_ppo.py:628)
        reset_at_each_iter=bool(getattr(cfg, "pgmorl_reset_each_iteration", False)),
        auto_register_policy_transforms=False,  # our policies are feed-forward: no InitTracker needed
        track_traj_ids=track_traj_ids,
        return_same_td=return_same_td,
    )


def evaluation_contexts(cfg, spec: DomainSpec) -> str | list[str]:
    """What the run's evaluator evaluates on: ``cfg.eval_contexts``, else the domain's evaluation suite
    (its vectors, in the evaluator's order: :func:`morl_trl.evaluation.suite_contexts`)."""
    return list(cfg.eval_contexts) if cfg.eval_contexts else spec.train_id


def policy_env_factory(cfg, device: torch.device):
    """``env_factory(num_envs, seed)`` of the evaluators: the training id (a DR id draws a context per
    episode, unless the evaluator gives one at reset) under the policy's history, without the
    training preference."""

    def env_factory(num_envs: int, seed: int):
        return compose_policy_env(make_env(cfg.env_id, num_envs=num_envs, seed=seed, device=device),
                                  history_len=cfg.history_len)

    return env_factory


def make_evaluator(cfg, agent, spec: DomainSpec, reference=None) -> MultiContextEvaluator:
    """The multi-context evaluator of ``agent.eval_policy`` on the policy stack of training (same env, same history)."""
    device = agent.device
    return MultiContextEvaluator(
        agent.eval_policy,
        evaluation_contexts(cfg, spec),
        weights=cfg.eval_weights,
        episodes=cfg.eval_episodes,
        gamma=run_discount(cfg, spec),
        env_factory=policy_env_factory(cfg, device),  # (the evaluator's contexts, given at every reset, replace its draws)
        reference=reference,
        ref_point=cfg.ref_point,
        exploration_type=agent.eval_exploration,
        device=device,
        seed=cfg.seed,
    )


def load_reference(cfg, spec: DomainSpec):
    """The bounds and specialist fronts for NHGR/EUGR: ``cfg.reference_dir``'s, else the copies
    shipped with the package; ``None`` for a domain without published data."""
    from morl_trl.reporting.reference import PACKAGED_REFERENCE, list_reference_domains, load_domain_reference

    root = cfg.reference_dir or PACKAGED_REFERENCE
    if spec.train_id not in list_reference_domains(root):  # (e.g. the DMC domains: no published data)
        return None
    return load_domain_reference(root, spec.train_id)


def no_reference_note(spec: DomainSpec, ref_point=None) -> str:
    """What a run of a domain without reference data says about NHGR (a foreign env's: with its
    reference point ``ref_point``, else the env's, and where it comes from)."""
    if spec.foreign:
        from morl_trl.reporting.report import foreign_nhgr_note

        return foreign_nhgr_note(spec, ref_point)
    return (f"NHGR unavailable for {spec.train_id}: no reference data (per-context bounds and specialist fronts) "
            f"exists for this domain, so the evaluation reports hypervolume and EUM only")


def start_notes(cfg, run, spec: DomainSpec, reference) -> list[str]:
    """What a run says in log.txt as it starts: NHGR without reference data, a budget that never learns."""
    notes = [] if reference is not None else [no_reference_note(spec, cfg.ref_point)]
    warmup = getattr(cfg, "init_random_frames", 0)
    if cfg.frames < warmup and run.frames < cfg.frames:
        notes.append(f"warning: frames ({cfg.frames:,}) is below init_random_frames ({warmup:,}): the "
                     f"run takes uniformly random actions only and never learns; raise frames or lower init_random_frames")
    return notes


def check_buffer_memory(cfg, env, device: torch.device) -> None:
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


def checkpoint_snapshot(agent, env, collector, device: torch.device):
    """The ``snapshot`` a recipe hands to :meth:`Run.session <morl_trl.runs.run.Run.session>`: a
    callable returning what a checkpoint holds besides the run's own counters (the agent's state, the
    env's, the collector's, the device), read when the checkpoint is written.

    Example:
        >>> from morl_trl.recipes import build_agent, resolve_config
        >>> cfg, cpu = resolve_config("envelope", "MOLavaGridDR-v0", num_envs=2), torch.device("cpu")
        >>> env = make_training_env(cfg, cpu)
        >>> agent = build_agent(cfg, env, gamma=0.99, device=cpu)
        >>> snapshot = checkpoint_snapshot(agent, env, make_collector(cfg, env, agent.explore_policy, cpu), cpu)
        >>> sorted(snapshot())
        ['agent', 'carrier', 'device', 'env', 'traj_pool']
    """
    return lambda: dict(agent=agent.state_dict(), env=env_state(env), **collector_state(collector),
                        device=str(device))


#: the errors ``load_state_dict`` raises for a state of another layout (keys, types, shapes, batch sizes)
LAYOUT_ERRORS = (KeyError, TypeError, AttributeError, RuntimeError, IndexError, ValueError)


def load_agent_state(agent, state: dict, source: Path, algo: str, *, todo: str | None = None) -> None:
    """``agent.load_state_dict(state["agent"])``, or one line naming ``source`` (a checkpoint or an
    export) and what is wrong when ``state`` is not a ``algo`` agent of this config: a config whose
    ``algo`` was changed (the state records the config it was written with), or a state of
    another layout (:class:`~morl_trl.runs.checkpoint.DamagedCheckpointError`, never a traceback
    or a TensorDict's repr)."""
    source = Path(source)
    if todo is None:
        todo = (f"move {source.name} out of {str(source.parent)!r} to use the previous checkpoint" if source.is_dir()
                else "export the policy again")
    written = state.get("config") if isinstance(state, dict) else None
    written = written.get("algo") if isinstance(written, dict) else None
    if isinstance(written, str) and written != algo:
        where = source.parent.parent / "config.json" if source.is_dir() else source
        raise DamagedCheckpointError(
            f"{str(where)!r} says algo {algo!r}, but {str(source)!r} was written by a {written!r} run: the config was "
            f"changed; set algo back to {written!r}")
    if not isinstance(state.get("agent"), dict):
        what = "no agent" if "agent" not in state else f"an agent that is a {type(state['agent']).__name__}"
        raise DamagedCheckpointError(f"{str(source)!r} holds {what}, not the state of a {algo} agent: it was changed "
                                     f"or belongs to another run; {todo}")
    try:
        agent.load_state_dict(state["agent"])
    except LAYOUT_ERRORS as err:
        raise DamagedCheckpointError(f"{str(source)!r} does not hold a {algo} agent of this run's config "
                                     f"({first_line(err)}): it was changed or belongs to another run; {todo}") from None
