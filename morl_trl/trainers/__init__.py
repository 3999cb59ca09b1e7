"""Training recipes: the paper's loop (domain-randomized generalist, multi-context evaluation)."""

from morl_trl.trainers.config import ALGORITHMS, TrainConfig, resolve_config
from morl_trl.trainers.loop import evaluate_run, train

__all__ = ["ALGORITHMS", "TrainConfig", "evaluate_run", "resolve_config", "train"]
