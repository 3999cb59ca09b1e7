"""GPI-LS and GPI-PD (Alegre et al., 2023): :mod:`~morl_trl.algorithms.gpi.recipe` (the agent, ``update``,
``on_batch``, the weight-support iterations and ``train_gpi``); its losses are in :mod:`morl_trl.objectives.gpi`
and :mod:`morl_trl.objectives.dynamics`."""
