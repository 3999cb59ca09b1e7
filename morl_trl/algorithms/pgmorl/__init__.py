"""PGMORL (Xu et al., 2020): :mod:`~morl_trl.algorithms.pgmorl.recipe` (population PPO, ``update``, ``on_batch``,
``train_pgmorl``) and its evolution (:mod:`~morl_trl.algorithms.pgmorl.evolution`: the performance buffer,
the prediction model, the task selection)."""
