"""The recipe's update, captured: ``torch.compile`` and CUDA graphs wrap the one gradient step the
recipe defines, TorchRL's sota way.

An algorithm whose update can run captured (Envelope, :mod:`~morl_trl.algorithms.envelope.recipe`; CAPQL,
MOSAC, discrete MOSAC and SAC, :mod:`~morl_trl.algorithms.actor_critic.recipe`) writes its update as
*sample → gradient_step → hard target copy → priority write*, with ``gradient_step(agent, batch,
actor_turn, on_device=False) -> (losses, found_inf)`` (loss → backward → clipping → optimizer
steps). With ``cfg.compile`` and/or ``cfg.cudagraphs`` (config group ``compile``, as in TorchRL's
``sota-implementations``) :func:`~morl_trl.training.agent.captured_update` wraps that same ``gradient_step`` in
``torch.compile(mode=cfg.compile_mode)`` and/or :class:`tensordict.nn.CudaGraphModule` (one graph
launch per update on CUDA), and the recipe's update hands the whole update to it (the decision:
:func:`~morl_trl.training.agent.runs_captured`). On an
accelerator the same step runs uncompiled by default (when the optimizers are fused), for its
on-device guard: no host synchronisation per update there either.

What changes so that nothing in it reads the host:

* the non-finite guard stays on the device: ``gradient_step(..., on_device=True)`` hands the
  loss's ``isfinite`` flag to the fused optimizers as ``found_inf`` (the kernel skips the step, as
  ``GradScaler`` does), the Polyak step is multiplied by it, and priorities of a skipped update
  are written as 0 (never NaN into the sampler's trees). Skipped updates are counted on the device
  and the count is read every ``cfg.finite_check_interval`` updates: :class:`NonFiniteLossError`
  is raised then, with the networks as the last finite update left them — the guarantee of the
  eager path (a non-finite update is never applied), reported up to that many updates late;
* the loss's input checks (which read the host) are off (``loss.validate_inputs = False``):
  the batches come from the run's own replay buffer, and a non-finite reward makes the loss
  non-finite, which the guard catches;
* every optimizer must be fused (:func:`~morl_trl.training.optim.adam` makes them so); with
  CUDA graphs they are made ``capturable``.

With ``cfg.capture_sampling`` (off by default until measured on a GPU) and a prioritized
buffer on :class:`~morl_trl.data.TorchPrioritizedSampler`, the whole update is one function
with no host read: drawing the batch from the sum tree, gathering it from the storage, the
gradient step, and writing the new priorities into the trees
(:meth:`~morl_trl.data.TorchPrioritizedSampler.sample_unchecked`,
:meth:`~morl_trl.data.TorchPrioritizedSampler.update_priority_unchecked`). With
``cfg.cudagraphs`` that function is captured as one CUDA graph (``torch.cuda.graph``; no
input copies, no synchronisation per replay): one launch per update. The same random draws
and arithmetic as the eager update from the same state (``tests/gpu/test_gpu.py``).

The arithmetic is the eager update's: on the CPU the compiled update matches the eager one
from the same state to float rounding (``tests/recipes/test_capture.py``); CUDA graphs replay
the same kernels.

Example:
    >>> from morl_trl.envs import make_env
    >>> from morl_trl.recipes import resolve_config, build_agent
    >>> from morl_trl.recipes.off_policy import make_replay_buffer
    >>> from morl_trl.transforms import compose_training_env
    >>> cfg = resolve_config("capql", "MOHopperDR-v5", quick=True, hidden=(16,), batch_size=8,
    ...                      compile=True, compile_mode=None, finite_check_interval=4)
    >>> env = compose_training_env(make_env(cfg.env_id, num_envs=2), gamma=0.99)
    >>> agent = build_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
    >>> from morl_trl.algorithms.actor_critic.recipe import gradient_step
    >>> CapturedUpdate(agent, gradient_step).interval
    4
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.objectives import SoftUpdate

from morl_trl._torchrl_compat import replay_sample_unit, sampler_generator, storage_data
from morl_trl.objectives import PolyakUpdate
from morl_trl.training.optim import NonFiniteLossError

__all__ = ["CapturedUpdate"]


class CapturedUpdate:
    """One agent's whole update with its ``gradient_step`` captured; call it with the buffer and whether
    the update is an actor turn (the delayed actor's clock, counted by the recipe).

    Args:
        agent: the :class:`~morl_trl.training.agent.Agent` (its ``cfg`` holds ``compile``,
            ``compile_mode``, ``cudagraphs``, ``finite_check_interval``).
        gradient_step: the recipe's ``gradient_step(agent, batch, actor_turn, on_device=False) ->
            (losses, found_inf)``.
    """

    def __init__(self, agent, gradient_step) -> None:
        cfg = agent.cfg
        self.agent = agent
        self.gradient_step = gradient_step
        self.policy_freq = int(getattr(cfg, "policy_freq", 1))
        self.interval = int(getattr(cfg, "finite_check_interval", 1))
        not_fused = [name for name, opt in agent.optimizers.items()
                     if not all(group.get("fused") for group in opt.param_groups)]
        if not_fused:
            raise ValueError(f"a captured update (compile/cudagraphs) needs fused optimizers, as "
                             f"morl_trl.training.optim.adam makes them; {not_fused} are not fused")
        cudagraphs = bool(getattr(cfg, "cudagraphs", False))
        if cudagraphs and torch.device(agent.device).type != "cuda":
            raise ValueError(f"cudagraphs=true needs device='cuda' (got {str(agent.device)!r}); "
                             "use compile=true alone on other devices")
        if cudagraphs:
            for opt in agent.optimizers.values():
                for group in opt.param_groups:
                    group["capturable"] = True
        if hasattr(agent.loss, "validate_inputs"):
            agent.loss.validate_inputs = False
        updater = agent.target_updater
        self.soft = isinstance(updater, SoftUpdate)
        if self.soft:
            self.tau = 1.0 - float(updater.eps)
            self.sources, self.targets = (updater.leaves() if isinstance(updater, PolyakUpdate)
                                          else PolyakUpdate.leaves(updater))
        self.skipped = torch.zeros((), device=agent.device)
        self.since_check = 0
        def capture(fn):
            if getattr(cfg, "compile", False):
                # dynamic=False: a training run's shapes never change, and symbolic sizes broke
                # dynamo on the preference draws (randn of a symbolic size) on the GPU
                fn = torch.compile(fn, mode=getattr(cfg, "compile_mode", None), dynamic=False)
            if cudagraphs:
                from tensordict.nn import CudaGraphModule

                fn = CudaGraphModule(fn, in_keys=[], out_keys=[], warmup=5 if getattr(cfg, "compile", False) else 2)
            return fn

        self.fn = capture(self.step)
        # the delayed actor (policy_freq > 1): a critic-only and a critic-then-actor update, one graph each
        self.fn_actor = capture(self.actor_step) if self.policy_freq > 1 else None
        self.capture_sampling = bool(getattr(cfg, "capture_sampling", False))
        self.compiled = bool(getattr(cfg, "compile", False))
        self.cudagraphs = cudagraphs
        self._whole = None  # the whole-update function (sampling included), built on first use
        self._graph = None
        self._calls = 0

    def step(self, batch: TensorDictBase) -> TensorDictBase:
        """Loss, backward, clipping, optimizer steps and the Polyak update, skipped on the device if non-finite
        (with ``policy_freq > 1``: the critic-only update, :meth:`actor_step` the other)."""
        return self._step(batch, self.policy_freq == 1)

    def actor_step(self, batch: TensorDictBase) -> TensorDictBase:
        """The delayed actor's actor turn: the critic step, then ``policy_freq`` actor steps."""
        return self._step(batch, True)

    def _step(self, batch: TensorDictBase, actor_turn: bool) -> TensorDictBase:
        agent = self.agent
        out, found_inf = self.gradient_step(agent, batch, actor_turn, on_device=True)
        if self.soft:
            with torch.no_grad():
                delta = torch._foreach_sub(self.sources, self.targets)
                torch._foreach_mul_(delta, (1.0 - found_inf) * self.tau)
                torch._foreach_add_(self.targets, delta)
        self.skipped.add_(found_inf)
        result = out.detach()
        key = agent.loss.tensor_keys.priority
        priority = batch.get(key, None)
        if priority is not None:
            result = result.set("_priority", torch.nan_to_num(priority.detach(), nan=0.0, posinf=0.0, neginf=0.0))
        return result

    # ------------------------------------------------ the whole update, sampling included
    def _samples_in_graph(self, buffer) -> bool:
        from torchrl.data import TensorDictReplayBuffer
        from torchrl.data.replay_buffers.storages import LazyTensorStorage

        from morl_trl.data import TorchPrioritizedSampler
        from morl_trl.data.lean import LeanTensorDictReplayBuffer

        if not self.capture_sampling or self.policy_freq > 1:
            return False
        if type(buffer) not in (TensorDictReplayBuffer, LeanTensorDictReplayBuffer):  # (the storage read as is)
            return False
        sampler, storage, transform = buffer.sampler, buffer.storage, buffer.transform
        return (isinstance(sampler, TorchPrioritizedSampler)
                and type(storage) is LazyTensorStorage and not (transform is not None and len(transform))
                and replay_sample_unit(buffer) is None and not buffer.writer.tracks_generations
                and bool(self.agent.cfg.prioritized) and sampler.reduction == "max"
                and sampler.supports_unchecked(storage) and buffer.priority_key == self.agent.loss.tensor_keys.priority
                and torch.device(storage.device).type == torch.device(self.agent.device).type)

    def _build_whole(self, buffer):
        sampler, storage, batch_size = buffer.sampler, buffer.storage, buffer.batch_size
        step = self.fn if not self.cudagraphs else self.step  # our own graph replaces CudaGraphModule
        descend, write = sampler.descend_unchecked, sampler.write_priorities_unchecked
        if self.compiled:
            mode = getattr(self.agent.cfg, "compile_mode", None)
            if self.cudagraphs:
                step = torch.compile(self.step, mode=mode, dynamic=False)
            # the tree walks (one small op per level) fuse into a few kernels
            descend, write = (torch.compile(f, mode=mode, dynamic=False) for f in (descend, write))
        rng = sampler_generator(sampler)

        def whole() -> TensorDictBase:
            # the uniform draws stay eager (compiled code draws from its own generator)
            u = torch.rand(batch_size, generator=rng, device=rng.device if rng is not None else sampler.device)
            index, weight = descend(u)
            batch = storage_data(storage)[index]
            batch.set("index", index)
            batch.set("priority_weight", weight)
            result = step(batch)
            write(index, result.get("_priority").reshape(-1), sampler._pinned_max_priority())
            return result.exclude("_priority")

        return whole

    def _run_whole(self, buffer) -> TensorDictBase:
        if self._whole is None:
            self._whole = self._build_whole(buffer)
        if not self.cudagraphs:
            return self._whole()
        warmup = 5 if self.compiled else 2
        if self._graph is None and self._calls < warmup:  # warm-up on a side stream, as torch.cuda.graphs asks
            stream = torch.cuda.Stream()
            stream.wait_stream(torch.cuda.current_stream())
            with torch.cuda.stream(stream):
                out = self._whole()
            torch.cuda.current_stream().wait_stream(stream)
            self._calls += 1
            return out
        if self._graph is None:
            self._graph = torch.cuda.CUDAGraph()
            with torch.cuda.graph(self._graph):
                self._static_out = self._whole()
        self._graph.replay()  # the capture recorded the update; this replay applies it
        return self._static_out  # (overwritten by the next update)

    def __call__(self, buffer, actor_turn: bool = True) -> TensorDictBase:
        agent = self.agent
        if self._whole is not None or self._samples_in_graph(buffer):  # (policy_freq 1: every update an actor turn)
            result = self._run_whole(buffer)
            if not self.soft:
                agent.target_updater.step()
            self.since_check += 1
            if self.since_check >= self.interval:
                self.check()
            return result
        batch = buffer.sample().to(agent.device)
        fn = self.fn_actor if self.fn_actor is not None and actor_turn else self.fn
        result = fn(batch)
        if not self.soft:
            agent.target_updater.step()  # a Python-side period counter: hard copies stay eager
        priority = result.get("_priority", None)
        if priority is not None:
            result = result.exclude("_priority")
            if agent.cfg.prioritized:
                batch.set(agent.loss.tensor_keys.priority, priority)
                buffer.update_tensordict_priority(batch)
        self.since_check += 1
        if self.since_check >= self.interval:
            self.check()
        return result

    def check(self) -> None:
        """Reads the device's count of skipped updates; raises :class:`NonFiniteLossError` if any."""
        since, self.since_check = self.since_check, 0
        skipped = int(self.skipped.item())
        if skipped:
            self.skipped.zero_()
            raise NonFiniteLossError(f"{skipped} of the last {since} updates had a non-finite loss and were skipped "
                                     "on the device; the networks are as the last finite update left them")
