"""morl_trl: TorchRL-native multi-objective RL that generalizes across environments."""

__version__ = "0.1.0"
