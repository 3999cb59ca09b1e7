"""morl_trl: TorchRL-native multi-objective RL that generalizes across environments.

The sub-packages are imported when used; ``import morl_trl`` itself imports nothing heavy.
The top level gives the two entry points of a user who trains and then uses a policy:

* :func:`train` (``morl_trl.recipes.train_policy``): train as ``morl-trl train`` does and get
  a :class:`~morl_trl.recipes.TrainResult` (run directory, summary, config, trained policy);
* :func:`load_policy` (``morl_trl.recipes.load_policy``): the trained policy of a run
  directory, a TorchRL module with its env composition (``policy.make_env(...)``).
"""

__version__ = "0.1.0"

from morl_trl._quiet import quiet_dependencies as _quiet_dependencies

_quiet_dependencies()  # narrow filters for two dependency messages (morl_trl/_quiet.py)

__all__ = ["TrainResult", "TrainedPolicy", "load_policy", "train"]

from morl_trl._lazy import lazy_attributes as _lazy_attributes  # noqa: E402

_LAZY = {
    "train": ("morl_trl.recipes.policy", "train_policy"),
    "load_policy": ("morl_trl.recipes.policy", "load_policy"),
    "TrainResult": ("morl_trl.recipes.policy", "TrainResult"),
    "TrainedPolicy": ("morl_trl.recipes.policy", "TrainedPolicy"),
}


__getattr__, __dir__ = _lazy_attributes(globals(), _LAZY)
