"""What every training run needs, whatever its algorithm: the run itself (:class:`Run`: its
directory, resume, schedules, progress, report), its logs (:class:`RunLog`), checkpoints that
hold everything to continue (tensors and plain data only, read without unpickling), a lock per
run directory, atomic writes, and RNG states.

Recipes (:mod:`morl_trl.recipes`) use these; a custom trainer can too.
"""

from morl_trl.runs.atomic import DiskFullError, atomic_write_bytes, atomic_write_text
from morl_trl.runs.checkpoint import (
    UntrustedCheckpointError,
    checkpoint_buffer,
    checkpoint_format,
    checkpoint_frames,
    convert_checkpoint,
    find_checkpoint,
    latest_checkpoint,
    load_checkpoint,
    rng_state,
    save_checkpoint,
    set_rng_state,
    verify_checkpoint,
)
from morl_trl.runs.env_state import env_state, load_env_state
from morl_trl.runs.lock import RunLock, RunLockedError
from morl_trl.runs.plain import UnsafeFileError, load_plain, save_plain
from morl_trl.runs.run import RUN_DIR_PATTERN, Run, default_run_dir
from morl_trl.runs.run_log import RunLog, check_logger

__all__ = ["DiskFullError", "RUN_DIR_PATTERN", "Run", "RunLock", "RunLockedError", "RunLog", "UnsafeFileError",
           "UntrustedCheckpointError", "atomic_write_bytes", "atomic_write_text", "check_logger", "checkpoint_buffer",
           "checkpoint_format", "checkpoint_frames", "convert_checkpoint", "default_run_dir", "env_state",
           "find_checkpoint", "latest_checkpoint", "load_checkpoint", "load_env_state", "load_plain", "rng_state",
           "save_checkpoint", "save_plain", "set_rng_state", "verify_checkpoint"]
