"""morl_trl.data: replay-buffer components TorchRL lacks on some builds.

* :class:`TorchPrioritizedSampler` -- prioritized replay on pure-torch segment trees,
  a drop-in :class:`torchrl.data.PrioritizedSampler` that needs no C++ extension.
* :class:`RunningMaxPrioritizedSampler` -- MORL-Baselines' priority rule (the authors' Envelope).
* :func:`prioritized_sampler` -- TorchRL's native sampler when it loads, else the above.
* :func:`normalize_device` -- compare devices only in this form (``"cuda" != "cuda:0"``).
"""

from morl_trl.data.prioritized import (
    RunningMaxPrioritizedSampler,
    TorchPrioritizedSampler,
    native_prioritized_sampler_available,
    normalize_device,
    prioritized_sampler,
)
from morl_trl.data.segment_tree import MinSegmentTree, SumSegmentTree

__all__ = [
    "MinSegmentTree",
    "RunningMaxPrioritizedSampler",
    "SumSegmentTree",
    "TorchPrioritizedSampler",
    "native_prioritized_sampler_available",
    "normalize_device",
    "prioritized_sampler",
]
