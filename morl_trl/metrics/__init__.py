"""Multi-objective and generalization metrics (maximization throughout).

Fronts are ``[n, k]`` torch tensors or numpy arrays; every metric returns a Python float.

* :func:`pareto_front`, :func:`hypervolume` (exact, ``moocore``), :func:`normalized_hypervolume`
* :func:`eum`, :func:`nhgr`, :func:`eugr`, :func:`sparsity`, :func:`cardinality`, :func:`igd`
* aggregates over runs (rliable's definitions): :func:`interquartile_mean`,
  :func:`optimality_gap`, :func:`stratified_bootstrap_ci`
* normalization bounds: :class:`Bounds`

Weight sets live in :mod:`morl_trl.preferences`; reference data (frozen bounds and specialist
fronts) and the paper's table in :mod:`morl_trl.reporting`.

Example:
    >>> from morl_trl.metrics import hypervolume, nhgr
    >>> hypervolume([[1.0, 2.0], [2.0, 1.0]], ref_point=[0.0, 0.0])
    3.0
    >>> nhgr([[0.5, 0.5]], [[1.0, 1.0]], lower=[0.0, 0.0], upper=[1.0, 1.0])
    0.25
"""

from morl_trl.metrics._arrays import as_points
from morl_trl.metrics.aggregate import interquartile_mean, iqm, mean, median, optimality_gap, stratified_bootstrap_ci
from morl_trl.metrics.bounds import Bounds
from morl_trl.metrics.distance import igd
from morl_trl.metrics.front_stats import cardinality, sparsity
from morl_trl.metrics.generalization import eugr, nhgr
from morl_trl.metrics.hypervolume import hypervolume, normalize, normalized_hypervolume
from morl_trl.metrics.pareto import is_nondominated, pareto_front
from morl_trl.metrics.utility import eum

__all__ = ["pareto_front", "is_nondominated", "hypervolume", "normalize", "normalized_hypervolume", "eum", "nhgr",
           "eugr", "igd", "sparsity", "cardinality", "interquartile_mean", "iqm", "optimality_gap", "mean", "median",
           "stratified_bootstrap_ci", "Bounds", "as_points"]
