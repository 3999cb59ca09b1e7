"""morl_trl.collectors."""
