"""The recipes do by default what the paper's authors ran (MORL-Generalization on MORL-Baselines);
our deviations stay as named options. One test per behaviour, with the authors' values."""

import pytest
import torch
from torchrl.envs.utils import ExplorationType

from morl_trl.envs import make_env
from morl_trl.recipes import build_agent, resolve_config
from morl_trl.algorithms.envelope import recipe as envelope
from morl_trl.recipes.off_policy import make_replay_buffer, make_training_env

CPU = torch.device("cpu")


def _agent(algo, env_id, *, set_=None, **overrides):
    cfg = resolve_config(algo, env_id, hidden=(32, 32), num_envs=2, progress=False, **overrides)
    for key, value in (set_ or {}).items():  # keys set to null (resolve_config drops None overrides)
        setattr(cfg, key, value)
    cfg.validate()
    env = make_training_env(cfg, CPU)
    return cfg, env, build_agent(cfg, env, gamma=0.99, device=CPU)


def _preference_transform(env):
    from morl_trl.transforms import PreferenceConditioning

    return next(t for t in env.transform if isinstance(t, PreferenceConditioning))


# ---------------------------------------------------------------- Envelope
def test_envelope_config_is_the_authors():
    ll = resolve_config("envelope", "MOLunarLanderDR-v0")
    assert (ll.homotopy_lambda0, ll.homotopy_final, ll.max_grad_norm) == (0.95, None, 1.0)
    assert (ll.per_importance_weights, ll.envelope_priority, ll.envelope_network) == (False, "first", "authors")
    assert (ll.preference_distribution, ll.preference_resample) == ("gaussian", "episode")
    assert (ll.num_sampled_prefs, ll.init_random_frames) == (8, 100)  # SPEC §4: 8; MORL-Baselines learning_starts
    lava = resolve_config("envelope", "MOLavaGridDR-v0")
    assert (lava.num_sampled_prefs, lava.init_random_frames) == (4, 100)  # MORL-Baselines' num_sample_w
    mario = resolve_config("envelope", "MOSuperMarioBrosZeroShot-v2")
    assert (mario.num_sampled_prefs, mario.init_random_frames) == (8, 25_000)  # SPEC §4
    for algo, env_id in (("capql", "MOHopperDR-v5"), ("mosac", "MOHopperDR-v5"),
                         ("mosac_discrete", "MOLavaGridDR-v0")):
        other = resolve_config(algo, env_id)
        assert other.max_grad_norm is None and "envelope_network" not in other.keys()  # the latter: envelope only


def test_envelope_homotopy_stays_fixed_by_default_as_the_authors():
    cfg, _, agent = _agent("envelope", "MOLavaGridDR-v0")
    assert agent.loss.homotopy_steps is None
    for frames in (0, cfg.frames // 2, 10 * cfg.frames):
        envelope.schedules(agent, frames)
        assert float(agent.loss.homotopy_lambda) == pytest.approx(0.95)
    cfg, _, ours = _agent("envelope", "MOLavaGridDR-v0", homotopy_final=1.0, frames=1000)  # our annealing
    envelope.schedules(ours, 500)
    assert float(ours.loss.homotopy_lambda) == pytest.approx(0.975)
    envelope.schedules(ours, 1000)
    assert float(ours.loss.homotopy_lambda) == pytest.approx(1.0)


def _filled_buffer(cfg, env, frames=256):
    buffer = make_replay_buffer(cfg, CPU)
    td = env.rollout(frames // env.batch_size[0], break_when_any_done=False)
    buffer.extend(td.reshape(-1))
    return buffer


def _grad_norm(agent):
    params = [p for opt in agent.optimizers.values() for g in opt.param_groups for p in g["params"]]
    return float(torch.linalg.vector_norm(torch.stack([p.grad.norm() for p in params if p.grad is not None])))


def test_envelope_grad_norm_clipped_at_1_as_the_authors():
    torch.manual_seed(0)
    cfg, env, agent = _agent("envelope", "MOLavaGridDR-v0", batch_size=32)
    assert cfg.max_grad_norm == 1.0
    buffer = _filled_buffer(cfg, env)
    envelope.update(agent, buffer)
    assert _grad_norm(agent) == pytest.approx(1.0, rel=1e-4)  # LavaGrid's rewards (-20, 300) give norms >> 1
    torch.manual_seed(0)
    cfg, env, ours = _agent("envelope", "MOLavaGridDR-v0", batch_size=32, set_={"max_grad_norm": None})
    assert cfg.max_grad_norm is None
    envelope.update(ours, _filled_buffer(cfg, env))
    assert _grad_norm(ours) > 2.0


def test_envelope_recipe_is_the_authors_network_loss_and_preferences():
    _, env, agent = _agent("envelope", "MOLavaGridDR-v0")
    loss = agent.loss
    net = loss.value_network.module
    assert net.trunk[0].in_features == 125  # LavaGrid's observation only: w joins after the first layer
    w = net.trunk[0].weight.detach()
    torch.testing.assert_close(w @ w.T, torch.eye(32), atol=1e-5, rtol=0)  # orthogonal, gain 1
    assert (loss.priority, loss.use_prioritized_weights, loss.num_preference_samples) == ("first", False, 4)
    assert _preference_transform(env).mode == "gaussian" and _preference_transform(env).resample == "episode"
    _, env, ours = _agent("envelope", "MOLavaGridDR-v0", envelope_network="input", per_importance_weights=True,
                          envelope_priority="mean", preference_distribution="dirichlet")
    assert ours.loss.value_network.module.mlp[0].in_features == 125 + 2
    assert (ours.loss.priority, ours.loss.use_prioritized_weights) == ("mean", True)
    assert _preference_transform(env).mode == "dirichlet"


def test_envelope_acts_and_learns_on_one_preference_distribution():
    """The authors' Envelope draws the episode's w and the update's ``num_sample_w`` from one ``dist``
    (hyperparameters.toml [envelope.*.init] dist = "gaussian"): one key sets both here too."""
    cfg, env, agent = _agent("envelope", "MOLavaGridDR-v0")
    assert cfg.preference_distribution == _preference_transform(env).mode == agent.loss.preference_distribution \
        == "gaussian"
    cfg, env, ours = _agent("envelope", "MOLavaGridDR-v0", preference_distribution="dirichlet")
    assert _preference_transform(env).mode == ours.loss.preference_distribution == "dirichlet"


# ---------------------------------------------------------------- CAPQL
def test_capql_recipe_acts_on_a_new_cone_preference_every_step_and_trains_on_it_as_the_authors():
    pytest.importorskip("mujoco")
    cfg, env, agent = _agent("capql", "MOHopperDR-v5")
    assert (cfg.preference_distribution, cfg.preference_resample) == ("cone", "step")
    assert (cfg.loss_fresh_preferences, cfg.actor_scale) == (False, "clamped_log_std")
    t = _preference_transform(env)
    assert (t.mode, t.resample) == ("cone", "step")
    assert agent.loss.resample_preferences is False and "preference" in agent.loss.in_keys
    assert type(agent.loss.actor_network.module[0].module).__name__ == "_LocClampedLogStd"
    with torch.no_grad():
        td = env.rollout(4, agent.explore_policy, break_when_any_done=False)
    w = td["preference"]  # [2 sub-envs, 4 steps, 3]
    assert (w[:, 1:] != w[:, :-1]).any(-1).all()
    assert torch.equal(td["next", "preference"][:, :-1], w[:, 1:])
    _, env, ours = _agent("capql", "MOHopperDR-v5", preference_distribution="dirichlet", preference_resample="episode",
                          loss_fresh_preferences=True, actor_scale="softplus")
    assert ours.loss.resample_preferences is True
    assert type(ours.loss.actor_network.module[0].module).__name__ == "_LocScale"


# ---------------------------------------------------------------- MORL/D's MOSAC
def test_mosac_is_evaluated_with_sampled_actions_as_the_paper():
    assert resolve_config("mosac", "MOHopperDR-v5").eval_exploration == "random"
    pytest.importorskip("mujoco")
    _, _, agent = _agent("mosac", "MOHopperDR-v5")
    assert agent.eval_exploration == ExplorationType.RANDOM
    _, _, greedy = _agent("mosac", "MOHopperDR-v5", eval_exploration="deterministic")
    assert greedy.eval_exploration == ExplorationType.DETERMINISTIC
    _, _, discrete = _agent("mosac_discrete", "MOLavaGridDR-v0")
    assert discrete.eval_exploration == ExplorationType.RANDOM
    for algo, env_id in (("envelope", "MOLavaGridDR-v0"), ("capql", "MOHopperDR-v5")):
        assert resolve_config(algo, env_id).eval_exploration == "deterministic"


# ---------------------------------------------------------------- optimizers
@pytest.mark.parametrize("algo, env_id, names", [
    ("envelope", "MOLavaGridDR-v0", {"qvalue"}),
    ("capql", "MOHopperDR-v5", {"actor", "qvalue"}),
])
def test_fused_adam_by_default_and_the_authors_per_tensor_adam_as_an_option(algo, env_id, names):
    if algo == "capql":
        pytest.importorskip("mujoco", reason="MO-Hopper needs the mujoco extra")
    _, _, fused = _agent(algo, env_id)
    _, _, plain = _agent(algo, env_id, fused_optimizer=False)
    assert set(fused.optimizers) >= names and set(plain.optimizers) == set(fused.optimizers)
    for name in names:
        assert fused.optimizers[name].defaults["fused"] is True
        assert plain.optimizers[name].defaults["fused"] is False


def test_the_sac_baseline_is_evaluated_with_sampled_actions_as_the_authors():
    # hyperparameters.toml sac.*.derived eval_action: "SAMPLED from the policy ..., not the mean/argmax" (SPEC §5 14)
    for env_id in ("MOHopperDR-v5", "MOLunarLanderDR-v0", "MOLavaGridDR-v0"):
        assert resolve_config("sac", env_id).eval_exploration == "random"
    pytest.importorskip("mujoco")
    _, _, agent = _agent("sac", "MOHopperDR-v5")
    assert agent.eval_exploration == ExplorationType.RANDOM
