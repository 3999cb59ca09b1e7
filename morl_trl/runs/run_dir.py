"""Starting a run in a directory without losing one: checks first, then a swap.

:func:`check_new_run_dir` says, before anything is built or written, whether a new run may
start in a directory (not a file, writable, empty unless ``overwrite`` and then a run
directory). :class:`NewRunDir` then starts it: the new run's first files go into a staging
directory beside it (``.<name>.starting-<pid>``, locked), which is renamed into place only once
the run is built; with ``overwrite`` the old run is first renamed aside (under its own lock:
a run in use by another process is never replaced) and deleted once the new run has written
its first checkpoint (:meth:`NewRunDir.commit`). A start that fails before that puts the old
run back (:meth:`NewRunDir.abort`) and leaves no new directory behind.

Example:
    >>> import tempfile, pathlib
    >>> target = pathlib.Path(tempfile.mkdtemp()) / "run"
    >>> check_new_run_dir(target, overwrite=False)
    >>> start = NewRunDir(target, overwrite=False)
    >>> lock = start.start()
    >>> (target / ".lock").is_file(), lock.held
    (True, True)
    >>> start.commit(); lock.release()
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from morl_trl.runs.atomic import fsync_dir
from morl_trl.runs.lock import LOCK_FILE, RunLock

__all__ = ["check_new_run_dir", "check_writable", "NewRunDir", "run_dir_contents"]


def run_dir_contents(run_dir: Path) -> list[str]:
    """What a run directory holds (its lock file aside)."""
    return sorted(p.name for p in run_dir.iterdir() if p.name != LOCK_FILE)


def check_writable(path: Path, what: str = "run directory") -> None:
    """``ValueError`` unless ``path`` (or, if missing, the folder it would be made in) is a
    writable directory."""
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise ValueError(f"{what} {str(path)!r} cannot be made: {str(probe)!r} is a file, not a folder")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ValueError(f"{what} {str(path)!r} cannot be written: {str(probe)!r} is read-only for this user")


def check_new_run_dir(run_dir: str | Path, overwrite: bool) -> None:
    """``ValueError`` (naming what is wrong and what to do) unless a new run may start in ``run_dir``."""
    run_dir = Path(run_dir)
    if run_dir.exists() and not run_dir.is_dir():
        raise ValueError(f"run directory {str(run_dir)!r} is a file")
    check_writable(run_dir)
    if run_dir.is_dir():
        held = run_dir_contents(run_dir)
        if held and not overwrite:
            raise ValueError(f"run directory {str(run_dir)!r} is not empty (it holds {held[:5]}): continue it with "
                             f"resume={str(run_dir)!r}, replace it with overwrite=True, or choose another run_dir=")
        if held and not (run_dir / "config.json").is_file():  # overwrite deletes runs only, never any other folder
            raise ValueError(f"overwrite=True replaces run directories only; {str(run_dir)!r} has no config.json "
                             f"(it holds {held[:5]}): choose another run_dir=")


class NewRunDir:
    """Starts a new run in ``run_dir`` (see the module docstring): :meth:`start`, then
    :meth:`commit` once the run has a checkpoint, or :meth:`abort` if it failed before."""

    def __init__(self, run_dir: str | Path, overwrite: bool) -> None:
        self.run_dir = Path(run_dir)
        self.overwrite = overwrite
        self._replaced: Path | None = None
        self._old_lock: RunLock | None = None
        self._made: Path | None = None  # the outermost folder this start created
        self.lock: RunLock | None = None

    def start(self) -> RunLock:
        """Put an empty, locked run directory in place; returns its (held) lock."""
        run_dir = self.run_dir
        check_new_run_dir(run_dir, self.overwrite)
        parent = run_dir.parent
        probe = parent
        while not probe.exists():
            self._made = probe
            probe = probe.parent
        parent.mkdir(parents=True, exist_ok=True)
        staging = parent / f".{run_dir.name}.starting-{os.getpid()}"
        if staging.is_symlink():  # (planted: the link goes, its target stays as it is)
            staging.unlink()
        shutil.rmtree(staging, ignore_errors=True)
        staging.mkdir()
        lock = RunLock(staging, "training").acquire()  # (the lock stays with the directory when it is renamed)
        try:
            if run_dir.is_dir() and run_dir_contents(run_dir):  # overwrite (checked above): the old run goes aside
                self._old_lock = RunLock(run_dir, "being replaced", check_links=False).acquire()  # (deleted whole)  # refused if a process uses it
                self._replaced = parent / f".{run_dir.name}.replaced-{os.getpid()}"
                shutil.rmtree(self._replaced, ignore_errors=True)
                os.replace(run_dir, self._replaced)
            try:
                os.replace(staging, run_dir)  # (over an empty directory; a non-empty one is refused)
            except OSError:
                raise ValueError(f"run directory {str(run_dir)!r} was filled by another process while this run "
                                 f"started: choose another run_dir=") from None
            fsync_dir(parent)
        except BaseException:
            lock.release()
            shutil.rmtree(staging, ignore_errors=True)
            self._restore()
            raise
        lock.run_dir = run_dir
        self.lock = lock
        return lock

    def _restore(self) -> None:
        if self._replaced is not None and self._replaced.exists():
            if self.run_dir.exists():
                shutil.rmtree(self.run_dir, ignore_errors=True)
            os.replace(self._replaced, self.run_dir)
        self._replaced = None
        if self._old_lock is not None:
            self._old_lock.release()
            self._old_lock = None

    def commit(self) -> None:
        """The new run has started (its first checkpoint is written): delete the run it replaced."""
        if self._old_lock is not None:
            self._old_lock.release()
            self._old_lock = None
        if self._replaced is not None:
            shutil.rmtree(self._replaced, ignore_errors=True)
            self._replaced = None
        self._made = None

    def abort(self) -> None:
        """The new run failed before its first checkpoint: remove it, put back the run it replaced."""
        if self.lock is not None:
            self.lock.release()
        if self._replaced is not None:
            self._restore()
        else:
            shutil.rmtree(self.run_dir, ignore_errors=True)
        if self._made is not None:
            shutil.rmtree(self._made, ignore_errors=True)
