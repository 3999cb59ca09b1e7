"""benchmarks/compare_commits.py: the worker times the training loop of the checkout it imports,
and the driver runs it in each checkout and prints one row per pair."""

from __future__ import annotations

from tests.benchmarks._helpers import ROOT, load_benchmark

TINY = {"frames_per_batch": 8, "init_random_frames": 8, "buffer_size": 1024, "num_envs": 4, "batch_size": 8,
        "hidden": [16, 16]}


def _module():
    return load_benchmark("compare_commits")


def test_worker_times_whole_batches_after_learning_starts():
    cc = _module()
    res = cc.time_training("envelope", "MOLavaGridDR-v0", 16, "cpu", TINY)
    assert res["frames"] == 16  # two batches of 8, timed after the 8 random frames and one warm-up batch
    assert res["fps"] > 0 and res["ups"] > 0 and 0 < res["learn_share"] <= 1


def test_driver_prints_a_row_per_pair_for_two_checkouts(capsys, monkeypatch):
    cc = _module()
    calls = []

    def fake_worker(checkout, pair, frames, clock, overrides, warm, timeout):
        calls.append((checkout.name, pair, overrides))
        return {"fps": 10.0 if checkout.name == "old" else 12.0, "learn_share": 0.5}

    monkeypatch.setattr(cc, "run_worker", fake_worker)
    cc.main(["--before", str(ROOT / "old"), "--after", str(ROOT / "new"), "--pairs", "pcn:MOLunarLanderDR-v0",
             "--rounds", "2", "--as-before"])
    out = capsys.readouterr().out
    row = [line for line in out.splitlines() if line.startswith("pcn")][0]
    assert row.split()[2:5] == ["10.0", "12.0", "1.20x"]
    # rounds alternate the checkouts; --as-before configures only 'after' as before
    assert [c[0] for c in calls] == ["old", "new", "new", "old"]
    assert calls[1][2] == {"pcn_er_episodes": 16, "hidden": [64, 64]} and calls[0][2] == {"pcn_er_episodes": 16}


def test_default_pairs_cover_every_method_of_the_authors_record_once():
    from morl_trl.recipes.fidelity import METHODS

    algos = [pair.split(":")[0] for pair in _module().PAIRS]
    assert sorted(algos) == sorted(set(METHODS.values()))
    assert len(algos) == 9
