"""A trained policy: morl_trl.train returns it with the results, morl_trl.load_policy rebuilds it."""

import re
import shutil

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs.utils import set_exploration_type

import morl_trl
from morl_trl.recipes import TrainedPolicy, TrainResult, load_policy, resolve_config, train_policy
from tests.recipes.test_training import TINY


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> TrainResult:
    run_dir = tmp_path_factory.mktemp("policy") / "run"
    return morl_trl.train("envelope", "MOLavaGridDR-v0", quick=True, run_dir=str(run_dir), **TINY)


def _actions(policy, tds, exploration_type):
    with set_exploration_type(exploration_type), torch.no_grad():
        return policy(tds.clone())["action"]


def test_train_returns_the_run_the_summary_and_the_policy(trained):
    assert isinstance(trained, TrainResult) and isinstance(trained.policy, TrainedPolicy)
    assert (trained.run_dir / "config.json").is_file() and trained.config.run_dir == str(trained.run_dir)
    assert trained.summary["frames"] == 512 and 0.0 <= trained.summary["nhgr_mean"] <= 1.0
    p = trained.policy
    assert (p.env_id, p.history_len, p.preference_key, p.frames) == ("MOLavaGridDR-v0", 0, "preference", 512)
    assert p.objective_names == ("lava", "time")
    # no published data given: NHGR from the shipped constants, and the report says how to add baselines
    report = (trained.run_dir / "report.md").read_text()
    assert "## NHGR per context" in report and "pass the folder that holds them with `--reference DIR`" in report


def test_loaded_policy_acts_as_the_trained_agent(trained):
    policy = load_policy(trained.run_dir)
    assert policy.checkpoint.name == "frames_000000000512"
    agent = trained.agent
    env = policy.make_env("MOLavaGridDR-v0", num_envs=8, seed=0, preference=[[0.9, 0.1], [0.2, 0.8]])
    rollout = env.rollout(40, policy, break_when_any_done=False)  # the loaded policy drives the policy env
    assert rollout["next", "reward"].shape == (8, 40, 2)
    assert torch.equal(rollout["preference"][0, 0], torch.tensor([0.9, 0.1]))
    tds = rollout.exclude("next", "action").reshape(-1)
    ours = _actions(policy, tds, agent.eval_exploration)
    theirs = _actions(agent.eval_policy, tds, agent.eval_exploration)
    assert torch.equal(ours, theirs) and torch.equal(ours, rollout["action"].reshape(-1))
    # the trained weights, read back from the checkpoint
    trained_params = dict(agent.eval_policy.named_parameters())
    assert trained_params and all(torch.equal(v, trained_params[k]) for k, v in policy.module.named_parameters())
    older = sorted((trained.run_dir / "checkpoints").glob("frames_*"))[0]
    assert older.name == "frames_000000000256"  # (the run keeps two checkpoints)
    before = dict(load_policy(trained.run_dir, checkpoint=256).module.named_parameters())
    assert any(not torch.equal(v, trained_params[k]) for k, v in before.items())


def test_preference_given_at_reset_and_fixed_contexts(trained):
    policy = load_policy(trained.run_dir, checkpoint="frames_000000000512")
    env = policy.make_env("MOLavaGridSnake-v0", num_envs=2, seed=1)
    w = torch.tensor([[1.0, 0.0], [0.3, 0.7]])
    td = env.reset(TensorDict(preference=w, batch_size=[2]))
    out = env.rollout(5, policy, auto_reset=False, tensordict=td)
    assert torch.equal(out["preference"][:, -1], w)
    with pytest.raises(ValueError, match="not of the domain"):
        policy.make_env("MOLunarLanderDR-v0")


def test_bad_run_dirs_name_the_path(trained, tmp_path):
    with pytest.raises(ValueError, match=re.escape(repr(str(tmp_path))) + " is not a run directory"):
        load_policy(tmp_path)
    broken = tmp_path / "broken"
    shutil.copytree(trained.run_dir, broken)
    for state in (broken / "checkpoints").glob("frames_*/state.pt"):
        state.write_bytes(b"damaged")
    with pytest.raises(ValueError, match=re.escape(repr(str(broken))) + r" has no intact checkpoint \(frames_\d+: state.pt"):
        load_policy(broken)
    with pytest.raises(ValueError, match="does not exist"):
        load_policy(trained.run_dir, checkpoint=12345)


def test_train_policy_takes_a_config(tmp_path):
    cfg = resolve_config("envelope", "MOLavaGridDR-v0", quick=True, run_dir=str(tmp_path / "r"),
                         **{**TINY, "frames": 128, "eval_interval": 128, "checkpoint_interval": 128})
    result = train_policy(cfg)
    assert result.policy.frames == 128 and result.summary["frames"] == 128
    again = train_policy(resume=result.run_dir)  # nothing left to do: the policy all the same
    assert again.agent is None and again.policy.frames == 128
    with pytest.raises(ValueError, match="env_id is missing"):
        train_policy("envelope")
