"""TorchRL transforms for contextual multi-objective RL."""

from morl_trl.transforms.domain_randomization import DomainRandomization

__all__ = ["DomainRandomization"]
