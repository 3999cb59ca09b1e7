"""The kit every algorithm's loop uses: the :class:`~morl_trl.training.agent.Agent` that holds an
algorithm's modules and state, the one optimizer step (:mod:`~morl_trl.training.optim`), the capture of
a recipe's gradient step (:mod:`~morl_trl.training.capture`: ``torch.compile`` / CUDA graphs), the run's
parts (:mod:`~morl_trl.training.parts`: the training env, replay buffer, collector, evaluator) and the
process's allocator (:mod:`~morl_trl.training.allocator`).

The algorithms themselves are in :mod:`morl_trl.algorithms`, one folder each.
"""
