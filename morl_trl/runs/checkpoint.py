"""Checkpoints that hold everything a run needs to continue, verified before they are used.

A checkpoint is a directory ``checkpoints/frames_<N>/`` with ``state.pt`` (networks,
optimizers, target params, schedules, the env's and transforms' running state, the
collector's carried TensorDict, RNG states, counters), ``buffer/`` (the replay buffer,
TorchRL's own ``dumps`` format) and ``manifest.json`` (the size and SHA-256 of every other
file, written last). It is written to a temporary directory and renamed into place, so a
kill mid-write leaves the previous checkpoint intact; ``latest`` names the newest one.

The ``keep`` newest checkpoints are kept, and only the newest holds the replay buffer (by far
the largest part): once a newer checkpoint is complete, an older one's manifest is rewritten
(atomically) to record ``"buffer": "pruned"`` and list its remaining files, then its
``buffer/`` is deleted. A pruned checkpoint still verifies; loading it leaves the replay
buffer empty (:func:`checkpoint_buffer` says which case a checkpoint is).

Before a checkpoint is used it is verified against its manifest, reading its files only
(:func:`verify_checkpoint`); :func:`find_checkpoint` falls back to the newest intact one and
says which it skipped and why.
"""

from __future__ import annotations

import hashlib
import json
import os
import random
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import torch

__all__ = ["save_checkpoint", "load_checkpoint", "latest_checkpoint", "find_checkpoint", "verify_checkpoint",
           "checkpoint_frames", "checkpoint_buffer", "rng_state", "set_rng_state", "MANIFEST"]

MANIFEST = "manifest.json"


def rng_state() -> dict[str, Any]:
    """Python's, NumPy's and torch's global generator states."""
    state = {"python": random.getstate(), "numpy": np.random.get_state(), "torch": torch.get_rng_state()}
    if torch.cuda.is_available():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


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
    tmp = directory / f".{MANIFEST}.tmp"
    tmp.write_text(json.dumps(manifest, indent=1, sort_keys=True))
    os.replace(tmp, directory / MANIFEST)


def _prune_buffer(ckpt: Path) -> None:
    """Drop the replay buffer of an older checkpoint: first its manifest (atomically: it then
    lists only what stays and records ``"buffer": "pruned"``), then ``buffer/``. A kill in
    between leaves an intact checkpoint with a stray, unlisted ``buffer/`` that is never loaded."""
    try:
        manifest = json.loads((ckpt / MANIFEST).read_text())
    except (OSError, ValueError):
        return  # a damaged checkpoint: left as it is for inspection
    if manifest.get("buffer") != "pruned" and ("buffer" in manifest.get("dirs", []) or manifest.get("buffer") == "saved"):
        manifest["files"] = {k: v for k, v in manifest["files"].items() if not k.startswith("buffer/")}
        manifest["dirs"] = [d for d in manifest.get("dirs", []) if d != "buffer" and not d.startswith("buffer/")]
        manifest["buffer"] = "pruned"
        _write_manifest(ckpt, manifest)
    if manifest.get("buffer") == "pruned":
        shutil.rmtree(ckpt / "buffer", ignore_errors=True)


def save_checkpoint(run_dir: str | Path, frames: int, state: dict[str, Any], replay_buffer=None, keep: int = 2) -> Path:
    """Atomically write a checkpoint at ``frames`` (with its manifest), keep the ``keep`` newest
    and the replay buffer in the newest only (see the module docstring)."""
    if isinstance(keep, bool) or not isinstance(keep, int) or keep < 1:
        raise ValueError(f"keep must be an int >= 1, got {keep!r}")
    root = Path(run_dir) / "checkpoints"
    root.mkdir(parents=True, exist_ok=True)
    final = root / f"frames_{frames:012d}"
    tmp = root / f".tmp_frames_{frames:012d}"
    for stale in root.glob(".tmp_frames_*"):  # half-written by a killed process
        shutil.rmtree(stale, ignore_errors=True)
    tmp.mkdir()
    torch.save(state, tmp / "state.pt")
    if replay_buffer is not None:
        replay_buffer.dumps(tmp / "buffer")
    manifest = {
        "frames": int(frames),
        "buffer": "saved" if replay_buffer is not None else "none",
        "files": {p.relative_to(tmp).as_posix(): {"size": p.stat().st_size, "sha256": _sha256(p)} for p in _files(tmp)},
        "dirs": sorted(p.relative_to(tmp).as_posix() for p in tmp.rglob("*") if p.is_dir()),
    }
    (tmp / MANIFEST).write_text(json.dumps(manifest, indent=1, sort_keys=True))  # last: its presence = complete
    shutil.rmtree(final, ignore_errors=True)
    os.replace(tmp, final)
    latest = root / "latest"
    tmp_link = root / ".latest_tmp"
    tmp_link.write_text(final.name)
    os.replace(tmp_link, latest)
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


def verify_checkpoint(path: str | Path) -> str | None:
    """``None`` if the checkpoint matches its manifest (every file present, same size and
    SHA-256, nothing missing), else what is wrong. Files are only read."""
    path = Path(path)
    manifest_file = path / MANIFEST
    if not manifest_file.is_file():
        return f"no {MANIFEST} (an incomplete write, or a checkpoint of an older version)"
    try:
        manifest = json.loads(manifest_file.read_text())
        files = manifest["files"]
    except (OSError, ValueError, KeyError, TypeError) as err:
        return f"unreadable {MANIFEST}: {err}"
    if "state.pt" not in files:
        return f"{MANIFEST} lists no state.pt"
    for d in manifest.get("dirs", []):
        if not (path / d).is_dir():
            return f"{d}/ is missing"
    for rel, want in files.items():
        f = path / rel
        if not f.is_file():
            return f"{rel} is missing"
        size = f.stat().st_size
        if size != want["size"]:
            return f"{rel} has {size} bytes; {want['size']} were written"
        if _sha256(f) != want["sha256"]:
            return f"{rel} does not match its checksum"
    return None


def _candidates(run_dir: Path) -> list[Path]:
    root = run_dir / "checkpoints"
    found = sorted((p for p in root.glob("frames_*") if p.is_dir()), reverse=True)
    latest = root / "latest"
    if latest.is_file():
        named = root / latest.read_text().strip()
        if named in found:  # the one `latest` names first, then the others newest first
            found.remove(named)
            found.insert(0, named)
    return found


def find_checkpoint(run_dir: str | Path) -> tuple[Path | None, list[tuple[Path, str]]]:
    """The newest intact checkpoint of a run (``None`` if there is none) and the damaged ones
    skipped on the way, each with what is wrong."""
    skipped = []
    for cand in _candidates(Path(run_dir)):
        problem = verify_checkpoint(cand)
        if problem is None:
            return cand, skipped
        skipped.append((cand, problem))
    return None, skipped


def latest_checkpoint(run_dir: str | Path) -> Path | None:
    """The newest intact checkpoint directory of a run, or ``None``."""
    return find_checkpoint(run_dir)[0]


def load_checkpoint(path: str | Path, replay_buffer=None, map_location=None) -> dict[str, Any]:
    """Read ``state.pt`` (and refill ``replay_buffer`` in place, if given and the checkpoint
    holds one: see :func:`checkpoint_buffer`) of a verified checkpoint."""
    path = Path(path)
    state = torch.load(path / "state.pt", weights_only=False, map_location=map_location)
    if replay_buffer is not None and checkpoint_buffer(path) == "saved":  # (verified: present as written)
        replay_buffer.loads(path / "buffer")
    return state
