"""The parity cases of MOSAC (one fixed weight on both sides) and of the SAC baseline (reference: TorchRL's own
SAC, ``torchrl_sac_runner.py``): how they are declared, ours' fixed preference, the report naming the reference."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict

PARITY = Path(__file__).resolve().parents[2] / "benchmarks" / "parity"



def test_mosac_case_gives_both_sides_one_weight_and_mbs_optimiser_values(parity):
    from common import CASES, reference_of

    case = CASES["mosac-hopper-5k"]
    assert case["algo"] == "mosac" and reference_of(case) == "mb"
    assert sum(case["weight"]) == pytest.approx(1.0) and len(case["weight"]) == 3  # (mo-hopper-v5: 3 objectives)
    # MB's MOSAC: q_lr 1e-3 for critics and temperature, log_alpha from 0 (alpha 1.0); ours' foreign defaults differ
    assert case["ours"] == dict(q_lr=1e-3, alpha_lr=1e-3, alpha=1.0) and case["mb"] == {}


def test_sac_case_names_torchrl_sac_as_its_reference_with_ours_settings(parity):
    from common import CASES, REFERENCES, reference_of

    case = CASES["sac-hopper-5k"]
    assert reference_of(case) == "torchrl_sac" and "torchrl_sac" in REFERENCES
    assert parity.REFERENCE_RUNNERS["torchrl_sac"].is_file()
    for key, value in case["ref"].items():  # the reference gets ours' values under the same names
        assert case["ours"][key] == value, key
    cmd = parity.runner_command("torchrl_sac", "sac-hopper-5k", "100", Path("/tmp/out"), None)
    assert cmd[:2] == [sys.executable, str(PARITY / "torchrl_sac_runner.py")]
    with pytest.raises(SystemExit):
        parity.runner_command("mb", "mosac-hopper-5k", "100", Path("/tmp/out"), None)  # (no MB venv)


def test_fixed_preference_policy_acts_on_the_weight_and_gives_back_the_evaluation_weight(parity):
    seen = []

    def policy(td):
        seen.append(td["preference"].clone())
        return td.set("action", torch.zeros(td.shape[0], 1))

    td = TensorDict(preference=torch.tensor([[1.0, 0.0], [0.0, 1.0]]), batch_size=[2])
    out = parity.FixedPreferencePolicy(policy, [0.25, 0.75])(td)
    assert torch.equal(seen[0], torch.tensor([[0.25, 0.75], [0.25, 0.75]]))
    assert torch.equal(out["preference"], torch.tensor([[1.0, 0.0], [0.0, 1.0]]))


def test_fixed_preference_holds_every_training_episode_at_the_weight(parity):
    """Inside ``fixed_preference(w)`` the actor-critic loop's training env gives every sub-env and episode ``w``
    (not a Dirichlet draw), and the evaluator's policy reads ``w``; outside it, the library is as it was."""
    from morl_trl.algorithms.actor_critic import recipe
    from morl_trl.recipes import resolve_config

    before = recipe.make_training_env, recipe.make_evaluator
    cfg = resolve_config("mosac", "mo-hopper-v5", num_envs=2, seed=0)
    w = [0.2, 0.3, 0.5]
    with parity.fixed_preference(w):
        env = recipe.make_training_env(cfg, torch.device("cpu"))
        td = env.rollout(60, break_when_any_done=False)  # (random actions: several episodes end on the way)
        env.close()
    assert bool(td["next", "done"].any())
    assert torch.allclose(td["preference"], torch.tensor(w).expand_as(td["preference"]))
    assert (recipe.make_training_env, recipe.make_evaluator) == before
    with parity.fixed_preference(None):  # (a case without a weight: nothing replaced)
        assert (recipe.make_training_env, recipe.make_evaluator) == before


def test_report_names_the_reference_and_judges_ours_against_it(parity, tmp_path):
    from common import result_path, write_result

    out = tmp_path / "results"
    for lib, hv in (("ours", [120.0, 121.0, 122.0]), ("torchrl_sac", [119.0, 121.0, 123.0])):
        for seed, v in zip((100, 101, 102), hv):
            curve = [dict(frames=0, hypervolume=10.0), dict(frames=5000, hypervolume=v)]
            write_result(result_path(out, "sac-hopper-5k", lib, seed),
                         dict(case="sac-hopper-5k", lib=lib, seed=seed, curve=curve, frames=5000, train_fps=20.0))
    text = parity.write_results(out, [100, 101, 102], "cmd").read_text()
    row = next(line for line in text.splitlines() if line.startswith("| sac-hopper-5k (ref.: torchrl_sac) |"))
    assert "| 3 / 3 |" in row and "both learn, at parity (seeds 100-102)" in row and "| learns (gain 111" in row
    assert "reference TorchRL's SAC" in text and "| 1.00x |" in row
    assert "| sac | sac-hopper-5k: both learn, at parity (seeds 100-102) | sac-hopper-5k |" in text


@pytest.mark.slow
def test_torchrl_sac_reference_smoke_run_writes_a_curve_from_frame0(tmp_path):
    """PARITY_SMOKE=1: 200 frames of the reference (learning from frame 100), evaluated at 0, 100 and 200 (~30 s)."""
    env = {**os.environ, "PARITY_SMOKE": "1", "PYTHONPATH": str(PARITY.parents[1])}
    subprocess.run([sys.executable, str(PARITY / "torchrl_sac_runner.py"), "sac-hopper-5k", "0", str(tmp_path)],
                   env=env, check=True, timeout=600)
    data = json.loads((tmp_path / "sac-hopper-5k" / "torchrl_sac_s0.json").read_text())
    assert [p["frames"] for p in data["curve"]] == [0, 100, 200]
    assert data["lib"] == "torchrl_sac" and data["updates"] == 101 and data["train_fps"] > 0
    # frames per CPU-second beside wall frames/s, as MB's and ours' runners (evaluations' CPU time left out)
    assert data["train_fps_cpu"] == pytest.approx(200 / data["train_cpu_seconds"]) and data["train_cpu_seconds"] > 0
    assert all(p["hypervolume"] is not None for p in data["curve"])
