"""No write leaves the run directory: symbolic links inside a run are refused, never followed.

A run directory someone shares (or a folder on a shared cluster) may hold symlinks planted at
the paths morl_trl writes (``.lock`` -> a user's file, ``reevaluation/`` -> another folder):
followed, a write would truncate, append to or overwrite their targets. So

* every writer takes the run's lock first (:class:`~morl_trl.runs.lock.RunLock`), which scans
  the run directory and refuses it if it holds a symlink (:func:`refuse_links`);
* the files morl_trl writes are opened with ``O_NOFOLLOW`` (:func:`open_nofollow`; a new file
  also with ``O_EXCL``), after a check that no folder between the run directory and the file is
  a symlink (:func:`check_no_links`).

Either way the error is a :class:`SymlinkRefusedError` naming the link and its target, and the
target is untouched. The run directory itself may be a symlink (e.g. ``runs/`` -> a scratch
disk): that is the user's own choice, made outside the run.

Example:
    >>> import os, tempfile, pathlib
    >>> run = pathlib.Path(tempfile.mkdtemp())
    >>> os.symlink("/etc/hostname", run / "log.txt")
    >>> try:
    ...     open_nofollow(run / "log.txt", "a", root=run)
    ... except SymlinkRefusedError as err:
    ...     print(str(err).split(":")[0])
    refusing to write through a symbolic link
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

__all__ = ["SymlinkRefusedError", "check_no_links", "open_nofollow", "refuse_links"]

_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_MODES = {"a": os.O_WRONLY | os.O_CREAT | os.O_APPEND, "w": os.O_WRONLY | os.O_CREAT | os.O_TRUNC,
          "x": os.O_WRONLY | os.O_CREAT | os.O_EXCL}

#: symlinks a logger makes inside ``logs/`` (W&B's ``latest-run``): its own, never written through by morl_trl
LOGGER_LINKS = ("latest-run",)


class SymlinkRefusedError(ValueError):
    """A path morl_trl would write inside a run directory is (or passes through) a symbolic link."""


def _refuse(link: Path) -> SymlinkRefusedError:
    try:
        target = os.readlink(link)
    except OSError:
        target = "?"
    return SymlinkRefusedError(
        f"refusing to write through a symbolic link: {str(link)!r} -> {target!r} (a write would change the link's "
        f"target, outside the run); remove the link (rm {str(link)!r}), then try again")


def check_no_links(path: str | Path, root: str | Path | None = None) -> None:
    """:class:`SymlinkRefusedError` if ``path`` or a folder between ``root`` and it is a symlink
    (``root`` itself may be one; without ``root``, or for a path outside it, only ``path`` is checked)."""
    path = Path(path)
    rel = None
    if root is not None:
        try:
            rel = path.relative_to(root)
        except ValueError:
            pass
    parts = [Path(root).joinpath(*rel.parts[: i + 1]) for i in range(len(rel.parts))] if rel else [path]
    for p in parts:
        if p.is_symlink():
            raise _refuse(p)


def open_nofollow(path: str | Path, mode: str = "a", *, root: str | Path | None = None, newline: str | None = None,
                  binary: bool = False):
    """``open(path, mode)`` (``"a"``, ``"w"`` or ``"x"``) that refuses a symlink at ``path`` (``O_NOFOLLOW``)
    or between ``root`` and it (:func:`check_no_links`)."""
    path = Path(path)
    check_no_links(path, root)
    try:
        fd = os.open(path, _MODES[mode] | _NOFOLLOW | getattr(os, "O_CLOEXEC", 0), 0o644)
    except OSError as err:
        if err.errno == errno.ELOOP or path.is_symlink():
            raise _refuse(path) from None
        raise
    return os.fdopen(fd, ("a" if mode == "a" else "w") + ("b" if binary else ""),
                     **({} if binary else {"newline": newline}))


def refuse_links(run_dir: str | Path) -> None:
    """:class:`SymlinkRefusedError` naming the first symlink found inside ``run_dir`` (the
    folder itself may be one; the loggers' own links, :data:`LOGGER_LINKS`, are left alone)."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        return
    for folder, dirs, files in os.walk(run_dir):  # (never follows a link: followlinks=False)
        for name in sorted(dirs + files):
            p = Path(folder) / name
            if name not in LOGGER_LINKS and p.is_symlink():
                raise _refuse(p)
