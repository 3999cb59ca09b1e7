"""Preferences: weight vectors on the probability simplex, in one place.

The bottom floor of the package (it imports torch, numpy and, lazily, pymoo; nothing from
``morl_trl``): every layer that checks, draws or enumerates weights uses it.

* :func:`check_simplex` with the one tolerance :data:`SIMPLEX_ATOL`;
* :func:`sample_preferences`: Dirichlet(alpha), MORL-Baselines' ``"gaussian"`` or the authors' CAPQL
  ``"cone"`` (:func:`sample_cone_preferences`) draws, from a
  :class:`torch.Generator` or the global RNG (the env transform and the losses);
* evaluation weight sets: :func:`energy_weights` (the paper's), :func:`uniform_weights`,
  :func:`extreme_weights`.

Example:
    >>> from morl_trl.preferences import check_simplex, energy_weights
    >>> check_simplex(energy_weights(3, 10), 3).shape
    torch.Size([10, 3])
"""

from morl_trl.preferences.sampling import (
    CONE_ANGLE_DEGREES,
    PREFERENCE_DISTRIBUTIONS,
    sample_cone_preferences,
    sample_preferences,
)
from morl_trl.preferences.simplex import SIMPLEX_ATOL, check_simplex
from morl_trl.preferences.weight_sets import energy_weights, extreme_weights, pymoo_energy_weights, uniform_weights

__all__ = [
    "SIMPLEX_ATOL",
    "check_simplex",
    "PREFERENCE_DISTRIBUTIONS",
    "sample_preferences",
    "sample_cone_preferences",
    "CONE_ANGLE_DEGREES",
    "energy_weights",
    "uniform_weights",
    "extreme_weights",
    "pymoo_energy_weights",
]
