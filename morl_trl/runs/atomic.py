"""Files written whole or not at all: temp file + fsync + rename + directory fsync.

A reader (or a process that resumes after a kill or a power cut) sees either the old file or
the new one, never half of one. A write that fails (a full disk: ``OSError(ENOSPC)``) removes
its temporary file and leaves the old file as it was; the error names the file.

Example:
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> atomic_write_text(d / "config.json", '{"seed": 0}')
    >>> (d / "config.json").read_text()
    '{"seed": 0}'
"""

from __future__ import annotations

import errno
import os
from pathlib import Path
from typing import Any, Callable

from morl_trl.runs.nofollow import check_no_links, open_nofollow

__all__ = ["atomic_write_bytes", "atomic_write_text", "atomic_write", "fsync_dir", "fsync_tree", "DiskFullError",
           "disk_error"]


class DiskFullError(OSError):
    """A write failed because the disk (or the quota) is full; what was there before is intact."""


def disk_error(err: OSError, what: str) -> OSError:
    """``err`` re-raised as one that names ``what`` was being written (a :class:`DiskFullError`
    for ENOSPC / EDQUOT)."""
    if err.errno in (errno.ENOSPC, errno.EDQUOT):
        return DiskFullError(err.errno, f"disk full while writing {what} ({os.strerror(err.errno)})")
    return OSError(err.errno, f"could not write {what}: {err.strerror or err}")


def fsync_dir(path: str | Path) -> None:
    """Make the entries of directory ``path`` (created, renamed, removed files) durable."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return  # (e.g. a platform without directory fds)
    try:
        os.fsync(fd)
    except OSError:
        pass  # some file systems refuse fsync on directories
    finally:
        os.close(fd)


def fsync_tree(root: str | Path) -> None:
    """fsync every file and directory under ``root`` (before renaming ``root`` into place)."""
    root = Path(root)
    for p in sorted(root.rglob("*")):
        if p.is_file():
            with p.open("rb") as fh:
                os.fsync(fh.fileno())
    for d in sorted((p for p in root.rglob("*") if p.is_dir()), reverse=True):
        fsync_dir(d)
    fsync_dir(root)


def atomic_write(path: str | Path, write: Callable[[Any], None], *, mode: str = "wb", root: str | Path | None = None,
                 **open_kwargs: Any) -> None:
    """Write ``path`` whole or not at all: ``write(fh)`` fills a temporary file beside it, which
    is fsynced and renamed over ``path``, then the directory is fsynced. A symlink at ``path``, at
    the temporary file or between ``root`` and ``path`` is refused (:mod:`morl_trl.runs.nofollow`)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    check_no_links(path, root)
    if os.path.lexists(tmp):  # (a stale one, or a planted link: the link goes, its target stays)
        os.unlink(tmp)
    try:
        with open_nofollow(tmp, "x", binary="b" in mode, **open_kwargs) as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError as err:
        tmp.unlink(missing_ok=True)
        raise disk_error(err, str(path)) from err
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    fsync_dir(path.parent)


def atomic_write_bytes(path: str | Path, data: bytes, *, root: str | Path | None = None) -> None:
    """``path.write_bytes(data)``, atomically (see :func:`atomic_write`)."""
    atomic_write(path, lambda fh: fh.write(data), root=root)


def atomic_write_text(path: str | Path, text: str, *, root: str | Path | None = None) -> None:
    """``path.write_text(text)``, atomically (see :func:`atomic_write`)."""
    atomic_write_bytes(path, text.encode(), root=root)
