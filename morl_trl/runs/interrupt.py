"""Ctrl-C during a run: the first finishes the current batch and checkpoints, the second exits at once.

:class:`GracefulInterrupt` replaces the SIGINT handler while a run trains (in the main thread
only; elsewhere it does nothing): the first Ctrl-C only sets :attr:`~GracefulInterrupt.requested`
and says what will happen; the training loop checks it after each batch, writes a checkpoint
and raises :class:`RunInterrupted` (a ``KeyboardInterrupt``) naming the command that resumes.
A second Ctrl-C raises ``KeyboardInterrupt`` at once.

Example:
    >>> with GracefulInterrupt() as interrupt:
    ...     interrupt.requested
    False
"""

from __future__ import annotations

import signal
import threading

from tqdm.auto import tqdm

__all__ = ["GracefulInterrupt", "RunInterrupted"]


class RunInterrupted(KeyboardInterrupt):
    """The run stopped at a user's Ctrl-C after writing a checkpoint; the message says how to resume."""


class GracefulInterrupt:
    """The SIGINT handler of a running training (a context manager; see the module docstring)."""

    def __init__(self, message: str = "Ctrl-C: stopping after this batch and writing a checkpoint "
                                      "(press Ctrl-C again to exit at once)") -> None:
        self.message = message
        self.requested = False
        self.count = 0
        self._previous = None

    def _handle(self, signum, frame) -> None:
        self.count += 1
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        tqdm.write(self.message)

    def __enter__(self) -> "GracefulInterrupt":
        if threading.current_thread() is threading.main_thread():
            try:
                self._previous = signal.signal(signal.SIGINT, self._handle)
            except ValueError:  # (not the main interpreter)
                self._previous = None
        return self

    def __exit__(self, *exc) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None
