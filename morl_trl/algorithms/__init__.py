"""The algorithms, one folder each: its builder, its one ``update``, its ``on_batch`` and its loop, read
top to bottom (``<name>/recipe.py``), and its config (``<name>/config.py``, torch-free).
:mod:`~morl_trl.algorithms.registry` maps each name to them.

============================  ===========================================
``envelope``                  :mod:`morl_trl.algorithms.envelope`
``capql``, ``mosac``,         :mod:`morl_trl.algorithms.actor_critic`
``mosac_discrete``, ``sac``
``gpi_ls``, ``gpi_pd``        :mod:`morl_trl.algorithms.gpi`
``morld``, ``morld_psa``      :mod:`morl_trl.algorithms.morld`
``pcn``                       :mod:`morl_trl.algorithms.pcn`
``pgmorl``                    :mod:`morl_trl.algorithms.pgmorl`
============================  ===========================================
"""
