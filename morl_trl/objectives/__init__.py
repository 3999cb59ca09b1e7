"""morl_trl.objectives."""
