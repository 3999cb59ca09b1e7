"""Which config dataclass and defaults each algorithm has (``--quick``: the preset file ``quick.toml``).

Example:
    >>> spec = ALGORITHM_SPECS["pcn"]
    >>> "eps_start" in spec.keys, spec.domains["MOLavaGridDR-v0"]["pcn_er_episodes"]
    (False, 2000)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from morl_trl.algorithms.actor_critic import capql_config as capql, mosac_config as mosac, sac_config as sac
from morl_trl.algorithms.envelope import config as envelope
from morl_trl.algorithms.gpi import config as gpi
from morl_trl.algorithms.morld import config as morld
from morl_trl.algorithms.pcn import config as pcn
from morl_trl.algorithms.pgmorl import config as pgmorl
from morl_trl.recipes.config.keys import ALGORITHMS, KEYS

__all__ = ["AlgorithmSpec", "ALGORITHM_SPECS"]


@dataclass(frozen=True)
class AlgorithmSpec:
    """An algorithm's config: its dataclass (keys and defaults), the shared sections' values it
    changes (``shared``) and its values per training domain (``domains``)."""

    name: str
    config: type
    shared: Mapping[str, Any]
    domains: Mapping[str, Mapping[str, Any]]

    @property
    def keys(self) -> tuple[str, ...]:
        """The algorithm's own keys, in order."""
        return tuple(f.name for f in dataclasses.fields(self.config))


ALGORITHM_SPECS: Mapping[str, AlgorithmSpec] = MappingProxyType({
    "envelope": AlgorithmSpec("envelope", envelope.EnvelopeConfig, envelope.SHARED_DEFAULTS, envelope.DEFAULTS),
    "capql": AlgorithmSpec("capql", capql.CAPQLConfig, capql.SHARED_DEFAULTS, capql.DEFAULTS),
    "mosac": AlgorithmSpec("mosac", mosac.MOSACConfig, mosac.SHARED_DEFAULTS, mosac.DEFAULTS),
    "mosac_discrete": AlgorithmSpec("mosac_discrete", mosac.MOSACDiscreteConfig, mosac.SHARED_DEFAULTS,
                                    mosac.DEFAULTS_DISCRETE),
    "morld": AlgorithmSpec("morld", morld.MORLDConfig, morld.SHARED_DEFAULTS, morld.DEFAULTS),
    "morld_psa": AlgorithmSpec("morld_psa", morld.MORLDPSAConfig, morld.SHARED_DEFAULTS, morld.DEFAULTS),
    "sac": AlgorithmSpec("sac", sac.SACConfig, sac.SHARED_DEFAULTS, sac.DEFAULTS),
    "pcn": AlgorithmSpec("pcn", pcn.PCNConfig, pcn.SHARED_DEFAULTS, pcn.DEFAULTS),
    "pgmorl": AlgorithmSpec("pgmorl", pgmorl.PGMORLConfig, pgmorl.SHARED_DEFAULTS, pgmorl.DEFAULTS),
    "gpi_ls": AlgorithmSpec("gpi_ls", gpi.GPILSConfig, gpi.SHARED_DEFAULTS, gpi.DEFAULTS),
    "gpi_pd": AlgorithmSpec("gpi_pd", gpi.GPIPDConfig, gpi.SHARED_DEFAULTS, gpi.DEFAULTS_PD),
})
assert tuple(ALGORITHM_SPECS) == ALGORITHMS
for _spec in ALGORITHM_SPECS.values():  # every key is defined once, in KEYS, with one type
    _unknown = set(_spec.keys) - set(KEYS)
    assert not _unknown, (_spec.name, _unknown)
    _retyped = {f.name: f.type for f in dataclasses.fields(_spec.config) if f.type != KEYS[f.name].type}
    assert not _retyped, (_spec.name, _retyped)
