"""One writer per run directory: an OS file lock (``fcntl.flock``) on ``<run>/.lock``.

Training, resuming, re-evaluating, exporting and converting hold it for as long as they
write; a second writer gets :class:`RunLockedError` at once, naming the process that holds
the lock and what it is doing. The OS drops the lock when its process ends (even by SIGKILL),
so a killed run never leaves a stale lock. Readers (``load_policy``) take no lock: they read
the newest complete checkpoint, which is never changed once written.

Example:
    >>> import tempfile
    >>> run = tempfile.mkdtemp()
    >>> with RunLock(run, "training"):
    ...     try:
    ...         RunLock(run, "evaluating").acquire()
    ...     except RunLockedError as err:
    ...         print(str(err).split(" (")[0])
    ... # doctest: +ELLIPSIS
    '...' is in use by process ...
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

from morl_trl.runs.nofollow import check_no_links, refuse_links

try:
    import fcntl
except ImportError:  # (Windows: no advisory locks; runs are then unguarded)
    fcntl = None

__all__ = ["RunLock", "RunLockedError", "LOCK_FILE", "lock_holder"]

LOCK_FILE = ".lock"


class RunLockedError(RuntimeError):
    """Another process holds the run directory's lock."""


def lock_holder(run_dir: str | Path) -> dict | None:
    """What the lock file says about its holder (``pid``, ``what``, ``since``), if readable."""
    try:
        info = json.loads((Path(run_dir) / LOCK_FILE).read_text())
    except (OSError, ValueError):
        return None
    return info if isinstance(info, dict) else None


class RunLock:
    """The exclusive lock of ``run_dir`` (a context manager; :meth:`acquire` / :meth:`release`).

    Args:
        run_dir: the run directory (must exist).
        what: what the holder does (``"training"``, ``"evaluating"``, ...), shown to a second writer.
        check_links: refuse a run directory holding a symlink (:func:`~morl_trl.runs.nofollow.refuse_links`).
    """

    def __init__(self, run_dir: str | Path, what: str, *, check_links: bool = True) -> None:
        self.run_dir = Path(run_dir)
        self.what = what
        self.check_links = check_links
        self._fd: int | None = None

    def acquire(self) -> "RunLock":
        if self._fd is not None:
            return self
        if self.check_links:  # every writer locks first: a run holding a symlink is refused before any write
            refuse_links(self.run_dir)
        if fcntl is None:
            return self
        path = self.run_dir / LOCK_FILE
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
        except OSError as err:
            if path.is_symlink():
                check_no_links(path, self.run_dir)  # (SymlinkRefusedError naming it)
            raise OSError(err.errno, f"cannot lock run directory {str(self.run_dir)!r}: {err.strerror}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            holder = lock_holder(self.run_dir) or {}
            pid, what = holder.get("pid", "unknown"), holder.get("what", "writing to it")
            raise RunLockedError(
                f"{str(self.run_dir)!r} is in use by process {pid} ({what}); wait for it to finish or stop it "
                f"(kill {pid}), then try again") from None
        info = json.dumps({"pid": os.getpid(), "what": self.what, "since": time.strftime("%Y-%m-%d %H:%M:%S")})
        os.ftruncate(fd, 0)
        os.pwrite(fd, info.encode(), 0)
        self._fd = fd
        return self

    def release(self) -> None:
        if self._fd is None:
            return
        try:
            os.ftruncate(self._fd, 0)
        except OSError:
            pass
        fcntl.flock(self._fd, fcntl.LOCK_UN)
        os.close(self._fd)
        self._fd = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def __enter__(self) -> "RunLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()
