"""The optimizer side of every recipe: Adam as the recipes build it, and the one optimizer step.

:func:`optimizer_step` is *loss → non-finite guard → backward → optional gradient-norm clip →
step*, the same for every algorithm (Envelope, the actor-critics, MORL/D, GPI-LS/PD, PCN,
PGMORL) and for the captured update (:mod:`morl_trl.training.capture`):

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
    morl_trl.training.optim.NonFiniteLossError: non-finite loss {'loss_q': nan}; the networks were left as they were before this update
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import torch
from torch.optim import optimizer as _optimizer_module
from torch.optim.adam import adam as adam_fn

from morl_trl.runs.session import StopRun

__all__ = ["NonFiniteLossError", "MemberAdam", "adam", "fused_choice", "optimizer_step", "clip_grad_norm",
           "check_finite", "keep_implementation", "fused_adam_step"]


class NonFiniteLossError(StopRun):
    """A loss came out NaN or infinite; the update was not applied. Raised inside
    :meth:`Run.session <morl_trl.runs.Run.session>` it stops the run cleanly (a
    :class:`~morl_trl.runs.session.StopRun`: the last good state is checkpointed)."""


def check_finite(losses: Mapping[str, torch.Tensor], total: torch.Tensor | None = None) -> None:
    """Raise :class:`NonFiniteLossError` naming ``losses`` unless ``total`` (default: each loss) is finite."""
    if total is not None:  # (one host read; torch.isfinite on a CPU scalar is four operations)
        finite = math.isfinite(total.item()) if total.numel() == 1 else bool(torch.isfinite(total).all())
    else:
        finite = all(bool(torch.isfinite(v).all()) for v in losses.values())
    if not finite:
        bad = {k: v.item() for k, v in losses.items()}
        raise NonFiniteLossError(f"non-finite loss {bad}; the networks were left as they were before this update")


def clip_grad_norm(params: Iterable[torch.Tensor], max_norm: float, *, population: int | None = None) -> None:
    """``torch.nn.utils.clip_grad_norm_``, or with ``population=P`` (parameters stacked ``[P, ...]``) each
    member's own norm clipped, by the same ``max / (norm + 1e-6)`` scale capped at 1."""
    params = list(params)
    if population is None:
        torch.nn.utils.clip_grad_norm_(params, max_norm)
        return
    params = [p for p in params if p.grad is not None]
    # (g * g: the same values as g.pow(2), which this CPU runs ~5x slower)
    sq = sum((p.grad * p.grad).reshape(population, -1).sum(-1) for p in params)
    scale = (max_norm / (sq.sqrt() + 1e-6)).clamp(max=1.0)
    for p in params:
        p.grad.mul_(scale.reshape(population, *([1] * (p.ndim - 1))))


def optimizer_step(loss: torch.Tensor, optimizers: Iterable[torch.optim.Optimizer], *,
                   max_grad_norm: float | None = None, population: int | None = None,
                   losses: Mapping[str, torch.Tensor] | None = None, on_device: bool = False,
                   found_inf: torch.Tensor | None = None) -> torch.Tensor | None:
    """One optimizer step on ``loss``: the non-finite guard, zero the gradients, backward, clip each
    optimizer's parameters to ``max_grad_norm`` (:func:`clip_grad_norm`, per member with ``population``),
    step every optimizer. Eager, a non-finite ``loss`` raises :class:`NonFiniteLossError` (naming
    ``losses``) before anything changes; ``on_device`` (fused optimizers), the step is skipped on the
    device instead and the returned ``found_inf`` is ``1.0`` (``found_inf``: an earlier step's flag of the
    same update, which skips this one too)."""
    optimizers = list(optimizers)
    if on_device:
        flag = (~torch.isfinite(loss)).to(torch.float32)
        found_inf = flag if found_inf is None else torch.maximum(flag, found_inf)
    else:
        found_inf = None
        check_finite(losses if losses is not None else {"loss": loss}, loss)
    for opt in optimizers:
        if type(opt) is torch.optim.Adam:  # its zero_grad(set_to_none=True), without the profiler record around it
            for group in opt.param_groups:
                for p in group["params"]:
                    p.grad = None
        else:
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
            opt.found_inf = None
        elif not fused_adam_step(opt):
            opt.step()
    return found_inf


def fused_adam_step(opt: torch.optim.Optimizer) -> bool:
    """``opt.step()`` of a plain fused ``torch.optim.Adam`` as the two kernels it runs (the step counts'
    ``_foreach_add_``, ``_fused_adam_``), without the ~0.1 ms of Python around them on a CPU core: the same
    parameters, moments and counts bit for bit (``tests/recipes/test_optimizer_step.py``). Only where that is
    all ``step()`` would do (no hooks, AMSGrad, weight decay, capturable, tensor lr, one device and dtype,
    state made by a first step, ...); otherwise returns ``False``, touching nothing: call ``opt.step()``.

    Example:
        >>> w = torch.nn.Parameter(torch.ones(2))
        >>> opt = adam([w], lr=0.1)
        >>> w.grad = torch.ones(2); opt.step()  # the first step makes the state
        >>> w.grad = torch.ones(2); fused_adam_step(opt), w.detach(), opt.state[w]["step"]
        (True, tensor([0.8000, 0.8000]), tensor(2.))
    """
    if type(opt) is not torch.optim.Adam or "step" in opt.__dict__ or opt._optimizer_step_pre_hooks \
            or opt._optimizer_step_post_hooks or _optimizer_module._global_optimizer_pre_hooks \
            or _optimizer_module._global_optimizer_post_hooks or getattr(opt, "grad_scale", None) is not None \
            or getattr(opt, "found_inf", None) is not None or len(opt.param_groups) != 1:
        return False
    params, grads, avgs, sqs, steps = [], [], [], [], []
    device = dtype = None
    for group in opt.param_groups:
        if not group.get("fused") or group["amsgrad"] or group["weight_decay"] != 0 or group["maximize"] \
                or group["differentiable"] or group["capturable"] or group.get("decoupled_weight_decay", False) \
                or torch.is_tensor(group["lr"]) or any(torch.is_tensor(b) for b in group["betas"]):
            return False
        for p in group["params"]:
            st = opt.state.get(p)
            if p.grad is None or not st or p.grad.is_sparse or p.is_complex() or not torch.is_tensor(st.get("step")):
                return False
            if device is None:
                device, dtype = p.device, p.dtype
            elif p.device != device or p.dtype != dtype:
                return False
            params.append(p), grads.append(p.grad), avgs.append(st["exp_avg"]), sqs.append(st["exp_avg_sq"])
            steps.append(st["step"])
    if not params:
        return False
    group = opt.param_groups[0]
    beta1, beta2 = group["betas"]
    with torch.no_grad():
        torch._foreach_add_(steps, 1)
        torch._fused_adam_(params, grads, avgs, sqs, [], steps, amsgrad=False, lr=group["lr"], beta1=beta1,
                           beta2=beta2, weight_decay=group["weight_decay"], eps=group["eps"], maximize=False,
                           grad_scale=None, found_inf=None)
    return True


class MemberAdam(torch.optim.Optimizer):
    """Adam over a population's stacked parameters that steps only the members of :attr:`members`.

    Every parameter holds ``P`` members along its group's ``member_dim`` (``0`` for ``[P, ...]``,
    ``1`` for a critic ensemble ``[n, P, ...]``). :meth:`step` updates, for each member ``p``
    with ``members[p]`` true, its slice of every parameter, of Adam's two moments and its own step
    count exactly as ``torch.optim.Adam`` on that member alone would (torch's own Adam, its
    ``foreach`` arithmetic, runs on the member's slices; its bias corrections use its own count); the other members' parameters, moments and counts are left bit for bit as they
    were, whatever their gradients. This is what a population trained one member at a time needs
    (MORL/D's round robin, :mod:`morl_trl.algorithms.morld.recipe`): one batched backward over all members,
    one step of the active ones. With every member active it is ``P`` independent Adams, as
    ``torch.optim.Adam`` over the stacked tensors.

    ``fused`` (default ``None``: where torch has the kernel, as :func:`adam`) steps every active
    member of a group in one call of torch's fused Adam kernel, each member's slices with its own
    count: bit for bit ``torch.optim.Adam(fused=True)`` on that member's networks alone (a critic
    ensemble ``[n, P, ...]``: each critic's tensors), the implementation :func:`adam` gives the
    other recipes (``tests/recipes/test_member_adam.py``). ``fused=False`` runs torch's
    foreach Adam on one member's slices at a time, its square roots floored as :meth:`_sqrt_floors`
    explains. The two agree to float rounding; on a MORL/D population update at the paper's Hopper
    settings the fused step costs a fifth of the foreach one (``docs/speed.md``).

    The state is Adam's (``step``, ``exp_avg``, ``exp_avg_sq`` per parameter) with ``step`` a
    ``[P]`` float tensor; a ``torch.optim.Adam`` state (one scalar ``step`` per parameter, all
    members stepped together) loads with that count for every member. ``found_inf`` (set by
    :func:`optimizer_step` with ``on_device``) skips the whole step. No weight decay, amsgrad
    or maximize.

    Example:
        >>> w = torch.nn.Parameter(torch.ones(3, 2))  # 3 members of 2 numbers
        >>> opt = MemberAdam([w], lr=0.1, population=3)
        >>> opt.members = torch.tensor([False, True, False])
        >>> w.grad = torch.ones(3, 2)
        >>> opt.step()
        >>> w.detach()
        tensor([[1.0000, 1.0000],
                [0.9000, 0.9000],
                [1.0000, 1.0000]])
        >>> opt.state[w]["step"]
        tensor([0., 1., 0.])
    """

    def __init__(self, params, lr: float = 1e-3, *, population: int, betas: tuple[float, float] = (0.9, 0.999),
                 eps: float = 1e-8, member_dim: int = 0, fused: bool | None = None) -> None:
        if population < 1:
            raise ValueError(f"population must be at least 1, got {population}")
        super().__init__(params, dict(lr=lr, betas=betas, eps=eps, member_dim=member_dim))
        self.population = int(population)
        everything = [p for group in self.param_groups for p in group["params"]]
        if fused is None:
            fused = all(p.is_floating_point() and p.device.type in ("cpu", "cuda") for p in everything)
        #: one fused Adam kernel per group and step (see the class docstring); ``False``: foreach, per member
        self.fused = bool(fused)
        device = self.param_groups[0]["params"][0].device
        #: ``[P]`` bool: the members the next :meth:`step` updates (all of them by default)
        self.members = torch.ones(self.population, dtype=torch.bool, device=device)
        self.found_inf: torch.Tensor | None = None
        for group in self.param_groups:
            for p in group["params"]:
                d = group["member_dim"]
                if p.ndim <= d or p.shape[d] != self.population:
                    raise ValueError(f"a parameter of shape {tuple(p.shape)} has no population dimension {d} of "
                                     f"size {self.population} (member_dim={d}, population={self.population})")
        self._member_dims = [group["member_dim"] for group in self.param_groups]
        self._floor_key, self._floors, self._floor_flat = None, None, None  # (_sqrt_floors' scratch)
        self.register_load_state_dict_post_hook(MemberAdam._per_member_steps)

    @staticmethod
    def _per_member_steps(opt: "MemberAdam") -> None:
        """After ``load_state_dict``: a scalar ``step`` (a ``torch.optim.Adam`` state) becomes one count per
        member; the groups keep their member dimensions (a ``torch.optim.Adam`` state has none)."""
        for group, d in zip(opt.param_groups, opt._member_dims):
            group["member_dim"] = d
        for p, st in opt.state.items():
            step = st.get("step")
            if step is not None:
                step = torch.as_tensor(step, dtype=torch.float32, device=p.device)
                st["step"] = step.expand(opt.population).clone() if step.ndim == 0 else step.clone()

    @torch.no_grad()
    def step(self, closure=None):
        if closure is not None:
            raise ValueError("MemberAdam.step takes no closure")
        if self.found_inf is not None and bool(self.found_inf):
            return None  # (a non-finite update: skipped, as the fused optimizers do)
        active = self.members.nonzero().flatten().tolist()
        for group in self.param_groups:
            beta1, beta2 = group["betas"]
            d = group["member_dim"]
            params = [p for p in group["params"] if p.grad is not None]
            for p in params:
                st = self.state[p]
                if not st:
                    st["step"] = torch.zeros(self.population, dtype=torch.float32, device=p.device)
                    st["exp_avg"] = torch.zeros_like(p, memory_format=torch.preserve_format)
                    st["exp_avg_sq"] = torch.zeros_like(p, memory_format=torch.preserve_format)
            if self.fused and (not params or not active or self._fused_step(group, params, active)):
                continue
            for m in active:  # torch's own Adam (its foreach arithmetic) on member m's slices, its own step count
                sts = [self.state[p] for p in params]
                sqs = [st["exp_avg_sq"].select(d, m) for st in sts]
                floors = self._sqrt_floors(sqs, group["eps"], beta2)
                adam_fn([p.select(d, m) for p in params], [p.grad.select(d, m) for p in params],
                        [st["exp_avg"].select(d, m) for st in sts], sqs, floors or [],
                        [st["step"][m:m + 1] for st in sts], foreach=True, amsgrad=floors is not None, beta1=beta1,
                        beta2=beta2, lr=group["lr"], weight_decay=0.0, eps=group["eps"], maximize=False)
        return None

    def _fused_step(self, group: dict, params: list[torch.Tensor], active: list[int]) -> bool:
        """One ``_fused_adam_`` call over the ``active`` members' slices of ``params``, each with its member's
        count. A slice goes as its contiguous blocks (member ``m`` of ``[*lead, P, *rest]``: ``[i..., m]``
        for every ``lead`` index; a critic ensemble's ``[n, P, ...]``: each critic's own tensors), which is
        how a member's networks hold them on their own. ``False`` (nothing done) where a tensor is not
        contiguous: the kernel walks its memory flat."""
        sts = [self.state[p] for p in params]
        grads, avgs, sqs = [p.grad for p in params], [st["exp_avg"] for st in sts], [st["exp_avg_sq"] for st in sts]
        if not all(t.is_contiguous() for ts in (params, grads, avgs, sqs) for t in ts):
            return False
        d = group["member_dim"]
        members = [st["step"].unbind(0) for st in sts]  # (unbind: one call for every member's view)
        torch._foreach_add_([steps[m] for steps in members for m in active], 1)

        def blocks(tensors):  # parameter-major, then member, then lead index
            out = []
            for t in tensors:
                lead = [block.unbind(0) for block in t.reshape(-1, *t.shape[d:]).unbind(0)] if d else [t.unbind(0)]
                out.extend(block[m] for m in active for block in lead)
            return out

        counts = [steps[m] for p, steps in zip(params, members) for m in active for _ in range(math.prod(p.shape[:d]))]
        beta1, beta2 = group["betas"]
        torch._fused_adam_(blocks(params), blocks(grads), blocks(avgs), blocks(sqs), [], counts, amsgrad=False,
                           lr=group["lr"], beta1=beta1, beta2=beta2, weight_decay=0.0, eps=group["eps"],
                           maximize=False, grad_scale=None, found_inf=None)
        return True

    def _sqrt_floors(self, sqs: list[torch.Tensor], eps: float, beta2: float) -> list[torch.Tensor] | None:
        """Scratch tensors shaped as ``sqs`` (a member's second moments), filled with the dtype's smallest
        normal number, for Adam's ``amsgrad`` slot: torch's foreach Adam then takes the square root of
        ``max(v, tiny)`` (its ``_foreach_maximum_`` into the scratch) instead of ``v``, and leaves ``v``,
        the state, as plain Adam does.

        Why: a second moment that decays towards zero (a gradient that stays zero: a dead unit, an input
        feature that never varies) passes through subnormal numbers, and this CPU's square root of a
        subnormal is ~50x slower than of a normal number (``_foreach_sqrt`` was 21% of a MORL/D
        population update, ``docs/speed.md``). The result is bit for bit plain Adam's: wherever
        ``v < tiny``, both ``sqrt(v) / sqrt(1 - beta2^t)`` and ``sqrt(tiny) / sqrt(1 - beta2^t)`` are
        below half a unit in the last place of ``eps``, so adding ``eps`` gives ``eps`` either way
        (``tests/recipes/test_member_adam.py``). ``None`` (plain Adam) where that bound does not hold
        (an ``eps`` too small for the dtype, or ``beta2 >= 1``)."""
        info = torch.finfo(sqs[0].dtype)
        if not (beta2 < 1.0 and math.sqrt(info.tiny) / math.sqrt(1.0 - beta2) < eps * info.eps / 4):
            return None
        key = tuple((t.shape, t.dtype, t.device) for t in sqs)
        if self._floor_key != key:
            flat = torch.empty(sum(t.numel() for t in sqs), dtype=sqs[0].dtype, device=sqs[0].device)
            self._floors = [chunk.view(t.shape) for chunk, t in zip(flat.split([t.numel() for t in sqs]), sqs)]
            self._floor_flat, self._floor_key = flat, key
        self._floor_flat.fill_(info.tiny)  # (the previous step's maxima overwritten)
        return self._floors


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
