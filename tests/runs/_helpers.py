"""Shared by the run tests: tiny MO-LavaGrid settings, a CLI runner, a real SIGKILL."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# MO-LavaGrid (pure tensors: deterministic on CPU), networks and evaluations small enough that a
# run of a few thousand frames takes seconds
TINY = dict(
    frames=512, num_envs=8, frames_per_batch=64, init_random_frames=128, updates_per_batch=2, batch_size=32,
    hidden=(32, 32), eval_interval=256, eval_weights=3, checkpoint_interval=256, buffer_size=4096,
    eval_contexts=("MOLavaGridRoom-v0", "MOLavaGridSnake-v0"), progress=False, eval_random_baseline=False,
)


def train_tiny(run: Path, logger: str = "none", **overrides) -> Path:
    """Train Envelope on MO-LavaGrid at :data:`TINY` (with ``overrides``) into ``run``; returns ``run``."""
    from morl_trl.recipes import resolve_config, train

    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), logger=logger, **{**TINY, **overrides}))
    return run


def write_config(path: Path, **overrides) -> Path:
    values = {**TINY, **overrides}
    path.write_text("\n".join(f"{k} = {json.dumps(list(v) if isinstance(v, tuple) else v)}"
                              for k, v in values.items()) + "\n")
    return path


def env() -> dict:
    out = dict(os.environ)
    out["PYTHONPATH"] = str(ROOT) + os.pathsep + out.get("PYTHONPATH", "")
    out.pop("MORL_TRL_REFERENCE", None)  # (and cwd=/: no ../shared/reference) runs without NHGR
    return out


CWD = "/"


def cli(*args: str, timeout: float = 900) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "morl_trl.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=env(), cwd=CWD)


def run_and_kill(args: list[str], ready, deadline_s: float = 600) -> None:
    """Start ``morl-trl <args>``, wait until ``ready()`` is true, then SIGKILL its process group."""
    proc = subprocess.Popen([sys.executable, "-m", "morl_trl.cli", *map(str, args)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True, env=env(), cwd=CWD)
    deadline = time.time() + deadline_s
    try:
        while time.time() < deadline:
            if ready():
                return
            if proc.poll() is not None:
                raise AssertionError(f"the run ended (rc {proc.returncode}) before it could be killed")
            time.sleep(0.02)
        raise AssertionError("the run did not reach the kill point within the deadline")
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)  # a real kill: no chance to clean up
        proc.wait()
