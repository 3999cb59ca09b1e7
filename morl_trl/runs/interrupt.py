"""Stopping a run by a signal: the first finishes the current batch and checkpoints, the second exits at once.

:class:`GracefulInterrupt` replaces the handlers of SIGINT (Ctrl-C), SIGTERM (``kill``,
``timeout``, SLURM's preemption, ``docker stop``) and SIGHUP (a closed terminal) while a run
trains (in the main thread only; elsewhere it does nothing): the first signal only sets
:attr:`~GracefulInterrupt.requested` and says what will happen; the training loop checks it
after each batch, writes a checkpoint and raises :class:`RunInterrupted` (a
``KeyboardInterrupt``) naming the command that resumes. A second signal raises
:class:`RunInterrupted` at once. The exit status is the shell's for the signal: 130 (SIGINT),
143 (SIGTERM), 129 (SIGHUP) (:attr:`RunInterrupted.exit_code`).

Example:
    >>> with GracefulInterrupt() as interrupt:
    ...     interrupt.requested, interrupt.signal_name
    (False, 'SIGINT')
"""

from __future__ import annotations

import signal
import threading

from tqdm.auto import tqdm

__all__ = ["GracefulInterrupt", "RunInterrupted", "SecondSignal", "SIGNALS", "signal_name"]

#: the signals a run stops on cleanly (those of them this platform has)
SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


def signal_name(signum: int) -> str:
    """``"SIGTERM"`` for ``signal.SIGTERM``."""
    return signal.Signals(signum).name


class RunInterrupted(KeyboardInterrupt):
    """The run stopped at a signal (Ctrl-C, SIGTERM, SIGHUP); the message says how to resume.

    Attributes:
        signum: the signal (``signal.SIGINT`` for Ctrl-C).
        exit_code: ``128 + signum`` (130, 143, 129), what a shell reports for that signal.
    """

    def __init__(self, message: str = "", signum: int = signal.SIGINT) -> None:
        super().__init__(message)
        self.signum = int(signum)

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


class SecondSignal(KeyboardInterrupt):
    """A second signal: the run exits at once (the session says which checkpoint it resumes from)."""

    def __init__(self, signum: int) -> None:
        super().__init__(f"interrupted by a second {signal_name(signum)}")
        self.signum = int(signum)

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


class GracefulInterrupt:
    """The signal handlers of a running training (a context manager; see the module docstring)."""

    def __init__(self, message: str | None = None) -> None:
        self.message = message
        self.requested = False
        self.count = 0
        self.signum = int(signal.SIGINT)
        self._previous: dict[int, object] = {}

    @property
    def signal_name(self) -> str:
        return signal_name(self.signum)

    def _handle(self, signum, frame) -> None:
        self.count += 1
        if self.requested:
            raise SecondSignal(signum)
        self.requested = True
        self.signum = int(signum)
        again = "press Ctrl-C again" if signum == signal.SIGINT else f"send {self.signal_name} again"
        what = "Ctrl-C" if signum == signal.SIGINT else self.signal_name
        tqdm.write(self.message or f"{what}: stopping after this batch and writing a checkpoint ({again} to exit at once)")

    def __enter__(self) -> "GracefulInterrupt":
        if threading.current_thread() is threading.main_thread():
            for signum in SIGNALS:
                try:
                    self._previous[signum] = signal.signal(signum, self._handle)
                except (ValueError, OSError):  # (not the main interpreter)
                    pass
        return self

    def __exit__(self, *exc) -> None:
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)
        self._previous = {}
