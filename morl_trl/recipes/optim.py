"""The optimizer side of every recipe: Adam as the recipes build it, and the one optimizer step.

:func:`optimizer_step` is *loss → non-finite guard → backward → optional gradient-norm clip →
step*, the same for every algorithm (Envelope, the actor-critics, MORL/D, GPI-LS/PD, PCN,
PGMORL) and for the captured update (:mod:`morl_trl.recipes.capture`):

* eager (the default) the guard reads the loss on the host before anything is touched and
  raises :class:`NonFiniteLossError`: a non-finite update is never applied;
* ``on_device=True`` (the captured / accelerator path) nothing reads the host: the
  non-finite flag is handed to the fused optimizers as ``found_inf`` (the kernel skips the
  step, as ``GradScaler`` does) and returned, for the caller's Polyak mask and skip count.

Example:
    >>> w = torch.nn.Parameter(torch.ones(2))
    >>> opt = adam([w], lr=0.1)
    >>> _ = optimizer_step((w * torch.tensor([3.0, 4.0])).sum(), [opt], max_grad_norm=1.0)
    >>> w.detach()
    tensor([0.9000, 0.9000])
    >>> optimizer_step(w.sum() * float("nan"), [opt], losses={"loss_q": w.sum() * float("nan")})
    Traceback (most recent call last):
    ...
    morl_trl.recipes.optim.NonFiniteLossError: non-finite loss {'loss_q': nan}; the networks were left as they were before this update
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import torch

from morl_trl.runs.session import StopRun

__all__ = ["NonFiniteLossError", "adam", "fused_choice", "optimizer_step", "clip_grad_norm", "check_finite",
           "keep_implementation"]


class NonFiniteLossError(StopRun):
    """A loss came out NaN or infinite; the update was not applied. Raised inside
    :meth:`Run.session <morl_trl.runs.Run.session>` it stops the run cleanly (a
    :class:`~morl_trl.runs.session.StopRun`: the last good state is checkpointed)."""


def check_finite(losses: Mapping[str, torch.Tensor], total: torch.Tensor | None = None) -> None:
    """Raise :class:`NonFiniteLossError` naming every loss of ``losses`` unless ``total`` (default:
    each of them) is finite. Reads the host."""
    finite = torch.isfinite(total) if total is not None else all(bool(torch.isfinite(v)) for v in losses.values())
    if not finite:
        bad = {k: v.item() for k, v in losses.items()}
        raise NonFiniteLossError(f"non-finite loss {bad}; the networks were left as they were before this update")


def clip_grad_norm(params: Iterable[torch.Tensor], max_norm: float, *, population: int | None = None) -> None:
    """Clip the gradient norm of ``params`` to ``max_norm``: ``torch.nn.utils.clip_grad_norm_``,
    or, with ``population=P`` (parameters stacked ``[P, ...]``: a batched population), each
    member's own norm (over its slices of every parameter), with the same ``max / (norm + 1e-6)``
    scale capped at 1."""
    params = list(params)
    if population is None:
        torch.nn.utils.clip_grad_norm_(params, max_norm)
        return
    params = [p for p in params if p.grad is not None]
    sq = sum(p.grad.pow(2).reshape(population, -1).sum(-1) for p in params)
    scale = (max_norm / (sq.sqrt() + 1e-6)).clamp(max=1.0)
    for p in params:
        p.grad.mul_(scale.reshape(population, *([1] * (p.ndim - 1))))


def optimizer_step(loss: torch.Tensor, optimizers: Iterable[torch.optim.Optimizer], *,
                   max_grad_norm: float | None = None, population: int | None = None,
                   losses: Mapping[str, torch.Tensor] | None = None, on_device: bool = False) -> torch.Tensor | None:
    """One optimizer step on ``loss``: guard, zero the gradients, backward, clip each optimizer's
    parameters to ``max_grad_norm`` (:func:`clip_grad_norm`, per member with ``population``),
    step every optimizer.

    Args:
        loss: the scalar to minimise.
        optimizers: stepped together after the one backward.
        losses: the named losses an error names (default ``{"loss": loss}``).
        on_device: skip the step on the device instead of raising (see the module docstring);
            every optimizer must then be fused.

    Returns:
        ``found_inf`` (``1.0`` where the step was skipped) with ``on_device``, else ``None``.

    Raises:
        NonFiniteLossError: ``loss`` is not finite (eager); nothing was changed.
    """
    optimizers = list(optimizers)
    found_inf = None
    if on_device:
        found_inf = (~torch.isfinite(loss)).to(torch.float32)
    else:
        check_finite(losses if losses is not None else {"loss": loss}, loss)
    for opt in optimizers:
        opt.zero_grad(set_to_none=True)
    loss.backward()
    if max_grad_norm is not None:
        for opt in optimizers:
            clip_grad_norm((p for group in opt.param_groups for p in group["params"]), max_grad_norm,
                           population=population)
    for opt in optimizers:
        if found_inf is not None:
            opt.found_inf = found_inf
        opt.step()
        if found_inf is not None:
            opt.found_inf = None
    return found_inf


def fused_choice(cfg) -> bool | None:
    """:func:`adam`'s ``fused`` for a config: ``None`` (fused where torch can) unless ``cfg.fused_optimizer`` is false."""
    return None if getattr(cfg, "fused_optimizer", True) else False


def adam(params, lr: float, *, fused: bool | None = None, **kwargs) -> torch.optim.Adam:
    """``torch.optim.Adam`` over ``params``, fused when torch has a fused kernel for them.

    The fused implementation updates every parameter in one kernel (on a CPU core ~4x faster
    than the per-tensor loop torch picks there by default) with Adam's arithmetic unchanged
    (results agree to float rounding), and it can skip a step on the device without reading
    the host (``found_inf``), which the captured update relies on. ``fused=None`` (the default):
    fused when every parameter is a floating point tensor on the CPU or a CUDA device. Other
    keyword arguments (e.g. ``eps``) go to ``torch.optim.Adam``.

    Example:
        >>> opt = adam([torch.nn.Parameter(torch.zeros(3))], lr=1e-3)
        >>> opt.defaults["fused"]
        True
    """
    params = list(params)
    if fused is None:
        fused = all(p.is_floating_point() and p.device.type in ("cpu", "cuda") for p in params)
    return torch.optim.Adam(params, lr=lr, fused=bool(fused), **kwargs)


def keep_implementation(opt: torch.optim.Optimizer) -> None:
    """After ``load_state_dict``: the optimizer keeps the implementation it was built with (a
    checkpoint written by a per-tensor Adam would otherwise turn a fused one back), with its step
    counters where that implementation keeps them."""
    for group in opt.param_groups:
        for key in ("fused", "foreach"):
            if key in opt.defaults:
                group[key] = opt.defaults[key]
    if opt.defaults.get("fused"):
        for param, st in opt.state.items():
            if torch.is_tensor(st.get("step")):
                st["step"] = st["step"].to(device=param.device, dtype=torch.float32)
