"""PCN (Reymond et al. 2022): its keys, and the authors' values per domain.

Source: ``hyperparameters.toml`` ``[pcn.<domain>]``; ``morl-trl config pcn ENV --compare-authors``.
``hidden`` is the authors' ``net_arch``: the first width embeds the state and the command (their
product feeds the head), the others are the head's hidden layers (256 x 4: one embedding and three
head layers; Mario: 512 after the CNN, one head layer).

Example:
    >>> PCNConfig().hidden, DEFAULTS[MARIO]["pcn_er_episodes"]
    ((256, 256, 256, 256), 200)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.algorithms.domains import (
    HALF_CHEETAH,
    HOPPER,
    HUMANOID,
    LAVA_GRID,
    LUNAR_LANDER,
    MARIO,
    domain_table,
    frozen,
)

__all__ = ["PCNConfig", "SHARED_DEFAULTS", "DEFAULTS"]


@dataclass
class PCNConfig:
    """PCN's keys (LunarLander's values: ``[pcn.lunarlander]``); what each means: ``KEYS``.

    Source of each default: ``[pcn.lunarlander.<table>] <setting>`` of ``hyperparameters.toml``, or "ours".
    """

    frames_per_batch: int = 64  # ours: frames collected between calls of the episode bookkeeping
    lr: float = 3e-4  # init.learning_rate
    batch_size: int = 256  # init.batch_size
    hidden: tuple[int, ...] = (256, 256, 256, 256)  # init.net_arch
    pcn_scaling_factor: tuple[float, ...] | None = None  # init.scaling_factor (null: 0.1 for each objective and the horizon)
    pcn_max_return: tuple[float, ...] | None = None  # init.max_return (null: 100 per objective)
    pcn_buffer_episodes: int = 100_000  # train.max_buffer_size
    pcn_er_episodes: int = 1000  # train.num_er_episodes
    pcn_step_episodes: int = 10  # train.num_step_episodes
    pcn_model_updates: int = 50  # train.num_model_updates
    pcn_noise: float = 0.1  # init.noise


SHARED_DEFAULTS = frozen({})
DEFAULTS = domain_table({
    LUNAR_LANDER: dict(pcn_scaling_factor=(0.1,) * 5),
    HOPPER: dict(pcn_scaling_factor=(0.1,) * 4, pcn_max_return=(2700.0, 3100.0, 1000.0)),
    HALF_CHEETAH: dict(pcn_scaling_factor=(0.1,) * 3, pcn_max_return=(12300.0, 0.0), pcn_buffer_episodes=10_000,
                       pcn_noise=0.2),
    HUMANOID: dict(pcn_scaling_factor=(0.1,) * 3, pcn_max_return=(5200.0, 1000.0)),
    LAVA_GRID: dict(pcn_scaling_factor=(0.1,) * 3, pcn_max_return=(300.0, 300.0), pcn_buffer_episodes=4000,
                    pcn_er_episodes=2000),
    MARIO: dict(pcn_scaling_factor=(0.1,) * 4, pcn_max_return=(100.0, 100.0, 200.0), pcn_er_episodes=200,
                batch_size=64, hidden=(512, 512)),
})
