"""``morl-trl convert-run RUN``: rewrite a run's pickled checkpoints (format 1, written before
2026-11-26) as tensors and plain data (format 2), once, so that loading it never unpickles. (Parameters saved in
an older layout are converted when an agent loads them: :mod:`morl_trl.training.state_upgrade`.)

Converting loads the old pickles one last time: do it only for a run you trust (your own, or
one from a source you trust). Each checkpoint is replaced atomically; the newest keeps its
replay buffer (read into a buffer built from the run's config), the others stay as they were
(pruned).

Example:
    >>> from morl_trl.recipes.convert import convert_run
    >>> convert_run("runs/old_run")  # doctest: +SKIP
    ['frames_000000000256']
"""

from __future__ import annotations

from pathlib import Path

import torch

from morl_trl.recipes.config import TrainConfig
from morl_trl.runs.checkpoint import FORMAT, checkpoint_buffer, checkpoint_format, convert_checkpoint, verify_checkpoint

__all__ = ["convert_run"]


def convert_run(run_dir: str | Path) -> list[str]:
    """Convert every intact pickled checkpoint of ``run_dir``; returns the names converted
    (damaged ones are left as they are and named in a ``ValueError`` if none could be converted)."""
    from morl_trl.recipes.off_policy import make_replay_buffer
    from morl_trl.runs.lock import RunLock

    run_dir = Path(run_dir)
    if not (run_dir / "config.json").is_file():
        raise ValueError(f"{str(run_dir)!r} is not a run directory (no config.json)")
    cfg = TrainConfig.load(run_dir / "config.json")
    done, damaged = [], []
    with RunLock(run_dir, "converting"):
        for ckpt in sorted((run_dir / "checkpoints").glob("frames_*")):
            if not ckpt.is_dir() or checkpoint_format(ckpt) >= FORMAT:
                continue
            problem = verify_checkpoint(ckpt)
            if problem is not None:
                damaged.append(f"{ckpt.name}: {problem}")
                continue
            buffer = make_replay_buffer(cfg, torch.device("cpu")) if checkpoint_buffer(ckpt) == "saved" else None
            convert_checkpoint(ckpt, buffer)
            done.append(ckpt.name)
    if damaged and not done:
        raise ValueError(f"nothing converted in {str(run_dir)!r}: " + "; ".join(damaged))
    return done
