"""morl_trl.metrics."""
