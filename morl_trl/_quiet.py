"""Narrow filters for dependency output that tells a morl_trl user nothing.

Installed once by ``import morl_trl`` (before any dependency is imported), each filter names
the one message it drops; nothing else from a dependency is hidden.
"""

from __future__ import annotations

import logging
import warnings

# torchrl 0.14 warns when its own collectors module defines its deprecated weight updaters
# (at import, whoever imports it): not about anything morl_trl or its user does.
_TORCHRL_WEIGHT_UPDATER = r"Creating \w+ which inherits from WeightUpdaterBase is deprecated"
# torchrl logs every lazy storage allocation at INFO on stdout, through any progress bar.
_TORCHRL_INFO = ("Initialized LazyTensorStorage",)


class _DropMessages(logging.Filter):
    def __init__(self, prefixes: tuple[str, ...]) -> None:
        super().__init__()
        self.prefixes = prefixes

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith(self.prefixes)


def quiet_dependencies() -> None:
    warnings.filterwarnings("ignore", message=_TORCHRL_WEIGHT_UPDATER, category=DeprecationWarning)
    log = logging.getLogger("torchrl")
    if not any(isinstance(f, _DropMessages) for f in log.filters):
        log.addFilter(_DropMessages(_TORCHRL_INFO))
