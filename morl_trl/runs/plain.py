"""Saving run state as tensors and plain data only, loaded without unpickling code.

``torch.load(weights_only=True)`` reads tensors, numbers, strings, ``None``, lists, tuples,
dicts, ``torch.Size``/``dtype``/``device`` and nothing else: a file planted in a run
directory cannot run code when it is read this way. :func:`to_plain` turns what a checkpoint
holds beyond that (TensorDicts, NumPy arrays and scalars, e.g. NumPy's generator state) into
marked dicts of such data, :func:`from_plain` turns them back; anything else is refused when
the checkpoint is *written* (``TypeError`` naming where it is), never found out at load time.

Example:
    >>> import io, numpy as np, torch
    >>> from tensordict import TensorDict
    >>> state = {"td": TensorDict(a=torch.zeros(2), batch_size=[2]), "np": np.arange(3)}
    >>> buf = io.BytesIO(); save_plain(state, buf); _ = buf.seek(0)
    >>> back = load_plain(buf)
    >>> type(back["td"]).__name__, back["np"].tolist()
    ('TensorDict', [0, 1, 2])
"""

from __future__ import annotations

import collections
import errno
import os
import zipfile
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase

__all__ = ["to_plain", "from_plain", "save_plain", "load_plain", "UnsafeFileError", "first_line", "check_inflation",
           "INFLATION_SLACK"]

_MARK = "__morl_trl_plain__"
_ATOMS = (type(None), bool, int, float, complex, str, bytes, torch.Size, torch.dtype, torch.device)


class UnsafeFileError(ValueError):
    """A file that is not tensors and plain data (e.g. a pickle of a Python object): not loaded."""


def to_plain(obj: Any, where: str = "state") -> Any:
    """``obj`` with TensorDicts and NumPy values replaced by marked dicts of tensors and plain data."""
    if isinstance(obj, torch.Tensor):
        return obj
    if isinstance(obj, _ATOMS):
        return obj
    if isinstance(obj, TensorDictBase):
        return {_MARK: "tensordict", "batch_size": list(obj.batch_size),
                "device": None if obj.device is None else str(obj.device),
                "items": {k: to_plain(v, f"{where}[{k!r}]") for k, v in obj.items()}}
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind not in "biuf":
            raise TypeError(f"{where}: a NumPy array of dtype {obj.dtype} cannot be saved as a tensor")
        return {_MARK: "ndarray", "data": torch.from_numpy(np.ascontiguousarray(obj).copy()), "dtype": str(obj.dtype)}
    if isinstance(obj, np.generic):
        return {_MARK: "np_scalar", "value": obj.item(), "dtype": str(obj.dtype)}
    if isinstance(obj, collections.OrderedDict):
        out = collections.OrderedDict((k, to_plain(v, f"{where}[{k!r}]")) for k, v in obj.items())
        if hasattr(obj, "_metadata"):  # (state_dict()s keep versions / TensorDict batch sizes there)
            return {_MARK: "state_dict", "items": out, "metadata": to_plain(obj._metadata, f"{where}._metadata")}
        return out
    if isinstance(obj, dict):
        return {k: to_plain(v, f"{where}[{k!r}]") for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        out = [to_plain(v, f"{where}[{i}]") for i, v in enumerate(obj)]
        return out if isinstance(obj, list) else tuple(out)
    raise TypeError(f"{where}: a {type(obj).__module__}.{type(obj).__qualname__} is not tensors or plain data; "
                    f"give its state_dict() (or numbers, strings, lists, dicts of tensors) instead")


def from_plain(obj: Any) -> Any:
    """The inverse of :func:`to_plain`."""
    if isinstance(obj, dict):
        kind = obj.get(_MARK) if _MARK in obj else None
        if kind == "tensordict":
            return TensorDict({k: from_plain(v) for k, v in obj["items"].items()}, batch_size=obj["batch_size"],
                              device=obj["device"])
        if kind == "ndarray":
            return obj["data"].numpy().astype(obj["dtype"], copy=False)
        if kind == "np_scalar":
            return np.dtype(obj["dtype"]).type(obj["value"])
        if kind == "state_dict":
            out = collections.OrderedDict((k, from_plain(v)) for k, v in obj["items"].items())
            out._metadata = from_plain(obj["metadata"])
            return out
        items = ((k, from_plain(v)) for k, v in obj.items())
        return collections.OrderedDict(items) if isinstance(obj, collections.OrderedDict) else dict(items)
    if isinstance(obj, list):
        return [from_plain(v) for v in obj]
    if isinstance(obj, tuple):
        return tuple(from_plain(v) for v in obj)
    return obj


#: what torch's zip writer says when a write under it fails (it turns ``OSError(ENOSPC)`` into a ``RuntimeError``)
_ZIP_WRITE_FAILED = ("unexpected pos", "PytorchStreamWriter failed", "inline_container")


def _write_failure(file, err: RuntimeError) -> OSError:
    """torch's zip-writer ``RuntimeError`` as the ``OSError`` it hides: ENOSPC when the file's disk is
    (nearly) full, else EIO."""
    path = file if isinstance(file, (str, os.PathLike)) else getattr(file, "name", None)  # (an fd for os.fdopen's)
    code = errno.EIO
    try:
        st = os.fstatvfs(path) if isinstance(path, int) else os.statvfs(os.path.dirname(os.path.abspath(path)))
        code = errno.ENOSPC if st.f_bavail * st.f_frsize < 1 << 20 else errno.EIO
    except (OSError, TypeError):
        pass
    return OSError(code, os.strerror(code) if code == errno.ENOSPC else f"{os.strerror(code)} ({first_line(err)})")


def save_plain(obj: Any, file) -> None:
    """``torch.save(to_plain(obj), file)``: readable by :func:`load_plain` without unpickling code.
    A write that fails under torch's zip writer (a full disk) is an ``OSError`` (``ENOSPC`` when
    the disk is full), never its ``RuntimeError: [enforce fail at inline_container.cc] ... unexpected pos``."""
    plain = to_plain(obj)
    try:
        torch.save(plain, file)
    except RuntimeError as err:
        if not any(s in str(err) for s in _ZIP_WRITE_FAILED):
            raise
        raise _write_failure(file, err) from None


def first_line(err: BaseException, limit: int = 200) -> str:
    """The first line of an error's message (its type's name for an empty one), at most ``limit`` characters:
    what an error about a file shows of torch's (a TensorDict's repr can run to hundreds of lines)."""
    lines = str(err).strip().splitlines()
    text = f"{type(err).__name__}: {lines[0]}" if lines else type(err).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


#: what a file may hold beyond its size on disk (the zip's own headers are counted in that size)
INFLATION_SLACK = 1 << 20


def check_inflation(path: str | os.PathLike) -> None:
    """:class:`UnsafeFileError` if the ``.pt`` file (a zip) at ``path`` would inflate beyond its own
    size on disk (+ :data:`INFLATION_SLACK`): :func:`save_plain` stores every entry uncompressed,
    so a file of ours never does, while a small compressed one can hold gigabytes of zeros. Reads
    the zip's directory only, before anything is allocated."""
    size = os.path.getsize(path)
    try:
        with zipfile.ZipFile(path) as z:
            entries = z.infolist()
    except (zipfile.BadZipFile, OSError, ValueError):
        return  # (not a zip: torch.load refuses it, naming the file)
    total = sum(e.file_size for e in entries)
    if total > size + INFLATION_SLACK:
        packed = sum(e.compress_type != zipfile.ZIP_STORED for e in entries)
        raise UnsafeFileError(
            f"{str(path)!r} would inflate to {total:,} bytes from {size:,} on disk ({packed} compressed entries): a "
            f"file morl_trl writes holds no more than its own size (+ {INFLATION_SLACK:,} bytes), so it is refused "
            f"before anything is allocated; it was not written by morl_trl")


def load_plain(file, map_location=None) -> Any:
    """Read a file written by :func:`save_plain` with ``torch.load(weights_only=True)``;
    :class:`UnsafeFileError` if it holds anything else (nothing in it is executed), or if it is
    empty or damaged (the error names the file and what is wrong)."""
    name = file if isinstance(file, (str, os.PathLike)) else getattr(file, "name", file)  # (the path, not its last part)
    if isinstance(file, (str, os.PathLike)) and os.path.isfile(file) and os.path.getsize(file) == 0:
        raise UnsafeFileError(f"{str(name)!r} is empty (0 bytes): it was cut short or emptied, so it holds nothing "
                              f"to load")
    if isinstance(file, (str, os.PathLike)) and os.path.isfile(file):
        check_inflation(file)
    try:
        data = torch.load(file, weights_only=True, map_location=map_location)
    except Exception as err:  # noqa: BLE001 - torch raises UnpicklingError, RuntimeError, ... for foreign files
        raise UnsafeFileError(f"{str(name)!r} is not a file of tensors and plain data (refused, nothing in it was "
                              f"run): {first_line(err)}") from None
    try:
        return from_plain(data)
    except Exception as err:  # noqa: BLE001 - a marked dict of the wrong layout
        raise UnsafeFileError(f"{str(name)!r} holds tensors and plain data in a layout morl_trl did not write "
                              f"({first_line(err)})") from None
