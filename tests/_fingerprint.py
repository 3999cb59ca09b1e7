"""One number per set of networks, and the tolerance a recorded one is compared with.

A recorded fingerprint ("the same parameters after N updates as before the change") is the one
kind of float a test compares across machines: another CPU (AVX2 or AVX-512, Intel or AMD, MKL
taking another kernel) rounds float32 sums in another order, ~1e-7 relative per operation, and a
few updates carry that into the parameters. Such a test compares with :data:`REORDER_TOLERANCE`
of :func:`fingerprint`'s ``scale``, never bit for bit; two code paths that must agree are run in
the same process and compared there instead.

How the tolerance was chosen (``tests/recipes/test_optimizer_step.py`` checks both sides of it
in one process, so the choice fails loudly if it stops separating them):

* *rounding*: every initial parameter multiplied by ``1 + 1.2e-7 * N(0, 1)`` (one float32
  rounding, as another CPU's kernels give) moved the fingerprint of the 11 recipe cases by 2e-10
  to 7e-9 of its scale (the Intel host of issue 43 against ours: 4e-10 for Envelope);
* *a changed update*: one optimizer step of the run skipped (the second, or the last of 3 to 8)
  moved it by 6e-6 (continuous GPI-PD's second) to 3e-4 of its scale.

``1e-6`` sits over 100x above the first and 6x below the smallest of the second (measured on an
AMD EPYC with AVX-512, torch 2.13.0 CPU, 2026-12-01).
"""

from __future__ import annotations

from collections.abc import Iterable

import torch

#: |fingerprint - recorded| allowed, as a fraction of the fingerprint's scale (see the module docstring)
REORDER_TOLERANCE = 1e-6


def fingerprint(tensors: Iterable[torch.Tensor]) -> tuple[float, float]:
    """``(sum of p_i * (1 + i / n), sum of |p_i| * (1 + i / n))`` over the floating point tensors, in float64.

    The position weight makes a permutation of the values count; the second number is the scale a
    rounding difference is measured against (a fingerprint can be near zero by cancellation).

    >>> fingerprint([torch.tensor([1.0, -2.0]), torch.tensor([3])])
    (-2.0, 4.0)
    """
    total = scale = 0.0
    for value in tensors:
        if torch.is_tensor(value) and value.is_floating_point():
            flat = value.detach().double().flatten()
            w = 1 + torch.arange(flat.numel(), dtype=torch.float64) / flat.numel()
            total += float((flat * w).sum())
            scale += float((flat.abs() * w).sum())
    return total, scale


def assert_same_fingerprint(value: float, scale: float, recorded: float) -> None:
    """``value`` equals ``recorded`` to float32 reordering: within :data:`REORDER_TOLERANCE` of ``scale``."""
    diff = abs(value - recorded)
    assert diff <= REORDER_TOLERANCE * scale, (
        f"fingerprint {value!r} differs from the recorded {recorded!r} by {diff:.3g}, "
        f"{diff / scale:.2g} of its scale {scale:.6g} (allowed: {REORDER_TOLERANCE:g}, float32 reordering)")
