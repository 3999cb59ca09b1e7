"""What every training run needs, whatever its algorithm: the run directory and its logs
(:class:`RunLog`), checkpoints that hold everything to continue, and RNG states.

Recipes (:mod:`morl_trl.recipes`) use these; a custom trainer can too.
"""

from morl_trl.runs.checkpoint import latest_checkpoint, load_checkpoint, rng_state, save_checkpoint, set_rng_state
from morl_trl.runs.run_log import RunLog

__all__ = ["RunLog", "latest_checkpoint", "load_checkpoint", "rng_state", "save_checkpoint", "set_rng_state"]
