"""PCN (Reymond et al., 2022): :mod:`~morl_trl.algorithms.pcn.recipe` (the agent, ``update``, ``on_batch``,
``train_pcn``); its loss is :class:`~morl_trl.objectives.PCNLoss`."""
