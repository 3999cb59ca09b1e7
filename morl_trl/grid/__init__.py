"""The paper's experiment grid: every algorithm × domain × seed, on Ray, resumable, one table at the end.

* :class:`GridSpec`, :class:`Cell`, :func:`load_grid_spec` (:mod:`morl_trl.grid.spec`): what to run;
* :func:`run_grid` (:mod:`morl_trl.grid.runner`): each cell a ``morl-trl train`` run, as a Ray Tune
  trial (resources per run, retries, clusters), resumed from our checkpoints;
* :func:`grid_status` (:mod:`morl_trl.grid.status`): where each cell stands, from the files;
* :func:`grid_report` (:mod:`morl_trl.grid.report`): the paper's table from the finished cells (the code of
  ``morl-trl reference-table``), beside the paper's values and the floors, and learning curves per domain.

``morl-trl grid`` is the command line. Ray is the ``grid`` extra (``pip install "morl-trl[grid]"``).

Example:
    >>> from morl_trl.grid import GridSpec
    >>> spec = GridSpec.from_dict({"algorithms": ["envelope"], "domains": ["MOLavaGridDR-v0"], "seeds": [0, 1]})
    >>> len(spec.cells())
    2
"""

from morl_trl.grid.spec import QUICK_GRID, Cell, GridSpec, load_grid_spec
from morl_trl.grid.status import CellState, format_status, grid_status

__all__ = ["QUICK_GRID", "Cell", "CellState", "GridSpec", "load_grid_spec", "grid_status", "format_status",
           "run_grid", "grid_report"]


def run_grid(*args, **kwargs):
    """:func:`morl_trl.grid.runner.run_grid` (imported on use: it needs Ray)."""
    from morl_trl.grid.runner import run_grid as _run

    return _run(*args, **kwargs)


def grid_report(*args, **kwargs):
    """:func:`morl_trl.grid.report.grid_report`."""
    from morl_trl.grid.report import grid_report as _report

    return _report(*args, **kwargs)
