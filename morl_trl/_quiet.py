"""Narrow filters for dependency output that tells a morl_trl user nothing.

:func:`quiet_dependencies` is installed once by ``import morl_trl`` (before any dependency is
imported); :func:`quiet_gym` holds only while morl_trl itself builds a Gymnasium env (the
command line, ``morl_trl.train()``, ``make_env``), so a user's own ``gymnasium.make`` still
warns as it always did. Each filter names the one message it drops; nothing else from a
dependency is hidden.
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import logging
import sys
import warnings
from collections.abc import Iterator

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


# gymnasium warns when a MO-Gymnasium env declares float64 bounds for a float32 Box (every
# MO-Gymnasium env whose bounds are written as Python floats): nothing a user can act on.
_BOX_PRECISION = r".*Box (low|high)'s precision lowered by casting"


def _import_gym_without_banner() -> None:
    """Import the legacy ``gym`` package (TorchRL's ``MOGymEnv`` imports it to read its version)
    with its 4-line "Gym has been unmaintained since 2022" notice dropped; whatever else it prints
    is passed on."""
    if "gym" in sys.modules or importlib.util.find_spec("gym") is None:
        return
    buffer = io.StringIO()
    with contextlib.redirect_stderr(buffer):
        try:
            import gym  # noqa: F401
        except Exception:  # (a broken install: TorchRL reports it when it needs gym)
            pass
    text = buffer.getvalue()
    try:
        from gym_notices.notices import notices

        for notice in notices.values():
            text = text.replace(f"{notice}\n", "")
    except Exception:
        pass
    if text.strip():
        sys.stderr.write(text)


@contextlib.contextmanager
def quiet_gym() -> Iterator[None]:
    """While morl_trl builds a Gymnasium / MO-Gymnasium env: no gym banner, no Box precision warning."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=_BOX_PRECISION, category=UserWarning)
        _import_gym_without_banner()
        yield
