"""PGMORL's own recipe (recipes/pgmorl.py: train_pgmorl) trains exactly as the generic Agent loop
(off_policy.train_agent with PGMORLAgent.learn) did before it: same population, optimizer, weights, performance
buffer, Pareto archive, prediction model, VecNorm statistics, member seeds, counters, env, RNG, evaluations and
logs, from the same seed."""

import pytest

from morl_trl.recipes import off_policy, resolve_config, train
from morl_trl.recipes.pgmorl import PGMORLAgent
from tests.recipes._helpers import assert_checkpoints_equal, assert_logs_equal, csv_rows, last_checkpoints

# 2 members x 2 sub-envs x 32 steps: 128 frames collected, 64 counted (one member's) per iteration; budget 192 ->
# 3 iterations. Warm-up 1 iteration, then generations of 1: the members are evaluated after iterations 1-3 (2
# prediction samples each) and the task selection runs once the prediction model holds 4 (after iterations 2 and
# 3); 2 epochs x 2 minibatches = 4 PPO updates per iteration; checkpoints every 128 counted frames (at 128 and
# the end), evaluations at 0 and 192 (32 weights: the paper's 3-objective set, read from a file, not computed)
TINY = dict(frames=192, pgmorl_pop=2, pgmorl_envs_per_member=2, num_envs=4, frames_per_batch=128, pgmorl_warmup=1,
            pgmorl_evo_iterations=1, pgmorl_epochs=2, pgmorl_minibatches=2, hidden=(8,), eval_interval=192,
            eval_weights=32, checkpoint_interval=128, eval_contexts=("MOHopperDefault-v5",), progress=False,
            eval_random_baseline=False)




def test_the_pgmorl_recipe_trains_exactly_as_the_agent_loop(tmp_path, monkeypatch):
    pytest.importorskip("mujoco", reason="PGMORL runs on MuJoCo (continuous actions): needs mujoco")
    # (report.md's figures take seconds to draw and are not compared)
    monkeypatch.setattr("morl_trl.reporting.report.write_report", lambda log, summary, fps: log.out_dir / "report.md")
    calls = {"learn": 0, "select_tasks": 0}

    def counted(name):
        method = getattr(PGMORLAgent, name)

        def wrapped(self, *args, **kw):
            calls[name] += 1
            return method(self, *args, **kw)
        monkeypatch.setattr(PGMORLAgent, name, wrapped)

    for name in calls:
        counted(name)
    assert off_policy.RECIPES["pgmorl"].__name__ == "train_pgmorl"
    train(resolve_config("pgmorl", "MOHopperDR-v5", run_dir=str(tmp_path / "recipe"), **TINY))
    recipe_calls = dict(calls)
    monkeypatch.delitem(off_policy.RECIPES, "pgmorl")  # the loop of every Agent, with PGMORLAgent.learn
    train(resolve_config("pgmorl", "MOHopperDR-v5", run_dir=str(tmp_path / "agent"), **TINY))
    agent_calls = {k: v - recipe_calls[k] for k, v in calls.items()}
    recipe, agent = last_checkpoints(tmp_path / "recipe", tmp_path / "agent")
    assert_checkpoints_equal(recipe, agent)
    assert_logs_equal(tmp_path / "recipe", tmp_path / "agent")
    # two different loops ran, each with a task selection at the end of the warm-up and of every generation
    assert recipe_calls == {"learn": 0, "select_tasks": 3} and agent_calls == {"learn": 3, "select_tasks": 3}
    # one member's frames counted (3 iterations x 2 sub-envs x 32 steps), 4 PPO updates per iteration
    assert (recipe["frames"], recipe["updates"]) == (192, 12)
    state = recipe["agent"]
    assert state["iteration"] == 3
    # the prediction model: 2 samples per evaluation after iterations 1-3 (the members' first evaluation, after
    # iteration 0's rollout, has no predecessor); the task selection ran after iterations 2 and 3 (4 samples)
    assert len(state["predictor"][2]) == 6 and state["generation"] == 2
    assert state["member_seeds"] == [42, 42]  # both slots are copies the task selection made
    assert 1 <= len(state["archive"]) == len(state["archive_members"]) <= 10
    assert [len(r) for r in state["population"]["bins"]] and state["population"]
    assert [int(r["frames"]) for r in csv_rows(tmp_path / "recipe" / "eval/metrics.csv")] == [0, 192]
