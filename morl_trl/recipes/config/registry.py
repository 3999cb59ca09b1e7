"""Which config dataclass, defaults and ``--quick`` values each algorithm has.

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

from morl_trl.recipes.config import capql, envelope, gpi, morld, mosac, pcn, pgmorl, sac
from morl_trl.recipes.config.keys import ALGORITHMS, KEYS

__all__ = ["AlgorithmSpec", "ALGORITHM_SPECS"]


@dataclass(frozen=True)
class AlgorithmSpec:
    """An algorithm's config: its dataclass (keys and defaults), the shared sections' values it
    changes (``shared``), its values per training domain (``domains``) and its ``--quick`` values."""

    name: str
    config: type
    shared: Mapping[str, Any]
    domains: Mapping[str, Mapping[str, Any]]
    quick: Mapping[str, Any]

    @property
    def keys(self) -> tuple[str, ...]:
        """The algorithm's own keys, in order."""
        return tuple(f.name for f in dataclasses.fields(self.config))


ALGORITHM_SPECS: Mapping[str, AlgorithmSpec] = MappingProxyType({
    "envelope": AlgorithmSpec("envelope", envelope.EnvelopeConfig, envelope.SHARED_DEFAULTS, envelope.DEFAULTS,
                              envelope.QUICK),
    "capql": AlgorithmSpec("capql", capql.CAPQLConfig, capql.SHARED_DEFAULTS, capql.DEFAULTS, capql.QUICK),
    "mosac": AlgorithmSpec("mosac", mosac.MOSACConfig, mosac.SHARED_DEFAULTS, mosac.DEFAULTS, mosac.QUICK),
    "mosac_discrete": AlgorithmSpec("mosac_discrete", mosac.MOSACDiscreteConfig, mosac.SHARED_DEFAULTS,
                                    mosac.DEFAULTS_DISCRETE, mosac.QUICK),
    "morld": AlgorithmSpec("morld", morld.MORLDConfig, morld.SHARED_DEFAULTS, morld.DEFAULTS, morld.QUICK),
    "morld_psa": AlgorithmSpec("morld_psa", morld.MORLDPSAConfig, morld.SHARED_DEFAULTS, morld.DEFAULTS,
                               morld.QUICK),
    "sac": AlgorithmSpec("sac", sac.SACConfig, sac.SHARED_DEFAULTS, sac.DEFAULTS, sac.QUICK),
    "pcn": AlgorithmSpec("pcn", pcn.PCNConfig, pcn.SHARED_DEFAULTS, pcn.DEFAULTS, pcn.QUICK),
    "pgmorl": AlgorithmSpec("pgmorl", pgmorl.PGMORLConfig, pgmorl.SHARED_DEFAULTS, pgmorl.DEFAULTS, pgmorl.QUICK),
    "gpi_ls": AlgorithmSpec("gpi_ls", gpi.GPILSConfig, gpi.SHARED_DEFAULTS, gpi.DEFAULTS, gpi.QUICK),
    "gpi_pd": AlgorithmSpec("gpi_pd", gpi.GPIPDConfig, gpi.SHARED_DEFAULTS, gpi.DEFAULTS_PD, gpi.QUICK_PD),
})
assert tuple(ALGORITHM_SPECS) == ALGORITHMS
for _spec in ALGORITHM_SPECS.values():  # every key is defined once, in KEYS
    _unknown = set(_spec.keys) - set(KEYS)
    assert not _unknown, (_spec.name, _unknown)
