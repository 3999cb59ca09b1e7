"""What every training run needs, whatever its algorithm: the run itself (:class:`Run`: its
directory, resume, schedules, progress, report), its logs (:class:`RunLog`), checkpoints that
hold everything to continue, and RNG states.

Recipes (:mod:`morl_trl.recipes`) use these; a custom trainer can too.
"""

from morl_trl.runs.checkpoint import (
    checkpoint_buffer,
    checkpoint_frames,
    find_checkpoint,
    latest_checkpoint,
    load_checkpoint,
    rng_state,
    save_checkpoint,
    set_rng_state,
    verify_checkpoint,
)
from morl_trl.runs.env_state import env_state, load_env_state
from morl_trl.runs.run import Run
from morl_trl.runs.run_log import RunLog, check_logger

__all__ = ["Run", "RunLog", "check_logger", "checkpoint_buffer", "checkpoint_frames", "env_state", "find_checkpoint", "latest_checkpoint",
           "load_checkpoint", "load_env_state", "rng_state", "save_checkpoint", "set_rng_state", "verify_checkpoint"]
