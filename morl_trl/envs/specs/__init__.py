"""Domain specs (data only; importing them loads no simulator).

Each module registers its :class:`~morl_trl.envs.DomainSpec` objects on import.
"""

from morl_trl.envs.specs import lava_grid, lunar_lander, mario, mujoco  # noqa: F401
