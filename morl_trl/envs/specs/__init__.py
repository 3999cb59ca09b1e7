"""Domain specs (data only; importing them loads no simulator).

Each module registers its :class:`~morl_trl.envs.DomainSpec` objects on import.
"""

from morl_trl.envs.specs import lunar_lander, mujoco  # noqa: F401
import importlib as _importlib

for _name in ("lava_grid", "mario"):
    try:
        _importlib.import_module(f"morl_trl.envs.specs.{_name}")
    except ModuleNotFoundError as _e:  # spec module not written yet
        if _e.name != f"morl_trl.envs.specs.{_name}":
            raise
