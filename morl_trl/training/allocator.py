"""glibc's allocator set for a training process: the memory an update frees is kept for the next one.

Every update allocates and frees the same large temporaries (activations of ``[E, rows, 256]``
floats: 0.5-3 MiB each). With glibc's defaults, blocks above a threshold that moves at run
time are served by ``mmap`` and the top of the heap is handed back to the kernel above another:
the next update faults those pages in again (measured on GPI-PD's update at the paper's
settings: ~3,000 minor page faults and ~15% of the update's CPU time in the kernel; with the
settings below: ~30 and ~0%). :func:`tune_malloc` fixes both thresholds once per process with
``mallopt``: blocks under 32 MiB come from the heap (larger ones, e.g. replay storage, are still
mapped and unmapped on their own), and up to 256 MiB of free heap top is kept.

It is what ``MALLOC_MMAP_THRESHOLD_=33554432 MALLOC_TRIM_THRESHOLD_=268435456`` in the
environment do, set from inside: :func:`~morl_trl.recipes.build_agent` calls it when a
trainer starts. Linux with glibc only (elsewhere it does nothing); ``MORL_TRL_MALLOC=0`` in
the environment turns it off, and a ``MALLOC_MMAP_THRESHOLD_`` or ``MALLOC_TRIM_THRESHOLD_``
the user set wins (nothing is changed then).

Example:
    >>> from morl_trl.training.allocator import tune_malloc
    >>> tune_malloc() in (True, False)  # True: set (Linux, glibc); False: not applicable or turned off
    True
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import platform
import sys

__all__ = ["tune_malloc", "MMAP_THRESHOLD", "TRIM_THRESHOLD", "DISABLE_VARIABLE"]

#: blocks under this many bytes are served from the heap (glibc's ``M_MMAP_THRESHOLD``; its own cap is 32 MiB)
MMAP_THRESHOLD = 32 << 20
#: free memory at the heap's top kept up to this many bytes (glibc's ``M_TRIM_THRESHOLD``)
TRIM_THRESHOLD = 256 << 20
#: ``MORL_TRL_MALLOC=0`` (or ``off``, ``false``, ``no``) leaves the allocator as it is
DISABLE_VARIABLE = "MORL_TRL_MALLOC"

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # <malloc.h>
_state: dict = {}


def tune_malloc() -> bool:
    """Set glibc's mmap and trim thresholds (see the module) once per process; ``True`` when set.

    ``False`` when not on Linux with glibc, when ``MORL_TRL_MALLOC`` is ``0``/``off``/``false``/``no``,
    or when the user set ``MALLOC_MMAP_THRESHOLD_`` or ``MALLOC_TRIM_THRESHOLD_`` (theirs are kept).
    """
    if "done" in _state:
        return _state["done"]
    _state["done"] = done = _tune()
    return done


def _tune() -> bool:
    if os.environ.get(DISABLE_VARIABLE, "").strip().lower() in ("0", "off", "false", "no"):
        return False
    if "MALLOC_MMAP_THRESHOLD_" in os.environ or "MALLOC_TRIM_THRESHOLD_" in os.environ:
        return False
    if not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc":
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    # (setting the trim threshold alone would also stop the mmap threshold from moving up from 128 KiB)
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
