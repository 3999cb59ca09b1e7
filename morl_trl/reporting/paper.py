"""What the paper published, as data: the order of its domains and its NHGR per algorithm and
domain (SPEC §3), and the display name of a domain. Used by the NHGR tables and the floors.

Example:
    >>> PAPER_ORDER[0], PAPER_NHGR["MOLunarLanderDR-v0"]["GPI-LS"]
    ('MOLunarLanderDR-v0', (0.66, 0.06))
"""

from __future__ import annotations

__all__ = ["PAPER_ORDER", "PAPER_NHGR", "PAPER_BUDGET", "paper_budget", "domain_name"]

# the paper's order of the domains (their names come from the registry's DomainSpec)
PAPER_ORDER = ("MOLunarLanderDR-v0", "MOHopperDR-v5", "MOHalfCheetahDR-v5", "MOHumanoidDR-v5",
               "MOSuperMarioBrosZeroShot-v2", "MOLavaGridDR-v0")

# SPEC §3 "All results" (the paper's Table 3 NHGR row and Fig. 3-4): mean, pooled std
PAPER_NHGR: dict[str, dict[str, tuple[float, float]]] = {
    "MOLunarLanderDR-v0": {
        "Envelope": (0.18, 0.06), "GPI-LS": (0.66, 0.06), "GPI-PD": (0.45, 0.07), "MORL/D SB": (0.57, 0.07),
        "MORL/D SB+PSA": (0.57, 0.05), "PCN": (0.28, 0.04), "SAC": (0.29, 0.06),
    },
    "MOHopperDR-v5": {
        "CAPQL": (0.50, 0.16), "GPI-LS": (0.45, 0.15), "GPI-PD": (0.37, 0.11), "MORL/D SB": (0.46, 0.14),
        "MORL/D SB+PSA": (0.54, 0.15), "PCN": (0.05, 0.03), "PGMORL": (0.20, 0.09), "SAC": (0.14, 0.06),
    },
    "MOHalfCheetahDR-v5": {
        "CAPQL": (0.03, 0.03), "GPI-LS": (0.16, 0.12), "MORL/D SB": (0.21, 0.09), "MORL/D SB+PSA": (0.29, 0.13),
        "PCN": (0.03, 0.02), "PGMORL": (0.07, 0.02), "SAC": (0.09, 0.07),
    },
    "MOHumanoidDR-v5": {
        "CAPQL": (0.31, 0.10), "GPI-LS": (0.07, 0.04), "MORL/D SB": (0.44, 0.19), "MORL/D SB+PSA": (0.43, 0.20),
        "PCN": (0.24, 0.07), "PGMORL": (0.03, 0.02), "SAC": (0.35, 0.20),
    },
    "MOLavaGridDR-v0": {
        "Envelope": (0.02, 0.05), "GPI-LS": (0.02, 0.05), "MORL/D SB": (0.37, 0.21), "MORL/D SB+PSA": (0.27, 0.23),
        "PCN": (0.03, 0.06), "SAC": (0.25, 0.19),
    },
    "MOSuperMarioBrosZeroShot-v2": {
        "Envelope": (0.08, 0.08), "GPI-LS": (0.12, 0.14), "PCN": (0.04, 0.06), "SAC": (0.06, 0.07),
    },
}


# SPEC §5 "Common" and §2 "Running": the training frames of every published run per domain, and
# its evaluation weights (100 energy weights; Mario 32): (frames, weights)
PAPER_BUDGET: dict[str, tuple[int, int]] = {
    "MOLunarLanderDR-v0": (3_000_000, 100),
    "MOHopperDR-v5": (3_000_000, 100),
    "MOHalfCheetahDR-v5": (5_000_000, 100),
    "MOHumanoidDR-v5": (10_000_000, 100),
    "MOSuperMarioBrosZeroShot-v2": (3_000_000, 32),
    "MOLavaGridDR-v0": (5_000_000, 100),
}


def paper_budget(domain: str) -> tuple[int, int] | None:
    """``(frames, evaluation weights)`` of the paper's runs on ``domain`` (``None``: not in the paper).

    Example:
        >>> paper_budget("MOLunarLanderDR-v0"), paper_budget("MOSuperMarioBrosZeroShot-v2")
        ((3000000, 100), (3000000, 32))
    """
    return PAPER_BUDGET.get(domain)


def domain_name(domain: str) -> str:
    """The display name of a domain id: its :class:`~morl_trl.envs.DomainSpec` ``name`` (the id if unregistered).

    Example:
        >>> domain_name("MOHopperDR-v5"), domain_name("NoSuchDomain-v0")
        ('MO-Hopper', 'NoSuchDomain-v0')
    """
    from morl_trl.envs import domain_of

    try:
        return domain_of(domain).name
    except ValueError:
        return domain
