"""Reporting: reference data (frozen bounds and specialist fronts), the paper's table, run reports.

* :class:`DomainReference`, :func:`load_domain_reference`, :func:`load_generalist_fronts`,
  :func:`read_front_csv`, :func:`write_front_csv` (:mod:`morl_trl.reporting.reference`);
* the paper's NHGR table recomputed from fronts (:mod:`morl_trl.reporting.table`, ``morl-trl reference-table``);
* the end-of-run ``report.md`` (:mod:`morl_trl.reporting.report`).

Built on :mod:`morl_trl.metrics` (the mathematics) and :mod:`morl_trl.preferences`.

Example:
    >>> from morl_trl.reporting import DomainReference
    >>> ref = DomainReference.from_fronts("ToyDR-v0", {"Toy-v0": [[2.0, 0.0], [0.0, 2.0], [1.5, 1.5]]})
    >>> ref.nhgr("Toy-v0", [[0.75, 0.75]])
    0.25
"""

from morl_trl.reporting.reference import (PACKAGED_REFERENCE, DomainReference, list_reference_domains,
                                          load_domain_reference, load_generalist_fronts, load_reference, pack_reference,
                                          read_front_csv, write_front_csv)

__all__ = ["PACKAGED_REFERENCE", "DomainReference", "list_reference_domains", "load_domain_reference",
           "load_generalist_fronts", "load_reference", "pack_reference", "read_front_csv", "write_front_csv"]
