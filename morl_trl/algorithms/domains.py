"""The training env id of each domain the authors ran (the keys of every algorithm's table),
and :func:`domain_table`, which freezes such a table so nothing can change it after import.

Example:
    >>> t = domain_table({LUNAR_LANDER: {"batch_size": 64}})
    >>> t[LUNAR_LANDER]["batch_size"]
    64
    >>> t[LUNAR_LANDER]["batch_size"] = 1
    Traceback (most recent call last):
    ...
    TypeError: 'mappingproxy' object does not support item assignment
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

__all__ = ["LUNAR_LANDER", "HOPPER", "HALF_CHEETAH", "HUMANOID", "LAVA_GRID", "MARIO", "MUJOCO", "RECORD_DOMAINS",
           "domain_table", "frozen"]

LUNAR_LANDER = "MOLunarLanderDR-v0"
HOPPER = "MOHopperDR-v5"
HALF_CHEETAH = "MOHalfCheetahDR-v5"
HUMANOID = "MOHumanoidDR-v5"
LAVA_GRID = "MOLavaGridDR-v0"
MARIO = "MOSuperMarioBrosZeroShot-v2"
MUJOCO = (HOPPER, HALF_CHEETAH, HUMANOID)
#: hyperparameters.toml's domain names -> our training env ids
RECORD_DOMAINS = MappingProxyType({"lunarlander": LUNAR_LANDER, "hopper": HOPPER, "cheetah": HALF_CHEETAH,
                                   "humanoid": HUMANOID, "lavagrid": LAVA_GRID, "mario": MARIO})


def frozen(values: Mapping[str, Any]) -> Mapping[str, Any]:
    """A read-only copy of ``values``."""
    return MappingProxyType(dict(values))


def domain_table(table: Mapping[str, Mapping[str, Any]]) -> Mapping[str, Mapping[str, Any]]:
    """A read-only ``{training env id: {key: value}}`` table."""
    return MappingProxyType({domain: frozen(values) for domain, values in table.items()})
