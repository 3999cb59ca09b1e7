"""One number per set of networks, and the tolerance a recorded one is compared with.

A recorded fingerprint ("the same parameters after N updates as before the change") is the one
kind of float a test compares across machines: another CPU (AVX2 or AVX-512, Intel or AMD, MKL
taking another kernel) rounds float32 sums in another order, ~1e-7 relative per operation, and a
few updates carry that into the parameters. Such a test compares with :data:`REORDER_TOLERANCE`
of :func:`fingerprint`'s ``scale``, never bit for bit; two code paths that must agree are run in
the same process and compared there instead.

How the tolerance was chosen (``tests/recipes/test_optimizer_step.py`` checks both sides of it,
so the choice fails loudly if it stops separating them):

* *another CPU*: the 11 recipe cases run with ATen's scalar kernels (``ATEN_CPU_CAPABILITY=default``,
  as a CPU without AVX2 runs them) differ from the AVX-512 run by 2e-9 to 2.4e-8 of their scale,
  PGMORL by 1.2e-6 (its stochastic MuJoCo rollouts carry a rounding of an action into the data);
  with the AVX2 kernels by 0 to 1e-12; the Intel host of issue 43 against ours: 4e-10 (Envelope);
* *a changed update*: one optimizer step of the run skipped (the second, or the last of 3 to 8)
  moves it by 6e-6 (continuous GPI-PD's second) to 3e-4 of its scale, PGMORL's by 5e-5 or more.

:data:`REORDER_TOLERANCE` (``1e-6``) sits 40x above the first and 6x below the second;
:data:`CHAOTIC_TOLERANCE` (``1e-5``), for runs whose rollouts amplify a rounding (PGMORL), 8x above
PGMORL's spread and 5x below its smallest change (measured on an AMD EPYC with AVX-512, torch
2.13.0 CPU).
"""

from __future__ import annotations

from collections.abc import Iterable

import torch

#: |fingerprint - recorded| allowed, as a fraction of the fingerprint's scale (see the module docstring)
REORDER_TOLERANCE = 1e-6
#: the same for a run whose rollouts amplify a rounding (stochastic actions in a chaotic simulator)
CHAOTIC_TOLERANCE = 1e-5


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


def assert_same_fingerprint(value: float, scale: float, recorded: float, tolerance: float = REORDER_TOLERANCE) -> None:
    """``value`` equals ``recorded`` to float32 reordering: within ``tolerance`` of ``scale``."""
    diff = abs(value - recorded)
    assert diff <= tolerance * scale, (
        f"fingerprint {value!r} differs from the recorded {recorded!r} by {diff:.3g}, "
        f"{diff / scale:.2g} of its scale {scale:.6g} (allowed: {tolerance:g}, float32 reordering)")
