"""The parity benchmark's report: IQM with bootstrap CIs per library from the per-seed JSON files,
and the cases not run yet named (no MORL-Baselines needed)."""

import importlib.util
import sys
from pathlib import Path

import pytest

PARITY = Path(__file__).resolve().parents[2] / "benchmarks" / "parity"



def test_results_md_from_seed_files(parity, tmp_path):
    from common import result_path, write_result

    out = tmp_path / "results"
    for lib, hv in (("ours", [100.0, 110.0, 120.0]), ("mb", [90.0, 90.0, 90.0])):
        for seed, v in enumerate(hv):
            curve = [dict(frames=0, hypervolume=10.0, eum=0.0, igd=5.0, hv_ratio=0.1),
                     dict(frames=100, hypervolume=v, eum=1.0, igd=1.0, hv_ratio=v / 200)]
            write_result(result_path(out, "gpi_ls-dst", lib, seed),
                         dict(case="gpi_ls-dst", lib=lib, seed=seed, curve=curve, frames=100, train_fps=50.0))
    text = parity.write_results(out, [0, 1, 2], "cmd").read_text()
    assert "Seeds done: mb [0, 1, 2], ours [0, 1, 2]" in text
    # IQM of 3 runs is their trimmed mean; MB's constant runs give a zero-width interval
    assert "| final hypervolume | 90.000 [90.000, 90.000] | 110.000 [" in text
    assert "## envelope-dst\n\n`envelope`" in text and "Not run yet." in text
    assert "pcn-fruit-tree" in text  # the cases without a runner are named
    assert (tmp_path / "gpi_ls-dst.png").is_file()


def test_summary_row_compares_cis_and_frames_per_second(parity, tmp_path):
    from common import current_commit, result_path, write_result

    out = tmp_path / "results"
    for lib, hv, fps in (("ours", [120.0, 121.0, 122.0], 30.0), ("mb", [90.0, 90.0, 90.0], 60.0)):
        for seed, v in enumerate(hv):
            curve = [dict(frames=0, hypervolume=0.0), dict(frames=100, hypervolume=v)]
            write_result(result_path(out, "pcn-dst", lib, seed),
                         dict(case="pcn-dst", lib=lib, seed=seed, curve=curve, frames=100, train_fps=fps))
    text = parity.write_results(out, [0, 1, 2], "cmd").read_text()
    # both learn from frame 0, ours beyond MB (Welch p < 0.05, 31 above a margin of 9); half MB's frames/s
    assert "| pcn-dst | 3 / 3 | 121.00 [" in text
    assert ("| 90.00 [90.00, 90.00] | both learn, ours better (seeds 0-2) | learns (gain 90, p 0) | - | - / - | 30 | 60 "
            "| 0.50x |" in text)  # (no trivial floor computed: "-")
    assert ("| pcn | pcn-dst: both learn, ours better (seeds 0-2) | pcn-dst | pcn-dst: both learn, ours better "
            "(seeds 0-2) |") in text  # per method, with the cases where the reference learns
    assert f"Results in the tables made by: `{current_commit()}` (6 files)\n" in text  # each file records its commit
    assert "| gpi_ls-dst | 0 / 0 | - |" in text  # a case without results is listed, not dropped


def test_frames_per_cpu_second_beside_wall_frames_per_second(parity, tmp_path):
    from common import result_path, write_result

    out = tmp_path / "results"
    for lib, fps, cpu in (("ours", 30.0, 90.0), ("mb", 60.0, 60.0)):
        for seed in range(2):
            curve = [dict(frames=0, hypervolume=0.0), dict(frames=100, hypervolume=1.0 + seed)]
            write_result(result_path(out, "pcn-dst", lib, seed), dict(case="pcn-dst", lib=lib, seed=seed, curve=curve,
                                                                     frames=100, train_fps=fps, train_fps_cpu=cpu,
                                                                     train_seconds=100 / fps, eval_seconds=seed + 1.0))
    text = parity.write_results(out, [0, 1], "cmd").read_text()
    assert "| a run's time, training + evaluations (mean over seeds [min, max]) | mb 3 s [3, 4] | ours 5 s [4, 5] |" in text
    assert "| 30 | 60 | 0.50x (CPU: 1.50x) |" in text  # ours waited for a core: half MB's wall rate, 1.5x per CPU-s
    assert "| training frames per CPU-second (mean) | mb 60 | ours 90 |" in text


def test_each_librarys_final_values_are_read_against_the_trivial_floor(parity, tmp_path):
    from common import case_floor, floor_path, result_path, write_result

    out = tmp_path / "results"
    for lib, hv in (("ours", [120.0, 121.0, 122.0]), ("mb", [90.0, 90.0, 90.0])):
        for seed, v in enumerate(hv):
            curve = [dict(frames=0, hypervolume=0.0), dict(frames=100, hypervolume=v)]
            write_result(result_path(out, "pcn-dst", lib, seed),
                         dict(case="pcn-dst", lib=lib, seed=seed, curve=curve, frames=100, train_fps=1.0))
    # the random policy's front reaches 100 (the constant actions less): MB's 90 from 0 is no learning
    for seed in range(3):
        write_result(floor_path(out, "pcn-dst", seed), dict(policies={
            "random": dict(hypervolume=95.0 + 5 * seed), "action 1": dict(hypervolume=16.8), "action 0": dict(hypervolume=0.0)}))
    assert case_floor(out, "pcn-dst", 2, compute=False)["policies"]["random"]["hypervolume"] == 105.0
    assert case_floor(out, "pcn-dst", 7, compute=False) is None  # not cached, not computed
    text = parity.write_results(out, [0, 1, 2], "cmd").read_text()
    # both learned from frame 0 (the verdict); ours beats the floor at every seed, MB's 90 is below 95-105
    assert ("| 90.00 [90.00, 90.00] | both learn, ours better (seeds 0-2) | learns (gain 90, p 0) | 100.00 (random) "
            "| above the floor (+21, p 0.0059) / not above the floor (-10, p 0.96) |") in text
    assert ("pcn-dst: both learn, ours better (seeds 0-2) [vs the floor: ours above, MB not above]" in text)
    # the floors live beside the runs, not among them
    assert sorted(p.name for p in (out / "pcn-dst").glob("*.json")) == [f"{lib}_s{s}.json" for lib in ("mb", "ours")
                                                                       for s in range(3)]


def test_the_floor_of_deep_sea_treasures_constant_actions_is_its_first_treasure(parity):
    from common import evaluate_floor

    from morl_trl.reporting.floors import trivial_policies

    assert list(trivial_policies("deep-sea-treasure-v0")) == ["random", "action 0", "action 1", "action 2", "action 3"]
    floor = evaluate_floor("deep-sea-treasure-v0", 0.99, 100)
    # "down" (action 1) stops on the first treasure: 0.7 at one step, HV 0.7 * (-1 - -25) against (0, -25); the
    # others never reach a treasure; the random policy's 16 episodes spread over several treasures
    assert {k: round(m["hypervolume"], 2) for k, m in floor.items() if k != "random"} == {
        "action 0": 0.0, "action 1": 16.8, "action 2": 0.0, "action 3": 0.0}
    assert floor["random"]["hypervolume"] > 16.8


def test_mb_multi_policy_acts_with_member_of_nearest_weight(monkeypatch):
    """The MB runner's evaluation rule for MORL/D and PGMORL is ours: the member whose weight is
    nearest to the evaluation weight acts (the first on ties)."""
    monkeypatch.syspath_prepend(str(PARITY))
    spec = importlib.util.spec_from_file_location("mb_runner", PARITY / "mb_runner.py")
    mb_runner = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mb_runner)

    class Member:
        def __init__(self, w, name):
            self.w, self.name = w, name

        def eval(self, obs, w):
            return self.name

    members = [Member([1.0, 0.0], "a"), Member([0.5, 0.5], "b"), Member([0.5, 0.5], "c"), Member([0.0, 1.0], "d")]
    act = mb_runner._nearest(members, lambda m: m.w)
    assert [act(None, w) for w in ([0.9, 0.1], [0.6, 0.4], [0.5, 0.5], [0.2, 0.8])] == ["a", "b", "b", "d"]
    sys.modules.pop("common", None)


def _load_mb_runner(monkeypatch):
    monkeypatch.syspath_prepend(str(PARITY))
    spec = importlib.util.spec_from_file_location("mb_runner", PARITY / "mb_runner.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("name, budget, iterations", [("pgmorl-hopper", (384, 128, 6), 3),
                                                       ("pgmorl-hopper-92k", (15_360, 5_120, 6), 15)])
def test_pgmorl_case_runs_the_same_iterations_on_both_sides(parity, name, budget, iterations):
    """MB 1.3.0 counts every member's frames (max_iterations = frames // steps // envs // pop, then at
    least warm-up + one generation); ours counts one member's: its budget is frames / 6, so both run
    3 PPO iterations of 4 envs x 32 steps per member on pgmorl-hopper (15 of 4 x 256 on pgmorl-hopper-92k:
    10 warm-up, one generation of 5)."""
    from common import CASES

    from morl_trl.algorithms.pgmorl.recipe import pgmorl_iterations

    case = CASES[name]
    mb = case["mb"]
    mb_iterations = max(case["frames"] // mb["steps_per_iteration"] // 4 // 6,
                        mb["warmup_iterations"] + mb["evolutionary_iterations"])
    frames, eval_every, scale = parity.ours_budget(case)
    assert (frames, eval_every, scale) == budget
    steps = case["ours"]["frames_per_batch"] // 24  # per sub-env and iteration
    assert steps == mb["steps_per_iteration"]
    ours_iterations = pgmorl_iterations(frames, 4 * steps, case["ours"]["pgmorl_warmup"],
                                        case["ours"]["pgmorl_evo_iterations"])
    assert mb_iterations == ours_iterations == iterations
    assert parity.ours_budget(CASES["gpi_ls-dst"]) == (2_000, 1_000, 1)  # other cases: the same count


def test_mb_pgmorl_is_evaluated_after_its_archive_changes(monkeypatch):
    """MB's PGMORL archive only changes in __eval_all_agents: the runner evaluates right after it
    (frame 0, then each call at or past the next multiple), never with the archive of an earlier iteration."""
    mb_runner = _load_mb_runner(monkeypatch)

    class FakePGMORL:
        def __init__(self):
            self.global_step, self.archive = 0, []

        def _PGMORL__eval_all_agents(self, *args, **kwargs):
            self.archive = [self.global_step]

    agent, seen = FakePGMORL(), []
    mb_runner.evaluate_after_archive_updates(agent, lambda frames: seen.append((frames, list(agent.archive))), 768)
    for step in (0, 1536, 2304, 2500):  # the calls of train(): before training, after warm-up, generations
        agent.global_step = step
        agent._PGMORL__eval_all_agents()
    assert seen == [(0, [0]), (1536, [1536]), (2304, [2304])]  # 2500 < 2304 + 768: not evaluated
    sys.modules.pop("common", None)


@pytest.mark.slow
def test_smoke_run_of_our_side_writes_a_curve(tmp_path):
    """PARITY_SMOKE=1: a 200-frame run of our PCN on deep-sea-treasure-v0 through the harness."""
    import json
    import os
    import subprocess

    env = {**os.environ, "PARITY_SMOKE": "1", "PYTHONPATH": str(PARITY.parents[1])}
    subprocess.run([sys.executable, str(PARITY / "run_parity.py"), "--cases", "pcn-dst", "--seeds", "0", "--libs",
                    "ours", "--nice", "0", "--out", str(tmp_path / "results")], env=env, check=True, timeout=600)
    data = json.loads((tmp_path / "results" / "pcn-dst" / "ours_s0.json").read_text())
    assert data["frames"] == data["curve"][-1]["frames"] >= 200
    assert data["train_fps"] > 0 and data["curve"][-1]["hypervolume"] >= 0.0
    assert data["train_fps_cpu"] > 0 and 0 < data["train_cpu_seconds"] <= 1.5 * data["train_seconds"] + 1
    assert data["pcn_eval_priorities_restored"] is True  # the evaluation did not re-rank the training's replay
    assert "pcn-dst" in (tmp_path / "RESULTS.md").read_text()
    floor = json.loads((tmp_path / "results" / "pcn-dst" / "floor" / "s0.json").read_text())  # the report's floor
    assert round(floor["policies"]["action 1"]["hypervolume"], 2) == 16.8


def test_mb_venv_is_completed_where_a_dependency_is_missing(parity, tmp_path, monkeypatch):
    """A venv with MB but not its GPI cases' imports (made by hand) gets MB_DEPS, our torch pinned; a
    complete one is left alone; a missing one is created with MB itself first."""
    import torch

    calls, failing = [], set()

    def run(cmd, *args, **kwargs):
        calls.append(cmd)
        if cmd[1:3] == ["-m", "venv"]:
            (tmp_path / "v" / "bin").mkdir(parents=True)
            (tmp_path / "v" / "bin" / "python").touch()
        if cmd[1] == "-m" and cmd[2] == "pip" and "-c" in cmd:
            assert open(cmd[cmd.index("-c") + 1]).read() == f"torch=={torch.__version__}\n"
        return type("Done", (), {"returncode": 1 if (cmd[1] == "-c" and cmd[2] in failing) else 0})()

    monkeypatch.setattr(parity.subprocess, "run", run)
    venv = tmp_path / "v"
    imports = "import " + ", ".join(parity.MB_IMPORTS)
    failing.update({"import morl_baselines", imports})  # absent: create, install MB, then its dependencies
    assert parity.ensure_mb_venv(venv) == venv / "bin" / "python"
    assert [c[1:3] for c in calls] == [["-m", "venv"], ["-c", "import morl_baselines"], ["-m", "pip"],
                                       ["-c", imports], ["-m", "pip"]]
    assert calls[2][-2:] == ["--no-deps", "morl-baselines==1.3.0"] and calls[4][-len(parity.MB_DEPS):] == parity.MB_DEPS
    calls.clear()
    failing.clear()
    failing.add(imports)  # MB there, seaborn & co. not: only the dependencies
    parity.ensure_mb_venv(venv)
    assert [c[1:3] for c in calls] == [["-c", "import morl_baselines"], ["-c", imports], ["-m", "pip"]]
    calls.clear()
    failing.clear()  # complete: nothing installed
    parity.ensure_mb_venv(venv)
    assert [c[1:3] for c in calls] == [["-c", "import morl_baselines"], ["-c", imports]]


def test_results_from_several_commits_are_flagged_and_a_run_without_frame0_is_said(parity, tmp_path):
    from common import result_path, write_result

    out = tmp_path / "results"
    for lib, commit, start in (("ours", "aaa", 0), ("mb", "bbb", 50)):  # MB's first point after frame 0
        for seed in range(2):
            curve = [dict(frames=start, hypervolume=1.0), dict(frames=100, hypervolume=5.0 + seed)]
            write_result(result_path(out, "gpi_ls-dst", lib, seed),
                         dict(case="gpi_ls-dst", lib=lib, seed=seed, curve=curve, frames=100, commit=commit))
    text = parity.write_results(out, [0, 1], "cmd").read_text()
    assert ("Results in the tables made by: `aaa` (2 files), `bbb` (2 files) -- **more than one commit: regenerate from one "
            "commit's runs before quoting**") in text
    assert "| gpi_ls-dst | 2 / 2 |" in text and "| no frame-0 evaluation (seeds 0-1) | no frame-0 evaluation |" in text


def test_the_verdict_is_on_the_rounds_seeds_where_both_libraries_have_them(parity, tmp_path):
    """Round 1's MB runs lack frame 0 (made before the runner had it): with round 2's seeds 100-102 run on both
    sides, the verdict and MB's own learning are computed on those; every seed stays in the tables."""
    from common import result_path, write_result

    out = tmp_path / "results"
    for lib in ("ours", "mb"):
        for seed in (0, 1):  # round 1: MB's curve starts after frame 0
            curve = [dict(frames=0 if lib == "ours" else 50, hypervolume=1.0), dict(frames=100, hypervolume=5.0)]
            write_result(result_path(out, "gpi_ls-dst", lib, seed),
                         dict(case="gpi_ls-dst", lib=lib, seed=seed, curve=curve, frames=100))
        for seed, v in zip((100, 101, 102), (100.0, 101.0, 102.0)):
            curve = [dict(frames=0, hypervolume=0.0), dict(frames=100, hypervolume=v)]
            write_result(result_path(out, "gpi_ls-dst", lib, seed),
                         dict(case="gpi_ls-dst", lib=lib, seed=seed, curve=curve, frames=100))
    text = parity.write_results(out, [100, 101, 102], "cmd").read_text()
    assert "Seeds done: mb [0, 1, 100, 101, 102], ours [0, 1, 100, 101, 102]" in text
    assert "| gpi_ls-dst | 5 / 5 |" in text and "| both learn, at parity (seeds 100-102) | learns (gain 101, p " in text
    text = parity.write_results(out, [200, 201], "cmd").read_text()  # a round not run: every seed, said
    assert "| no frame-0 evaluation (seeds 0, 1, 100, 101, 102) | no frame-0 evaluation |" in text


def test_dst_bound_is_the_deepest_treasure_and_its_discounted_value_from_the_start(parity):
    pytest.importorskip("mo_gymnasium")
    from common import q_bounds

    bounds = q_bounds("deep-sea-treasure-v0", 0.99)
    # 23.7 one step from the deepest treasure; from the start it is 19 steps away: 23.7 * 0.99 ** 18
    assert bounds["any_state"] == pytest.approx(23.7, abs=1e-5)
    assert bounds["start"] == pytest.approx(23.7 * 0.99 ** 18, abs=1e-4)  # 19.778
    assert q_bounds("minecart-v0", 0.98) is None


def test_q_estimate_log_keeps_the_largest_greedy_estimate_and_batch_mean(parity, tmp_path):
    import torch
    from common import QEstimateLog, result_path, write_result

    log = QEstimateLog()
    log.mark(0)
    w = torch.tensor([[1.0, 0.0], [0.5, 0.5]])
    q = torch.tensor([[[30.0, -1.0], [1.0, -1.0]], [[2.0, 0.0], [4.0, 2.0]]])  # greedy w.Q: 30 and 3
    log.record(w, q)
    log.record(w, q * 0.1)
    log.mark(100)
    assert log.points == [dict(frames=0, updates=0, max_scalarized_q=None, max_mean_scalarized_q=None),
                          dict(frames=100, updates=2, max_scalarized_q=30.0, max_mean_scalarized_q=16.5)]
    check = log.result("deep-sea-treasure-v0", 0.99)
    assert check["exceeds_bound"] and not check["mean_exceeds_bound"]  # 30 > 23.7 > 16.5
    curve = [dict(frames=0, hypervolume=1.0, hv_ratio=0.1), dict(frames=100, hypervolume=2.0, hv_ratio=0.5)]
    write_result(result_path(tmp_path / "results", "envelope-dst-mb", "ours", 100),
                 dict(case="envelope-dst-mb", lib="ours", seed=100, curve=curve, frames=100, q_check=check))
    text = parity.write_results(tmp_path / "results", [100], "cmd").read_text()
    assert "| ours | 100 | 30.0 | 16.5 | max | 0.500 |" in text and "| ours | seeds above | 1 of 1 | 0 of 1 | | |" in text


def test_mb_evaluation_leaves_the_global_rng_streams_as_they_were(monkeypatch):
    """The MB runner's evaluations (frame 0 and every eval_every frames inside MB's loop) run under
    preserved_rng: Python's, NumPy's and torch's global streams continue as if nothing had drawn from them."""
    import random

    import numpy as np
    import torch

    mb_runner = _load_mb_runner(monkeypatch)
    random.seed(1), np.random.seed(1), torch.manual_seed(1)
    expected = random.random(), float(np.random.rand()), float(torch.rand(1))
    random.seed(1), np.random.seed(1), torch.manual_seed(1)
    with mb_runner.preserved_rng():
        random.random(), np.random.rand(5), torch.rand(7), torch.manual_seed(99)
    assert (random.random(), float(np.random.rand()), float(torch.rand(1))) == expected
    sys.modules.pop("common", None)


def test_mb_pcn_frame0_commands_and_a_replay_left_as_it_was(monkeypatch):
    """MB's PCN at frame 0 (no episode yet) gets ours' frame-0 commands (zeros, horizon 1); later, the commands
    come from MB's _nlargest, whose in-place re-pricing of the replay is undone (it decides MB's evictions)."""
    import numpy as np
    import torch

    mb_runner = _load_mb_runner(monkeypatch)

    class Step:
        def __init__(self, reward):
            self.reward = np.float32(reward)

    class FakePCN:
        reward_dim = 2
        env = type("E", (), {"action_space": type("S", (), {"n": 4})()})()
        experience_replay: list = []

        def model(self, obs, desired, horizon):
            return torch.zeros(obs.shape[0], 4)

        def _nlargest(self, n):  # as MB's: re-prices every entry, re-heapifies in place, returns the best n
            self.experience_replay[:] = [(-1.0, e[1], e[2]) for e in self.experience_replay][::-1]
            return sorted(self.experience_replay, key=lambda e: -e[2][0].reward.sum())[:n]

    agent = FakePCN()
    policy = mb_runner._pcn_policy(agent, 2)
    returns, horizons = policy._commands()
    assert returns.shape == (16, 2) and not returns.any() and bool((horizons == 1).all())
    agent.experience_replay = [(1, 3, [Step([1.0, 2.0])] * 3), (1, 5, [Step([4.0, 0.0])] * 5)]
    before = list(agent.experience_replay)
    returns, horizons = policy._commands()
    assert agent.experience_replay == before  # same entries, same order, same priorities
    assert returns[:2].tolist() == [[4.0, 0.0], [1.0, 2.0]] and horizons[:2].tolist() == [5.0, 3.0]
    sys.modules.pop("common", None)


def _mb_python():
    import os

    for venv in (os.environ.get("PARITY_MB_VENV"), "/tmp/mbvenv", str(Path.home() / ".cache/morl_trl/mb-1.3.0")):
        if venv and (Path(venv) / "bin" / "python").exists():
            return Path(venv) / "bin" / "python"
    return None


@pytest.mark.parametrize("case", ["pcn-dst", pytest.param("gpi_ls-dst", marks=pytest.mark.slow),
                                  pytest.param("gpi_pd-dst", marks=pytest.mark.slow),
                                  pytest.param("envelope-dst", marks=pytest.mark.slow),
                                  pytest.param("pcn-fruit-tree", marks=pytest.mark.slow),
                                  pytest.param("capql-mountaincar", marks=pytest.mark.slow),
                                  pytest.param("morld-mountaincar", marks=pytest.mark.slow),
                                  pytest.param("mosac-hopper-5k", marks=pytest.mark.slow)])
def test_mb_runner_evaluates_the_untrained_agent_at_frame0(case, tmp_path):
    """PARITY_SMOKE=1 (200 frames): MB's run of a case starts its curve at frame 0, as ours. Needs MB's venv
    (PARITY_MB_VENV, /tmp/mbvenv or run_parity's default): skipped without it. pcn-dst ~10 s; the others slow."""
    import json
    import os
    import subprocess

    python = _mb_python()
    if python is None:
        pytest.skip("no MORL-Baselines venv (PARITY_MB_VENV, /tmp/mbvenv)")
    env = {**os.environ, "PARITY_SMOKE": "1", "PYTHONPATH": str(PARITY.parents[1])}
    subprocess.run([str(python), str(PARITY / "mb_runner.py"), case, "0", str(tmp_path)], env=env, check=True,
                   timeout=600, capture_output=True, cwd=tmp_path)  # (MB's PCN saves weights/ in the cwd)
    curve = json.loads((tmp_path / case / "mb_s0.json").read_text())["curve"]
    assert [p["frames"] for p in curve][:3] == [0, 100, 200]
    assert curve[0]["hypervolume"] is not None


def test_the_benchmarks_own_outputs_do_not_mark_a_commit_dirty(parity):
    """A long run rewrites RESULTS.md and the plots after every round: those (and result files) are not
    uncommitted code, so the next round's results still name the commit alone."""
    from common import _own_output

    assert _own_output("benchmarks/parity/RESULTS.md") and _own_output("benchmarks/parity/gpi_ls-dst-30k.png")
    assert _own_output("benchmarks/parity/results/gpi_ls-dst-30k/ours_s105.json")
    assert not _own_output("benchmarks/parity/common.py") and not _own_output("morl_trl/data/lean.py")
    assert not _own_output("docs/figure.png")


def test_the_sac_case_is_judged_on_the_f_sorl_return_both_loops_record(parity, tmp_path):
    """sac-hopper-10k's metric is the f_SORL return (the best of the evaluation's episodes of the original scalar
    reward, SPEC §3), which ``evaluate_policy`` records where the env emits it (the reference's runs) under the name
    our runs' ``eval/metrics.csv`` gives it; the summary names it in its cells."""
    from common import CASES, case_metric, evaluate_policy, result_path, write_result

    assert case_metric(CASES["sac-hopper-10k"]) == "sorl_return_max" and case_metric(CASES["sac-hopper-5k"]) == "hypervolume"
    room = evaluate_policy("random", "MOLavaGridRoom-v0", 0.99, 100)  # (an env with an original reward)
    assert room["sorl_return_max"] < 0 and room["sorl_discounted_return_max"] > room["sorl_return_max"]
    assert "sorl_return_max" not in evaluate_policy("random", "deep-sea-treasure-v0", 0.99, 100)  # (no such reward)
    out = tmp_path / "results"
    for lib, final in (("ours", [300.0, 320.0, 340.0]), ("torchrl_sac", [200.0, 210.0, 220.0])):
        for seed, v in enumerate(final):
            curve = [dict(frames=0, hypervolume=1.0, sorl_return_max=20.0 + seed),
                     dict(frames=100, hypervolume=1.0, sorl_return_max=v)]
            write_result(result_path(out, "sac-hopper-10k", lib, seed),
                         dict(case="sac-hopper-10k", lib=lib, seed=seed, curve=curve, frames=100, train_fps=10.0))
    text = parity.write_results(out, [0, 1, 2], "cmd").read_text()
    assert "| sac-hopper-10k (ref.: torchrl_sac) | 3 / 3 | 320.000 [" in text and "f_SORL return |" in text
    assert "sac-hopper-10k: both learn, ours better (seeds 0-2)" in text  # (on the f_SORL return; the HV is flat)
    assert "| final f_SORL return (best of the evaluation's episodes) | 320.000 [" in text


def test_one_commits_page_uses_only_that_commits_runs_and_lists_every_other(parity, tmp_path):
    """``--commit``: the tables and the verdict read the runs made at that commit (clean); a run made at another
    commit, a ``+dirty`` one and those set aside under ``earlier/`` and ``superseded/`` are listed, not dropped."""
    from common import result_path, set_aside, write_result

    out = tmp_path / "results"
    new, old = "1234567" + "0" * 33, "abcdef0" + "0" * 33
    for lib in ("ours", "mb"):
        for seed in range(3):
            curve = [dict(frames=0, hypervolume=0.0), dict(frames=100, hypervolume=50.0 + seed)]
            write_result(result_path(out, "pcn-dst", lib, seed),
                         dict(case="pcn-dst", lib=lib, seed=seed, curve=curve, frames=100, commit=old))
            set_aside(result_path(out, "pcn-dst", lib, seed))  # (as a run at --commit does before running it again)
            curve = [dict(frames=0, hypervolume=0.0), dict(frames=100, hypervolume=(100.0 if lib == "ours" else 90.0) + seed)]
            write_result(result_path(out, "pcn-dst", lib, seed),
                         dict(case="pcn-dst", lib=lib, seed=seed, curve=curve, frames=100, commit=new))
    write_result(result_path(out, "pcn-dst", "ours", 7), dict(case="pcn-dst", lib="ours", seed=7, frames=100,
                                                              curve=[dict(frames=100, hypervolume=3.0)],
                                                              commit=new + "+dirty"))
    assert sorted(p.name for p in (out / "pcn-dst" / "earlier").iterdir()) == [
        "mb_s0@abcdef0.json", "mb_s1@abcdef0.json", "mb_s2@abcdef0.json",
        "ours_s0@abcdef0.json", "ours_s1@abcdef0.json", "ours_s2@abcdef0.json"]
    text = parity.write_results(out, [0, 1, 2], "cmd", commit="1234567").read_text()
    assert f"Results in the tables made by: `{new}` (6 files)\n" in text
    assert "Only the runs made at `1234567` (from a clean checkout) are in the tables and verdicts (`--commit`); " \
           "the 7 other runs are listed under their cases." in text
    assert "Seeds done: mb [0, 1, 2], ours [0, 1, 2]" in text  # (not the dirty seed 7)
    from common import machine  # every result records the CPU that made it: another CPU is another trajectory
    assert f"(target: 3 per library); machine: {machine()}\n" in text and machine().endswith(" cores")
    assert "| final hypervolume | 91.000 [90.000, 92.000] | 101.000 [100.000, 102.000] |" in text
    assert "| ours | 1 | `abcdef0` | 0 | 51 | `earlier/` |" in text
    assert "| ours | 7 | `1234567+dirty` | - | 3 | another commit |" in text
    # without --commit: the top-level runs (the dirty one too) in the tables, the set-aside ones listed
    text = parity.write_results(out, [0, 1, 2], "cmd").read_text()
    assert "Seeds done: mb [0, 1, 2], ours [0, 1, 2, 7]" in text
    assert "6 runs set aside (`earlier/`, `superseded/`) are listed under their cases, not used." in text
    # a case with runs at other commits only: its row says what those said, and that they are not this commit's
    for lib in ("ours", "mb"):
        for seed in range(2):
            write_result(result_path(out, "gpi_pd-dst", lib, seed), dict(
                case="gpi_pd-dst", lib=lib, seed=seed, frames=100, commit=old,
                curve=[dict(frames=0, hypervolume=0.0), dict(frames=100, hypervolume=16.8)]))
    text = parity.write_results(out, [0, 1, 2], "cmd", commit="1234567").read_text()
    assert ("| gpi_pd-dst | 0 / 0 | - | - | not run at `1234567` (other commits' runs, seeds 0-1: both learn, at parity) "
            "| - |") in text
    # --case-commit: that case's tables read its own commit's runs (one commit per case, named at the top)
    text = parity.write_results(out, [0, 1, 2], "cmd", commit="1234567", case_commits={"gpi_pd-dst": "abcdef0"}).read_text()
    assert "| gpi_pd-dst | 2 / 2 | 16.80 [16.80, 16.80] | 16.80 [16.80, 16.80] | both learn, at parity (seeds 0-1; < 3 seeds) |" in text
    assert ("(`--commit`), but for the cases run again at a later commit, each from that commit's runs only "
            "(`--case-commit`): `gpi_pd-dst` at `abcdef0`; the 7 other runs") in text
    with pytest.raises(SystemExit, match=r"--case-commit 'gpi_pd-dst=HEAD': give CASE=SHA"):
        parity.main(["--report-only", "--commit", "1234567", "--case-commit", "gpi_pd-dst=HEAD", "--out", str(out)])
    # a case whose runs were all set aside (run again at another commit later): read from earlier/, the latest
    for lib in ("ours", "mb"):
        for seed in range(2):
            path = result_path(out, "pcn-fruit-tree", lib, seed)
            write_result(path, dict(case="pcn-fruit-tree", lib=lib, seed=seed, frames=100, commit=old,
                                    curve=[dict(frames=0, hypervolume=0.0), dict(frames=100, hypervolume=5.0)]))
            set_aside(path)
    text = parity.write_results(out, [0, 1, 2], "cmd", commit="1234567").read_text()
    assert "pcn-fruit-tree: not run at `1234567` (other commits' runs, seeds 0-1: both learn, at parity)" in text
    with pytest.raises(ValueError, match="at least 7 hex digits"):
        parity.write_results(out, [0, 1, 2], "cmd", commit="123")


def test_a_run_at_a_commit_needs_a_clean_checkout_of_it(parity, tmp_path, monkeypatch):
    with pytest.raises(SystemExit, match=r"--commit 'HEAD': give at least 7 lowercase hex digits of a SHA"):
        parity.main(["--report-only", "--commit", "HEAD", "--out", str(tmp_path)])
    monkeypatch.setattr(parity, "current_commit", lambda: "1234567" + "0" * 33 + "+dirty")
    with pytest.raises(SystemExit, match=r"--commit 1234567: this checkout is at 12345670{33}\+dirty; run from a "
                                         r"clean checkout of that commit \(git worktree add DIR 1234567\)"):
        parity.main(["--commit", "1234567", "--cases", "pcn-dst", "--libs", "ours", "--out", str(tmp_path)])
