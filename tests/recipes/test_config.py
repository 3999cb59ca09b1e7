"""The config per algorithm (issue 26): its keys, frozen defaults, strict keys, old files and runs."""

import json
import warnings
from pathlib import Path

import pytest
import torch

from morl_trl.recipes.config import (
    ALGORITHM_SPECS,
    ALGORITHMS,
    TrainConfig,
    load_config_file,
    resolve_config,
    valid_keys,
)
from morl_trl.recipes.config.train_config import _V1_DEFAULTS

ROOT = Path(__file__).resolve().parents[2]
FIXTURE = ROOT / "tests" / "fixtures" / "envelope_lavagrid_run" / "config.json"


def test_each_algorithm_has_only_its_keys():
    pcn = resolve_config("pcn", "MOLavaGridDR-v0")
    assert "eps_start" not in pcn.keys() and "pcn_er_episodes" in pcn.keys() and "pcn_hidden" not in pcn.keys()
    # a key the algorithm lacks is an error, never an inert value (shared code names its fallback: getattr)
    for key in ("eps_start", "prioritized", "init_random_frames"):
        with pytest.raises(AttributeError, match=f"'{key}' is not a setting of pcn"):
            getattr(pcn, key)
    assert getattr(pcn, "init_random_frames", 0) == 0
    assert set(resolve_config("gpi_pd", "MOLavaGridDR-v0").keys()) - set(resolve_config("gpi_ls", "MOLavaGridDR-v0")
                                                                         .keys()) == {
        "gpi_dynamics_hidden", "gpi_dynamics_ensemble", "gpi_dynamics_elites", "gpi_dynamics_lr",
        "gpi_dynamics_train_freq", "gpi_dynamics_rollout_freq", "gpi_dynamics_rollout_batch", "gpi_dynamics_buffer",
        "gpi_uncertainty_threshold", "gpi_real_ratio", "gpi_dynamics_rollout_len", "gpi_dynamics_normalize",
        "gpi_model_termination", "gpi_dynamics_max_logvar", "gpi_dynamics_max_grad_norm"}
    assert len(TrainConfig(algo="envelope").keys()) == 55 and len(TrainConfig(algo="pcn").keys()) == 40  # of 119


def test_a_key_the_algorithm_does_not_have_is_an_error_naming_where_the_valid_keys_are():
    with pytest.raises(ValueError, match=r"config key 'eps_start' is not a setting of pcn; morl-trl config pcn ENV_ID "
                                         r"prints every key of pcn"):
        resolve_config("pcn", "MOLavaGridDR-v0", eps_start=0.5)
    with pytest.raises(ValueError, match=r"unknown config key 'learning_rate' \(did you mean 'lr'\?\)"):
        resolve_config("envelope", "MOLavaGridDR-v0", learning_rate=1e-3)


def test_defaults_tables_are_frozen_and_resolving_changes_nothing():
    table = ALGORITHM_SPECS["gpi_pd"].domains["MOLavaGridDR-v0"]
    with pytest.raises(TypeError):
        table["gpi_dynamics_lr"] = 1.0
    with pytest.raises(TypeError):
        ALGORITHM_SPECS["gpi_pd"].domains["MOLunarLanderDR-v0"] = {}
    first = resolve_config("gpi_pd", "MOHopperDR-v5", gpi_dynamics_lr=0.1)
    again = resolve_config("gpi_pd", "MOHopperDR-v5")
    assert (first.gpi_dynamics_lr, again.gpi_dynamics_lr) == (0.1, 1e-3)


def test_the_renamed_pcn_hidden_maps_to_hidden_with_a_deprecation_warning():
    with pytest.warns(DeprecationWarning, match="'pcn_hidden' is deprecated; use hidden"):
        cfg = resolve_config("pcn", "MOLavaGridDR-v0", pcn_hidden=64)
    assert cfg.hidden == (64, 64)  # the old network: a 64 embedding and one 64 layer


def test_a_run_config_written_before_configs_were_per_algorithm_loads(tmp_path):
    cfg = TrainConfig.load(FIXTURE)  # the checkpoint fixture: every key of every algorithm
    saved = json.loads(FIXTURE.read_text())
    assert len(saved) > len(cfg.keys()) and cfg.algo == "envelope"
    ours = json.loads(json.dumps(cfg.to_dict()))
    assert {k: saved[k] for k in cfg.keys() if k in saved} == {k: ours[k] for k in saved if k in ours}  # same values
    assert {k: ours[k] for k in set(ours) - set(saved)} == {"domain_modules": [], "ref_point": None,
                                                          "capture_sampling": False,
                                                          "per_running_max": False}  # added since: the old code
    # an old SAC run updated every frame with one lr: the keys added since reproduce that
    old = {**_V1_DEFAULTS, "algo": "sac", "env_id": "MOLavaGridDR-v0", "hidden": [16, 16]}
    (tmp_path / "config.json").write_text(json.dumps(old))
    sac = TrainConfig.load(tmp_path / "config.json")
    assert (sac.update_frequency, sac.q_lr, sac.alpha_lr, sac.adam_eps, sac.alpha) == (1, None, None, None, 0.2)
    assert (sac.policy_freq, sac.actor_scale) == (1, "softplus")  # the joint step and the softplus scale then
    # an old PCN run: pcn_hidden was its width
    (tmp_path / "config.json").write_text(json.dumps({**old, "algo": "pcn", "pcn_hidden": 32}))
    assert TrainConfig.load(tmp_path / "config.json").hidden == (32, 32)


def test_an_old_complete_config_file_still_works_and_a_foreign_value_is_refused(tmp_path):
    dump = {k: list(v) if isinstance(v, tuple) else v for k, v in _V1_DEFAULTS.items() if v is not None}
    dump.update(algo="pcn", env_id="MOLavaGridDR-v0")
    path = tmp_path / "old.json"
    path.write_text(json.dumps(dump))
    with pytest.warns(DeprecationWarning, match=r"are not settings of pcn and are ignored"):
        cfg = resolve_config("pcn", "MOLavaGridDR-v0", config_file=path)
    assert cfg.pcn_er_episodes == 20 and cfg.hidden == (64, 64)  # the file's values (pcn_hidden 64)
    path.write_text(json.dumps({"eps_start": 0.3}))
    with pytest.raises(ValueError, match=r"'eps_start' is not a setting of pcn"):
        resolve_config("pcn", "MOLavaGridDR-v0", config_file=path)


@pytest.mark.parametrize("algo", ALGORITHMS)
def test_the_printed_config_is_the_config(algo, tmp_path, capsys):
    from morl_trl.cli import main

    env_id = "MOHopperDR-v5" if algo in ("capql", "mosac", "pgmorl") else "MOLavaGridDR-v0"
    assert main(["config", algo, env_id]) == 0
    path = tmp_path / "c.toml"
    path.write_text(capsys.readouterr().out)
    cfg = resolve_config(algo, env_id)
    assert resolve_config(algo, "MOLunarLanderDR-v0", config_file=path) == cfg
    assert main(["config", algo, env_id, "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(json.dumps(cfg.to_dict()))
    assert set(load_config_file(path)) == set(valid_keys(algo)) - {k for k, v in cfg.to_dict().items() if v is None}


def test_cli_config_refuses_a_foreign_key(capsys):
    from morl_trl.cli import main

    assert main(["config", "pcn", "MOLavaGridDR-v0", "eps_frames=10"]) == 2
    assert "config key 'eps_frames' is not a setting of pcn; morl-trl config pcn ENV_ID" in capsys.readouterr().err


def test_discrete_sac_updates_once_every_four_frames_with_the_authors_optimizers():
    from morl_trl.recipes import build_agent
    from morl_trl.algorithms.actor_critic.recipe import on_batch
    from morl_trl.recipes.off_policy import make_replay_buffer, make_training_env

    torch.manual_seed(0)
    cfg = resolve_config("sac", "MOLavaGridDR-v0", num_envs=4, hidden=(16,), batch_size=8, buffer_size=512,
                         init_random_frames=0, progress=False)
    assert (cfg.update_frequency, cfg.target_update_period, cfg.q_lr, cfg.alpha_lr, cfg.adam_eps) == \
        (4, 50, 3e-4, 3e-4, 1e-4)
    env = make_training_env(cfg, torch.device("cpu"))
    agent = build_agent(cfg, env, gamma=0.995, device=torch.device("cpu"))
    assert {g["eps"] for o in agent.optimizers.values() for g in o.param_groups} == {1e-4}
    buffer = make_replay_buffer(cfg, torch.device("cpu"))
    td = env.rollout(5, agent.explore_policy, break_when_any_done=False)  # 4 x 5 = 20 frames
    assert on_batch(agent, td, buffer, 20)[1] == 5  # frames 1..20: one update per 4 frames
    td = env.rollout(3, agent.explore_policy, break_when_any_done=False)  # frames 21..32
    assert on_batch(agent, td, buffer, 32)[1] == 3
    hop = resolve_config("sac", "MOHopperDR-v5")
    assert (hop.lr, hop.q_lr, hop.alpha_lr, hop.alpha, hop.update_frequency) == (3e-4, 1e-3, 1e-3, 1.0, 1)
