"""CAPQL, MOSAC (continuous and discrete) and the SAC baseline, one loop: :mod:`~morl_trl.algorithms.actor_critic.recipe`
(the builders of CAPQL and MOSAC, ``gradient_step``, ``update``, ``on_batch``, ``train_actor_critic``) and SAC's
modules on the scalar reward (:mod:`~morl_trl.algorithms.actor_critic.sac`); their losses are
:class:`~morl_trl.objectives.CAPQLLoss`, :class:`~morl_trl.objectives.MOSACLoss`,
:class:`~morl_trl.objectives.DiscreteMOSACLoss` and :mod:`morl_trl.objectives.sac`."""
