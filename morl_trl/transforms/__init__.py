"""TorchRL transforms for contextual multi-objective RL.

Compose them in a :class:`~torchrl.envs.TransformedEnv` like TorchRL's own transforms:

* :class:`DomainRandomization` -- a new context per sub-env at each of its resets;
* :class:`StateActionHistory` -- ``(s_{t-2}, a_{t-2}, s_{t-1}, a_{t-1}, s_t)`` (paper appendix B);
* :class:`ContextObservation` -- the (normalized) context appended to the observation;
* :class:`PreferenceConditioning` -- a weight vector ``w`` per sub-env and episode under ``"preference"``;
* :class:`LinearScalarization` -- ``w . r`` into a scalar reward;
* :class:`DiscountedVectorReturn` -- the running discounted and undiscounted vector return.
"""

from morl_trl.transforms.context_observation import ContextObservation
from morl_trl.transforms.domain_randomization import DomainRandomization
from morl_trl.transforms.history import StateActionHistory
from morl_trl.transforms.preference import PreferenceConditioning
from morl_trl.transforms.returns import DiscountedVectorReturn
from morl_trl.transforms.scalarization import LinearScalarization

__all__ = [
    "ContextObservation",
    "DiscountedVectorReturn",
    "DomainRandomization",
    "LinearScalarization",
    "PreferenceConditioning",
    "StateActionHistory",
]
