"""A foreign env's run: MORL-Baselines' defaults, refusals with what is valid, IGD and HV ratio in evaluations."""

import numpy as np
import pytest
import torch

pytest.importorskip("mo_gymnasium")

from morl_trl.envs import domain_of  # noqa: E402
from morl_trl.evaluation import MultiContextEvaluator  # noqa: E402
from morl_trl.metrics import hypervolume, igd  # noqa: E402
from morl_trl.recipes import resolve_config  # noqa: E402


def test_foreign_env_gets_morl_baselines_constructor_defaults():
    cfg = resolve_config("envelope", "deep-sea-treasure-v0")
    # morl_baselines 1.3.0 Envelope.__init__: batch 256, 4 sampled weights, fixed epsilon 0.01,
    # hard target copy every 200 steps, no homotopy (initial_homotopy_lambda 0 without decay)
    assert (cfg.batch_size, cfg.num_sampled_prefs, cfg.eps_start, cfg.eps_end) == (256, 4, 0.01, 0.01)
    assert (cfg.target_update_period, cfg.tau, cfg.homotopy_lambda0, cfg.gamma) == (200, None, 0.0, 0.99)
    assert (cfg.num_envs, cfg.frames_per_batch, cfg.updates_per_batch, cfg.history_len) == (1, 1, 0, 0)
    gpi = resolve_config("gpi_ls", "deep-sea-treasure-v0")
    assert (gpi.batch_size, gpi.gpi_gradient_updates, gpi.gpi_iteration_frames, gpi.target_update_period) == \
        (128, 20, 10_000, 1000)
    # MB's PCN steps one env and picks a command per episode (16 sub-envs sharing a stale command
    # learned less on fruit-tree-v0 in benchmarks/parity)
    pcn = resolve_config("pcn", "fruit-tree-v0")
    assert (pcn.num_envs, pcn.frames_per_batch, pcn.pcn_step_episodes, pcn.pcn_model_updates) == (1, 1, 10, 50)
    # continuous actions: GPILSContinuousAction's values; the dynamics model's only for GPI-PD (GPI-LS
    # refused them: `morl-trl train gpi_ls mo-mountaincarcontinuous-v0` failed before this)
    gpi_c = resolve_config("gpi_ls", "mo-mountaincarcontinuous-v0")
    assert (gpi_c.hidden, gpi_c.buffer_size, gpi_c.gpi_policy_delay, gpi_c.gpi_min_priority) == ((256, 256), 400_000, 2, 0.1)
    pd_c = resolve_config("gpi_pd", "mo-mountaincarcontinuous-v0")
    assert (pd_c.gpi_dynamics_hidden, pd_c.gpi_real_ratio, pd_c.gpi_dynamics_rollout_len) == ((200, 200, 200, 200), 0.1, 5)
    # a paper domain keeps the paper's values
    assert resolve_config("envelope", "MOLavaGridDR-v0").num_sampled_prefs == 4
    assert resolve_config("envelope", "MOLunarLanderDR-v0").num_sampled_prefs == 8


def test_methods_that_cannot_run_an_env_refuse_before_anything_is_built():
    with pytest.raises(ValueError, match="pgmorl needs continuous actions .*continuous-only"):
        resolve_config("pgmorl", "deep-sea-treasure-v0")
    with pytest.raises(ValueError, match="sac trains on the env's original scalar reward"):
        resolve_config("sac", "deep-sea-treasure-v0")
    # resource-gathering-v0 has no MORL-Baselines point: the rule's bounds x horizon (100 steps) - 1
    assert domain_of("resource-gathering-v0").hv_ref_point == (-101.0, -1.0, -1.0)
    assert resolve_config("envelope", "resource-gathering-v0").ref_point is None  # (the env's)
    assert resolve_config("envelope", "resource-gathering-v0", ref_point=[-1, -1, -1]).ref_point == (-1.0, -1.0, -1.0)
    with pytest.raises(ValueError, match=r"ref_point \[0.0\] has 1 numbers; deep-sea-treasure-v0 has 2 objectives"):
        resolve_config("envelope", "deep-sea-treasure-v0", ref_point=[0.0])


def test_evaluation_on_a_foreign_env_reports_igd_and_the_hypervolume_ratio():
    down = lambda td: td.set("action", torch.ones(td.batch_size, dtype=torch.long))  # noqa: E731  first treasure
    ev = MultiContextEvaluator(down, "deep-sea-treasure-v0", weights=2, gamma=0.99, seed=0)
    m = ev.evaluate().per_context["deep-sea-treasure-v0"].metrics
    true = domain_of("deep-sea-treasure-v0").true_front(0.99)
    assert m["hypervolume"] == pytest.approx(0.7 * 24)  # (0.7, -1) against the reference point (0, -25)
    assert m["igd"] == pytest.approx(igd(np.array([[0.7, -1.0]]), true), rel=1e-6)
    assert m["hv_ratio"] == pytest.approx(0.7 * 24 / hypervolume(true, [0.0, -25.0]), rel=1e-6)
    assert 0 < m["hv_ratio"] < 0.1


def test_pgmorl_policy_of_a_run_is_rebuilt_with_its_env_layout():
    """train()/load_policy rebuild the agent from a run's config: PGMORL's num_envs is fixed to
    pop x envs per member, so the one-sub-env shortcut of the other methods is refused by it
    (morl_trl.train("pgmorl", env="mo-hopper-v5") failed after training before this)."""
    from morl_trl.recipes.policy import _build_agent

    cfg = resolve_config("pgmorl", "mo-mountaincarcontinuous-v0", pgmorl_pop=2, pgmorl_envs_per_member=1, num_envs=2,
                         frames_per_batch=8)
    agent = _build_agent(cfg, torch.device("cpu"))
    assert type(agent).__name__ == "PGMORLAgent"


@pytest.mark.parametrize("algo", ["mosac", "morld", "morld_psa"])
def test_mosacs_temperature_starts_at_mbs_autotune_start_with_its_critic_rate(algo):
    # MB 1.3.0's MOSAC (mosac_continuous_action.py): log_alpha = 0 (alpha 1.0; its alpha=0.2 is unused with autotune),
    # the temperature's Adam at q_lr, q_lr 1e-3, policy_lr 3e-4
    from morl_trl.recipes import resolve_config

    cfg = resolve_config(algo, "mo-hopper-v5")
    assert (cfg.alpha, cfg.learn_alpha, cfg.q_lr, cfg.alpha_lr, cfg.lr) == (1.0, True, 1e-3, 1e-3, 3e-4)


def test_discrete_mosacs_temperature_starts_at_mbs_autotune_start():
    from morl_trl.recipes import resolve_config

    cfg = resolve_config("mosac_discrete", "deep-sea-treasure-v0")
    assert (cfg.alpha, cfg.learn_alpha) == (1.0, True)  # MOSACDiscrete: log_alpha = 0 (mosac_discrete_action.py:260)
