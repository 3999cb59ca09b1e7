"""MORL/D SB and SB+PSA (Felten et al., 2024): :mod:`~morl_trl.algorithms.morld.recipe` (the batched population,
``update``, ``on_batch``, the round robin and the exchanges, ``train_morld``); its loss is
:class:`~morl_trl.objectives.population.PopulationMOSACLoss`."""
