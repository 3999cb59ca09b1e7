"""Envelope Q-learning (Yang et al., 2019): :mod:`~morl_trl.algorithms.envelope.recipe` (its builder,
``gradient_step``, ``update``, ``on_batch`` and the loop ``train_envelope``); its loss is
:class:`~morl_trl.objectives.EnvelopeQLoss`, its configuration :mod:`~morl_trl.algorithms.envelope.config`."""
