"""Multi-objective and generalization metrics (maximization throughout).

Fronts are ``[n, k]`` torch tensors or numpy arrays; every metric returns a Python float.

* :func:`pareto_front`, :func:`hypervolume` (exact, ``moocore``), :func:`normalized_hypervolume`
* :func:`eum`, :func:`nhgr`, :func:`eugr`, :func:`sparsity`, :func:`cardinality`
* weight sets: :func:`energy_weights` (the paper's), :func:`uniform_weights`
* aggregates over runs (rliable's definitions): :func:`interquartile_mean`,
  :func:`optimality_gap`, :func:`stratified_bootstrap_ci`
* reference data: :class:`Bounds`, :class:`DomainReference`, :func:`load_domain_reference`

Example:
    >>> from morl_trl.metrics import hypervolume, nhgr
    >>> hypervolume([[1.0, 2.0], [2.0, 1.0]], ref_point=[0.0, 0.0])
    3.0
    >>> nhgr([[0.5, 0.5]], [[1.0, 1.0]], lower=[0.0, 0.0], upper=[1.0, 1.0])
    0.25
"""

from morl_trl.metrics.aggregate import (
    interquartile_mean,
    iqm,
    mean,
    median,
    optimality_gap,
    stratified_bootstrap_ci,
)
from morl_trl.metrics.front_stats import cardinality, sparsity
from morl_trl.metrics.generalization import eugr, nhgr
from morl_trl.metrics.hypervolume import hypervolume, normalize, normalized_hypervolume
from morl_trl.metrics.pareto import is_nondominated, pareto_front
from morl_trl.metrics.reference import (
    Bounds,
    DomainReference,
    list_reference_domains,
    load_domain_reference,
    load_generalist_fronts,
    load_reference,
    read_front_csv,
    write_front_csv,
)
from morl_trl.metrics.utility import eum
from morl_trl.metrics.weights import energy_weights, extreme_weights, uniform_weights

__all__ = [
    "pareto_front",
    "is_nondominated",
    "hypervolume",
    "normalize",
    "normalized_hypervolume",
    "eum",
    "nhgr",
    "eugr",
    "sparsity",
    "cardinality",
    "energy_weights",
    "uniform_weights",
    "extreme_weights",
    "interquartile_mean",
    "iqm",
    "optimality_gap",
    "mean",
    "median",
    "stratified_bootstrap_ci",
    "Bounds",
    "DomainReference",
    "list_reference_domains",
    "load_domain_reference",
    "load_generalist_fronts",
    "load_reference",
    "read_front_csv",
    "write_front_csv",
]
