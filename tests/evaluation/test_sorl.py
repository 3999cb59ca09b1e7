"""The evaluator's f_SORL record (the domain's original scalar reward, summed per episode), with
values worked out by hand.

Toy env (morl_trl/envs/toy.py): context (speed s, bias b); action 1 moves right, 0 left; reward
[s * move + b, -1], original_reward = its sum; terminates at |position| >= 3 (3 steps straight).
"""

import csv

import torch

from morl_trl.envs.toy import ToyContextEnv
from morl_trl.evaluation import MultiContextEvaluator
from morl_trl.reporting.fsorl import run_section

WEIGHTS = torch.tensor([[0.2, 0.8], [0.9, 0.1], [0.6, 0.4]], dtype=torch.float64)


def toy_factory(num_envs, seed):
    return ToyContextEnv(num_envs=num_envs, seed=seed)


def right_if_progress(td):
    """Straight right when the weight favours progress (w[0] > 0.5), else straight left."""
    return td.set("action", (td["preference"][..., 0] > 0.5).long())


def test_scripted_policy_f_sorl_by_hand_and_the_argmax_weight():
    # context s=2, b=0.5: right earns 2 + 0.5 - 1 = 1.5 per step, left -2 + 0.5 - 1 = -2.5, 3 steps
    ev = MultiContextEvaluator(right_if_progress, {"c": torch.tensor([2.0, 0.5])}, WEIGHTS, gamma=0.5,
                               env_factory=toy_factory)
    r = ev.evaluate()
    assert r.sorl_returns.squeeze(-1).tolist() == [[-7.5, 4.5, 4.5]]
    # discounted: x * (1 + 0.5 + 0.25)
    assert r.sorl_discounted_returns.squeeze(-1).tolist() == [[-4.375, 2.625, 2.625]]
    best = r.sorl_best()["c"]
    assert best["return_max"] == 4.5 and best["discounted_return_max"] == 2.625
    assert best["best_weight_index"] == 1  # the first of the tied maxima
    assert best["best_weight"] == {"progress": 0.9, "time": 0.1}
    rows = r.sorl_rows()
    assert [(x["weight_index"], x["sorl_return"], x["best"]) for x in rows] == [(0, -7.5, 0), (1, 4.5, 1), (2, 4.5, 0)]
    metrics = r.metric_rows()[0]
    assert metrics["sorl_return_max"] == 4.5 and metrics["sorl_best_weight_index"] == 1
    assert metrics["sorl_best_weight_progress"] == 0.9
    s = r.summary()
    assert s["eval/sorl_return_max/c"] == 4.5 and s["eval/sorl_discounted_return_max/c"] == 2.625
    assert s["eval/sorl_best_weight_time/c"] == 0.1
    assert [x["sorl_return"] for x in r.to_rows()] == [-7.5, 4.5, 4.5]


def test_episodes_are_averaged_per_weight_before_the_max():
    ev = MultiContextEvaluator(right_if_progress, {"c": torch.tensor([2.0, 0.5])}, WEIGHTS[:2], gamma=1.0,
                               env_factory=toy_factory, episodes=3, chunk_size=2)
    r = ev.evaluate()
    assert r.sorl_returns.shape == (1, 2, 3)
    assert r.sorl_values().tolist() == [[-7.5, 4.5]]


def test_scripted_policy_on_lava_grid_room_by_hand():
    """MO-LavaGrid Room: the agent starts at (6, 6) facing north. Turning in place for 256 steps
    pays only time: f_SORL = 0.1 * -3 * 256 = -76.8. Walking north passes (6, 5..2) and steps
    into the lava ring at (6, 1) on step 5 (-20), then bumps the wall: 0.9 * -20 + 0.1 * -768 = -94.8."""
    def policy(td):
        turn = td["preference"][..., 0] > 0.5  # weight on lava: stay out of it
        return td.set("action", torch.where(turn, 0, 2))

    ev = MultiContextEvaluator(policy, ["MOLavaGridRoom-v0"], torch.tensor([[0.2, 0.8], [0.9, 0.1]]), seed=0)
    r = ev.evaluate()
    g = 0.995
    time_disc = -0.3 * (1 - g**256) / (1 - g)
    torch.testing.assert_close(r.sorl_returns.squeeze(-1), torch.tensor([[-94.8, -76.8]], dtype=torch.float64),
                               rtol=0, atol=1e-4)
    torch.testing.assert_close(r.sorl_discounted_returns.squeeze(-1),
                               torch.tensor([[0.9 * -20 * g**4 + time_disc, time_disc]], dtype=torch.float64),
                               rtol=0, atol=1e-4)
    best = r.sorl_best()["MOLavaGridRoom-v0"]
    assert best["best_weight_index"] == 1 and abs(best["return_max"] + 76.8) < 1e-4
    # LavaGrid's f_SORL is exactly its spec's weighted sum of the vector return
    torch.testing.assert_close(r.sorl_returns, r.undiscounted_returns @ torch.tensor([0.9, 0.1], dtype=torch.float64))


def test_a_policy_ignoring_the_weight_gets_the_best_of_as_many_episodes():
    """SAC's protocol: as many episodes as weights; its f_SORL max is the best of them."""
    W = 6
    w = torch.linspace(0, 1, W, dtype=torch.float64)
    ev = MultiContextEvaluator("random", ["MOLavaGridRoom-v0", "MOLavaGridMaze-v0"], torch.stack([w, 1 - w], -1),
                               seed=3)
    r = ev.evaluate()
    assert r.sorl_returns.shape == (2, W, 1)
    per_episode = r.sorl_returns[..., 0]
    assert len(set(per_episode[0].tolist())) > 1  # the random episodes differ
    best = r.sorl_best()
    for i, c in enumerate(r.context_names):
        assert best[c]["return_max"] == per_episode[i].max().item()
        assert best[c]["best_weight_index"] == int(per_episode[i].argmax())
    lines = run_section(r, "/nonexistent", "sac", None, "MOLavaGridDR-v0")
    text = "\n".join(lines)
    assert f"the best of its {W} evaluation episodes per context (SAC ignores the weight)" in text
    assert "SAC does not read the weight" in text and "| objective |" not in text


class NoOriginalRewardEnv(ToyContextEnv):
    has_original_reward = False


def test_an_env_without_an_original_reward_has_no_f_sorl_and_says_so_once(tmp_path):
    ev = MultiContextEvaluator(right_if_progress, {"c": torch.tensor([2.0, 0.5])}, WEIGHTS, gamma=0.5,
                               env_factory=lambda num_envs, seed: NoOriginalRewardEnv(num_envs=num_envs, seed=seed))
    r = ev.evaluate()
    assert r.sorl_returns is None and not r.has_sorl
    assert r.sorl_rows() == [] and "sorl_return_max" not in r.metric_rows()[0]
    assert not any("sorl" in k for k in r.summary())
    lines = run_section(r, tmp_path, "envelope", None, "MyEnv-v0")
    said = [line for line in lines if "original scalar reward" in line]
    assert len(said) == 1 and said[0].startswith("No f_SORL: MyEnv-v0 emits no original scalar reward")
    assert not (tmp_path / "report_fsorl.png").exists()


def test_sorl_key_none_records_nothing():
    ev = MultiContextEvaluator(right_if_progress, {"c": torch.tensor([2.0, 0.5])}, WEIGHTS, gamma=0.5,
                               env_factory=toy_factory, sorl_key=None)
    assert ev.evaluate().sorl_returns is None


def test_run_log_stores_f_sorl_and_the_run_report_shows_the_best_weights(tmp_path):
    from types import SimpleNamespace

    from morl_trl.runs.run_log import RunLog

    spec = SimpleNamespace(objective_names=("progress", "time"), sorl=None)
    log = RunLog(tmp_path, SimpleNamespace(logger="none"), spec)
    ev = MultiContextEvaluator(right_if_progress, {"c": torch.tensor([2.0, 0.5])}, WEIGHTS, gamma=0.5,
                               env_factory=toy_factory)
    r = ev.evaluate()
    for frames in (0, 100, 200):
        log.evaluation(frames, r)
    with (tmp_path / "eval" / "sorl.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 3 * 3 and rows[0].keys() >= {"frames", "context", "weight_index", "weight_progress",
                                                     "sorl_return", "sorl_discounted_return", "best"}
    assert [(x["frames"], x["weight_index"], float(x["sorl_return"]), x["best"]) for x in rows[:3]] == [
        ("0", "0", -7.5, "0"), ("0", "1", 4.5, "1"), ("0", "2", 4.5, "0")]
    assert log.truncate(100) >= 3  # a resume cuts f_SORL rows past the checkpoint like every other log
    with (tmp_path / "eval" / "sorl.csv").open() as fh:
        assert {x["frames"] for x in csv.DictReader(fh)} == {"0", "100"}

    text = "\n".join(run_section(r, tmp_path, "envelope", None, "Toy-v0"))
    assert (tmp_path / "report_fsorl.png").stat().st_size > 5_000 and "(report_fsorl.png)" in text
    assert "| f_SORL max | 4.5 |" in text and "| discounted | 2.62 |" in text
    assert "| progress | **0.90** |" in text and "| time | 0.10 |" in text and "| weight index | 1 |" in text
