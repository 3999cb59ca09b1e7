"""Checkpoints that hold everything a run needs to continue, verified before they are used.

A checkpoint is a directory ``checkpoints/frames_<N>/`` with ``state.pt`` (networks,
optimizers, target params, schedules, the env's and transforms' running state, the
collector's carried TensorDict, RNG states, counters), ``buffer.pt`` (the replay buffer's
``state_dict()``: storage, sampler, writer) and ``manifest.json`` (``"format": 2``, the size
and SHA-256 of every other file, written last). Both ``.pt`` files hold tensors and plain data
only (:mod:`morl_trl.runs.plain`) and are read with ``torch.load(weights_only=True)``: nothing
in a run directory is unpickled, so a shared run cannot run code on the machine that loads it.
Every file is fsynced in a temporary directory that is renamed into place (and the directory
fsynced), so a kill or a power cut mid-write leaves the previous checkpoint intact; ``latest``
names the newest one. A write that fails (a full disk) removes its temporary directory and
raises an ``OSError`` naming the checkpoint (:class:`~morl_trl.runs.atomic.DiskFullError`).

Checkpoints of format 1 (before 2026-11-26: pickled ``state.pt``, TorchRL's ``buffer/`` dump
with ``prefetch.pkl``) are refused (:class:`UntrustedCheckpointError`) unless the caller says
it trusts them (``trust_pickle=True``, ``--trust-pickle``: a warning says what that means), or
after a one-time conversion (``morl-trl convert-run RUN``, :func:`convert_checkpoint`).

The ``keep`` newest checkpoints are kept, and only the newest holds the replay buffer (by far
the largest part): once a newer checkpoint is complete, an older one's manifest is rewritten
(atomically) to record ``"buffer": "pruned"`` and list its remaining files, then its
``buffer/`` is deleted. A pruned checkpoint still verifies; loading it leaves the replay
buffer empty (:func:`checkpoint_buffer` says which case a checkpoint is).

Before a checkpoint is used it is verified against its manifest, reading its files only
(:func:`verify_checkpoint`); :func:`find_checkpoint` falls back to the newest intact one and
says which it skipped and why.

Example:
    >>> import tempfile, torch
    >>> run = tempfile.mkdtemp()
    >>> path = save_checkpoint(run, 64, {"weights": torch.ones(2), "frames": 64})
    >>> path.name, verify_checkpoint(path), checkpoint_format(path)
    ('frames_000000000064', None, 2)
    >>> load_checkpoint(path)["frames"]
    64
"""

from __future__ import annotations

import hashlib
import json
import os
import random
import shutil
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import torch

from morl_trl.runs.atomic import atomic_write_text, disk_error, fsync_dir, fsync_tree
from morl_trl.runs.nofollow import check_no_links, open_nofollow
from morl_trl.runs.plain import UnsafeFileError, first_line, load_plain, save_plain

__all__ = ["save_checkpoint", "load_checkpoint", "latest_checkpoint", "find_checkpoint", "verify_checkpoint",
           "checkpoint_frames", "checkpoint_buffer", "checkpoint_format", "convert_checkpoint", "rng_state",
           "set_rng_state", "check_rng_state", "MANIFEST", "FORMAT", "UntrustedCheckpointError", "DamagedCheckpointError", "check_state",
           "damaged"]

MANIFEST = "manifest.json"
#: the checkpoint format written now (2: tensors and plain data only; 1: pickled, before 2026-11-26)
FORMAT = 2


class DamagedCheckpointError(ValueError):
    """A checkpoint whose files match their manifest but do not hold what morl_trl writes (edited, or another run's)."""


class UntrustedCheckpointError(UnsafeFileError):
    """A checkpoint of the old pickled format, refused because loading it could run code."""


def rng_state() -> dict[str, Any]:
    """Python's, NumPy's and torch's global generator states."""
    state = {"python": random.getstate(), "numpy": np.random.get_state(), "torch": torch.get_rng_state()}
    if torch.cuda.is_available():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def check_rng_state(path: Path, state: Any) -> None:
    """:class:`DamagedCheckpointError` unless ``state`` (of checkpoint ``path``) is one :func:`set_rng_state`
    takes; the generators are left as they were."""
    now = rng_state()
    try:
        set_rng_state(state)
    except (KeyError, TypeError, AttributeError, RuntimeError, IndexError, ValueError) as err:
        raise damaged(Path(path), f"its random generator states are not what morl_trl writes ({first_line(err)})"
                      ) from None
    finally:
        set_rng_state(now)


def set_rng_state(state: dict[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    torch.set_rng_state(state["torch"])
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["cuda"])


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:  # read-only: verifying never changes a checkpoint
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _files(root: Path) -> list[Path]:
    return sorted(p for p in root.rglob("*") if p.is_file() and p.name != MANIFEST)


def checkpoint_frames(path: str | Path) -> int:
    """The frame count in a checkpoint directory's name (``frames_<N>``)."""
    return int(Path(path).name.split("_")[-1])


def _write_manifest(directory: Path, manifest: dict[str, Any]) -> None:
    atomic_write_text(directory / MANIFEST, json.dumps(manifest, indent=1, sort_keys=True))


def _is_buffer(rel: str) -> bool:
    return rel == "buffer.pt" or rel.startswith("buffer/")


def _prune_buffer(ckpt: Path) -> None:
    """Drop the replay buffer of an older checkpoint: first its manifest (atomically: it then
    lists only what stays and records ``"buffer": "pruned"``), then ``buffer/``. A kill in
    between leaves an intact checkpoint with a stray, unlisted ``buffer/`` that is never loaded."""
    try:
        manifest = json.loads((ckpt / MANIFEST).read_text())
    except (OSError, ValueError):
        return  # a damaged checkpoint: left as it is for inspection
    if manifest.get("buffer") != "pruned" and ("buffer" in manifest.get("dirs", []) or manifest.get("buffer") == "saved"):
        manifest["files"] = {k: v for k, v in manifest["files"].items() if not _is_buffer(k)}
        manifest["dirs"] = [d for d in manifest.get("dirs", []) if d != "buffer" and not d.startswith("buffer/")]
        manifest["buffer"] = "pruned"
        _write_manifest(ckpt, manifest)
    if manifest.get("buffer") == "pruned":
        shutil.rmtree(ckpt / "buffer", ignore_errors=True)
        (ckpt / "buffer.pt").unlink(missing_ok=True)


def _save_pt(obj: Any, path: Path) -> None:
    with open_nofollow(path, "x", binary=True) as fh:  # (a new file, in a folder this process just made)
        save_plain(obj, fh)


def save_checkpoint(run_dir: str | Path, frames: int, state: dict[str, Any], replay_buffer=None, keep: int = 2) -> Path:
    """Atomically write a checkpoint at ``frames`` (with its manifest), keep the ``keep`` newest
    and the replay buffer in the newest only (see the module docstring).

    ``state`` may hold tensors, plain data, TensorDicts and NumPy values (anything else is a
    ``TypeError`` before anything is written). A failed write (``OSError``, e.g. a full disk)
    leaves the previous checkpoints as they were and names the checkpoint it could not write."""
    if isinstance(keep, bool) or not isinstance(keep, int) or keep < 1:
        raise ValueError(f"keep must be an int >= 1, got {keep!r}")
    run_dir = Path(run_dir)
    root = run_dir / "checkpoints"
    final = root / f"frames_{frames:012d}"
    tmp = root / f".tmp_frames_{frames:012d}"
    for path in (final, root / "latest"):  # (checkpoints/, the checkpoint itself, latest: never a symlink)
        check_no_links(path, run_dir)
    try:
        root.mkdir(parents=True, exist_ok=True)
        for stale in root.glob(".tmp_frames_*"):  # half-written by a killed process (a planted link: only it goes)
            stale.unlink() if stale.is_symlink() else shutil.rmtree(stale, ignore_errors=True)
        tmp.mkdir()
        _save_pt(state, tmp / "state.pt")
        if replay_buffer is not None:
            _save_pt(replay_buffer.state_dict(), tmp / "buffer.pt")
        manifest = {
            "format": FORMAT,
            "frames": int(frames),
            "buffer": "saved" if replay_buffer is not None else "none",
            "files": {p.relative_to(tmp).as_posix(): {"size": p.stat().st_size, "sha256": _sha256(p)} for p in _files(tmp)},
            "dirs": sorted(p.relative_to(tmp).as_posix() for p in tmp.rglob("*") if p.is_dir()),
        }
        (tmp / MANIFEST).write_text(json.dumps(manifest, indent=1, sort_keys=True))  # last: its presence = complete
        fsync_tree(tmp)
        shutil.rmtree(final, ignore_errors=True)
        os.replace(tmp, final)
        fsync_dir(root)
        atomic_write_text(root / "latest", final.name, root=run_dir)
    except OSError as err:
        shutil.rmtree(tmp, ignore_errors=True)
        raise disk_error(err, f"checkpoint {final}") from err
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    # prune the older ones (newer ones can only be damaged checkpoints a resume skipped: they are
    # left for inspection and replaced when the run reaches their frame)
    older = sorted(p for p in root.glob("frames_*") if p.is_dir() and p.name < final.name)
    drop = max(len(older) - (keep - 1), 0)
    for old in older[:drop]:
        shutil.rmtree(old, ignore_errors=True)
    for old in older[drop:]:  # the kept older ones: the newest checkpoint holds the buffer
        _prune_buffer(old)
    return final


def checkpoint_buffer(path: str | Path) -> str:
    """What a checkpoint holds of the replay buffer: ``"saved"``, ``"pruned"`` (dropped when a
    newer checkpoint was written) or ``"none"`` (none was given, e.g. empty at frame 0)."""
    path = Path(path)
    try:
        manifest = json.loads((path / MANIFEST).read_text())
    except (OSError, ValueError):
        return "none"
    if "buffer" in manifest:
        return manifest["buffer"]
    return "saved" if "buffer" in manifest.get("dirs", []) else "none"  # (a manifest of an older version)


def checkpoint_format(path: str | Path) -> int:
    """The format of a checkpoint (:data:`FORMAT` now; 1: pickled, written before 2026-11-26)."""
    try:
        manifest = json.loads((Path(path) / MANIFEST).read_text())
        fmt = manifest.get("format", 1)
    except (OSError, ValueError, AttributeError):
        return 1
    return fmt if isinstance(fmt, int) and not isinstance(fmt, bool) else 1


def verify_checkpoint(path: str | Path, only: tuple[str, ...] | None = None) -> str | None:
    """``None`` if the checkpoint matches its manifest (every file present, same size and
    SHA-256, nothing missing), else what is wrong. Files are only read. ``only``: check just
    these files (e.g. ``("state.pt",)`` for a reader that needs no replay buffer)."""
    path = Path(path)
    manifest_file = path / MANIFEST
    if not manifest_file.is_file():
        return f"no {MANIFEST} (an incomplete write, or a checkpoint of an older version)"
    try:
        manifest = json.loads(manifest_file.read_text())
        files = manifest["files"]
    except (OSError, ValueError, KeyError, TypeError) as err:
        return f"unreadable {MANIFEST}: {err}"
    if not isinstance(files, dict) or not all(isinstance(w, dict) for w in files.values()):
        return f"unreadable {MANIFEST}: 'files' is not a mapping of file -> size and sha256"
    if "state.pt" not in files:
        return f"{MANIFEST} lists no state.pt"
    for d in manifest.get("dirs", []) if only is None else ():
        if not (path / str(d)).is_dir():
            return f"{d}/ is missing"
    for rel, want in files.items():
        if only is not None and rel not in only:
            continue
        f = path / rel
        if not f.is_file():
            return f"{rel} is missing"
        size = f.stat().st_size
        if size != want.get("size"):
            return f"{rel} has {size} bytes; {want['size']} were written"
        if _sha256(f) != want.get("sha256"):
            return f"{rel} does not match its checksum"
    return None


def _latest_problem(root: Path, found: list[Path]) -> str | None:
    """What is wrong with ``checkpoints/latest`` (``None``: nothing, or there is no such file)."""
    latest = root / "latest"
    if not latest.is_file():
        return None
    try:
        text = latest.read_bytes().decode().strip()
    except UnicodeDecodeError:
        return "is not UTF-8 text (garbled)"
    except OSError as err:
        return f"cannot be read ({err.strerror or err})"
    if root / text not in found:
        return f"names {text[:60]!r}, which is not a checkpoint of this run"
    return None


def _candidates(run_dir: Path) -> list[Path]:
    root = run_dir / "checkpoints"
    found = sorted((p for p in root.glob("frames_*") if p.is_dir()), reverse=True)
    if _latest_problem(root, found) is None and (root / "latest").is_file():
        named = root / (root / "latest").read_text().strip()
        found.remove(named)  # the one `latest` names first, then the others newest first
        found.insert(0, named)
    return found


def find_checkpoint(run_dir: str | Path, only: tuple[str, ...] | None = None,
                    ) -> tuple[Path | None, list[tuple[Path, str]]]:
    """The newest intact checkpoint of a run (``None`` if there is none) and the damaged ones
    skipped on the way, each with what is wrong. ``only``: as in :func:`verify_checkpoint`.

    Safe while the run is going: a checkpoint that a training process deleted or pruned while
    it was being checked is looked for again (the newer one that replaced it is then found)."""
    run_dir = Path(run_dir)
    for _ in range(5):
        skipped = []
        candidates = _candidates(run_dir)
        latest = _latest_problem(run_dir / "checkpoints", candidates)
        if latest is not None:  # (said, then the newest intact checkpoint is used)
            skipped.append((run_dir / "checkpoints" / "latest", f"{latest}; using the newest intact checkpoint "
                                                                 f"instead"))
        for cand in candidates:
            problem = verify_checkpoint(cand, only)
            if problem is None:
                return cand, skipped
            skipped.append((cand, problem))
        if _candidates(run_dir) == candidates:  # nothing changed under us: the skips are real damage
            break
    return None, skipped


def latest_checkpoint(run_dir: str | Path) -> Path | None:
    """The newest intact checkpoint directory of a run, or ``None``."""
    return find_checkpoint(run_dir)[0]


def _refuse_pickle(path: Path) -> UntrustedCheckpointError:
    run = path.parent.parent
    return UntrustedCheckpointError(
        f"checkpoint {str(path)!r} is of the old pickled format (written before 2026-11-26): loading it can run code "
        f"stored in it, so it is refused. If you trust where this run comes from, convert it once with "
        f"`morl-trl convert-run {run}` (or pass --trust-pickle / trust_pickle=True)")


def damaged(path: Path, problem: str) -> DamagedCheckpointError:
    """The one-line error for checkpoint ``path`` whose files are not what morl_trl wrote."""
    return DamagedCheckpointError(
        f"checkpoint {str(path)!r} is damaged: {problem}. Move it out of {str(path.parent)!r} to use the previous "
        f"checkpoint, or start the run again")


#: what :class:`~morl_trl.runs.Run` adds to every checkpoint's state.pt (besides the recipe's own state), and its type
RUN_STATE = {"frames": int, "updates": int, "next_eval": int, "next_ckpt": int, "last_eval": int, "rng": dict}


def check_state(path: Path, state: Any, keys: dict[str, type] = RUN_STATE) -> dict[str, Any]:
    """``state`` (read from ``path/state.pt``) if it has ``keys`` of their types, else :class:`DamagedCheckpointError`."""
    if not isinstance(state, dict):
        raise damaged(path, f"state.pt holds a {type(state).__name__}, not the dict of a checkpoint")
    missing = [k for k in keys if k not in state]
    if missing:
        raise damaged(path, f"state.pt has no {missing} (it holds {sorted(map(str, state))[:8]})")
    wrong = [f"{k} is a {type(state[k]).__name__}, not a {t.__name__}" for k, t in keys.items()
             if not isinstance(state[k], t) or isinstance(state[k], bool)]
    if wrong:
        raise damaged(path, f"in state.pt, {'; '.join(wrong)}")
    return state


def load_checkpoint(path: str | Path, replay_buffer=None, map_location=None, *, trust_pickle: bool = False,
                    keys: dict[str, type] | None = None) -> dict[str, Any]:
    """Read ``state.pt`` (and refill ``replay_buffer`` in place, if given and the checkpoint
    holds one: see :func:`checkpoint_buffer`) of a verified checkpoint, with
    ``torch.load(weights_only=True)``: a file that is not tensors and plain data is refused
    (:class:`~morl_trl.runs.plain.UnsafeFileError`), nothing in it is run.

    A checkpoint of the old pickled format is refused (:class:`UntrustedCheckpointError`)
    unless ``trust_pickle=True``, which loads it with a warning. ``keys``: what ``state.pt`` must
    hold (e.g. :data:`RUN_STATE`; :func:`check_state`), else :class:`DamagedCheckpointError`."""
    path = Path(path)
    if checkpoint_format(path) < 2:
        if not trust_pickle:
            raise _refuse_pickle(path)
        warnings.warn(f"loading the pickled checkpoint {path} (trust_pickle=True): this runs any code stored in it; "
                      f"convert the run once with `morl-trl convert-run {path.parent.parent}`", stacklevel=2)
        state = torch.load(path / "state.pt", weights_only=False, map_location=map_location)
        if replay_buffer is not None and checkpoint_buffer(path) == "saved":  # (verified: present as written)
            replay_buffer.loads(path / "buffer")
        return state
    try:
        state = load_plain(path / "state.pt", map_location=map_location)
        if keys is not None:
            state = check_state(path, state, keys)
        if replay_buffer is not None and checkpoint_buffer(path) == "saved":
            try:
                replay_buffer.load_state_dict(load_plain(path / "buffer.pt", map_location=map_location))
            except (KeyError, TypeError, AttributeError, RuntimeError, IndexError) as err:
                raise damaged(path, f"buffer.pt does not fit this run's replay buffer ({first_line(err)})") from None
    except DamagedCheckpointError:
        raise
    except UnsafeFileError as err:
        raise type(err)(f"{err}. Move checkpoint {str(path)!r} out of {str(path.parent)!r} to use the previous "
                        f"checkpoint") from None
    return state


def convert_checkpoint(path: str | Path, replay_buffer=None) -> Path:
    """Rewrite a pickled (format 1) checkpoint in the current format, in place (atomically: a
    new directory renamed over the old one). Its pickles are loaded once, so call this only for
    a checkpoint you trust. ``replay_buffer``: an empty buffer built as the run's (to read the
    old buffer dump into); ``None`` drops the buffer (the checkpoint then says ``"pruned"``)."""
    path = Path(path)
    if checkpoint_format(path) >= FORMAT:
        return path
    problem = verify_checkpoint(path)
    if problem is not None:
        raise ValueError(f"checkpoint {str(path)!r} is damaged ({problem}): not converted")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        state = load_checkpoint(path, replay_buffer if checkpoint_buffer(path) == "saved" else None, trust_pickle=True)
    had_buffer = checkpoint_buffer(path)
    new = path.with_name(f".convert_{path.name}")
    shutil.rmtree(new, ignore_errors=True)
    try:
        new.mkdir()
        _save_pt(state, new / "state.pt")
        keep_buffer = replay_buffer is not None and had_buffer == "saved"
        if keep_buffer:
            _save_pt(replay_buffer.state_dict(), new / "buffer.pt")
        manifest = {
            "format": FORMAT, "frames": checkpoint_frames(path),
            "buffer": "saved" if keep_buffer else ("pruned" if had_buffer == "saved" else had_buffer),
            "files": {p.relative_to(new).as_posix(): {"size": p.stat().st_size, "sha256": _sha256(p)} for p in _files(new)},
            "dirs": [], "converted_from": 1,
        }
        (new / MANIFEST).write_text(json.dumps(manifest, indent=1, sort_keys=True))
        fsync_tree(new)
        old = path.with_name(f".old_{path.name}")
        shutil.rmtree(old, ignore_errors=True)
        os.replace(path, old)
        os.replace(new, path)
        fsync_dir(path.parent)
        shutil.rmtree(old, ignore_errors=True)
    except OSError as err:
        shutil.rmtree(new, ignore_errors=True)
        raise disk_error(err, f"converted checkpoint {path}") from err
    return path
