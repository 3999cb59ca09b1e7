"""Exactness of the one-env speed work (issue 31): a one-env run (MORL-Baselines' configuration,
``num_envs=1, frames_per_batch=1``) from a fixed seed gives the same networks, evaluations and
training logs as before it (values recorded on main at 8e24a7e, 2026-11-26, before the change (GPI-LS's:
see EXPECTED):
the pure-torch segment trees, TorchRL's weight copy every batch, a file append per episode)."""

import csv
from pathlib import Path

import pytest
import torch

import morl_trl
from tests._fingerprint import assert_same_fingerprint
from tests._fingerprint import fingerprint as params_fingerprint

# name -> (algorithm, env id, overrides)
CASES = {
    # Envelope: MORL-Baselines' prioritized rule (RunningMaxPrioritizedSampler)
    "envelope": ("envelope", "deep-sea-treasure-v0", dict(frames=200, hidden=[16, 16], batch_size=8,
                                                          init_random_frames=50, eval_interval=100)),
    # GPI-LS: TorchRL's prioritized rule on our trees (TorchPrioritizedSampler)
    "gpi_ls": ("gpi_ls", "deep-sea-treasure-v0", dict(frames=150, hidden=[16, 16], batch_size=8, init_random_frames=50,
                                                      gpi_gradient_updates=1, gpi_iteration_frames=75,
                                                      eval_interval=10**6)),
    # GPI-LS as before issue 48's first-episode fix: the option that keeps the episodes in progress
    "gpi_ls-support": ("gpi_ls", "deep-sea-treasure-v0", dict(frames=150, hidden=[16, 16], batch_size=8,
                                                              init_random_frames=50, gpi_gradient_updates=1,
                                                              gpi_iteration_frames=75, eval_interval=10**6,
                                                              gpi_first_episode="support")),
}

#: (sum of p * (1 + index / n) over the policy's parameters, hypervolume of each evaluation,
#: training episodes logged, sum of their undiscounted returns)
EXPECTED = {
    # Envelope: recorded again after issue 48 (MB's QNet on foreign envs, the target copied every 200 updates, not
    # 201); before it: (-5.998602081722158, [246.81995421074996, 222.03077598118702, 239.9752753275052], 18,
    # -83.59999877214432)
    "envelope": (-5.899746010424678, [0.0, 0.0, 0.0], 11, -102.80000030994415),
    # GPI-LS: recorded again after issue 48's first-episode fix (gpi_first_episode="w": every sub-env reset at the
    # iteration's start, its first episode acting with w; e_1's first episodes end at the first treasure, hence
    # more episodes); the values before it, recorded on main at f9a6dc4 (the CPU dropout masks of issue 31's GPI
    # update work) before the one-env changes, are "gpi_ls-support"'s: that option gives the old run exactly
    "gpi_ls": (55.65748458514838, [0.0, 16.799999713897705], 39, -94.20000064373016),
    "gpi_ls-support": (55.80534078173923, [0.0, 16.799999713897705], 16, -122.80000054836273),
}


def fingerprint(case: str, tmp_path: Path) -> tuple:
    algo, env_id, overrides = CASES[case]
    run = morl_trl.train(algo, env=env_id, seed=3, eval_weights=4, eval_episodes=1, eval_random_baseline=False,
                         progress=False, logger="csv", run_dir=str(tmp_path / case), **overrides)
    params = params_fingerprint(p for _, p in sorted(run.policy.state_dict().items()))
    d = Path(run.run_dir)
    hv = [float(r["hypervolume"]) for r in csv.DictReader((d / "eval" / "metrics.csv").open())]
    episodes = list(csv.DictReader((d / "train" / "episodes.csv").open()))
    returns = sum(float(v) for r in episodes for k, v in r.items() if k.startswith("return_"))
    return params, hv, len(episodes), returns


@pytest.mark.parametrize("case", [pytest.param("envelope", marks=pytest.mark.slow), "gpi_ls", "gpi_ls-support"])
def test_a_one_env_run_is_what_it_was_before_the_speed_work(case, tmp_path, single_thread):
    (params, scale), hv, n_episodes, returns = fingerprint(case, tmp_path)
    want_params, want_hv, want_episodes, want_returns = EXPECTED[case]
    assert_same_fingerprint(params, scale, want_params)  # (to float32 reordering: tests/_fingerprint.py)
    # returns and hypervolumes: float32 sums of the same rewards (another CPU: ~1e-7); another trajectory
    # moves a return by a whole step's reward (1 of ~100)
    assert hv == pytest.approx(want_hv, rel=1e-6)
    assert (n_episodes, returns) == (want_episodes, pytest.approx(want_returns, rel=1e-6))


if __name__ == "__main__":  # prints the values to record in EXPECTED
    import sys
    import tempfile

    torch.set_num_threads(1)
    for name in sys.argv[1:] or sorted(CASES):
        with tempfile.TemporaryDirectory() as tmp:
            (params, _), *rest = fingerprint(name, Path(tmp))
            print(f"    {name!r}: {(params, *rest)!r},", flush=True)


def test_the_collector_copies_weights_only_when_it_acts_with_a_copy(single_thread):
    from tensordict import TensorDict

    from morl_trl.recipes import build_agent, build_training_env, resolve_config
    from morl_trl.training.parts import make_collector

    cfg = resolve_config("envelope", "deep-sea-treasure-v0", hidden=[8], frames=4, init_random_frames=0)
    env = build_training_env(cfg, torch.device("cpu"))
    agent = build_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
    collector = make_collector(cfg, env, agent.explore_policy, torch.device("cpu"))
    assert collector.shares_policy_weights  # (the same module: nothing to copy)
    collector.update_policy_weights_()
    weights = TensorDict.from_module(agent.explore_policy).data.clone().apply(torch.ones_like)
    collector.update_policy_weights_(weights)  # given weights are still copied in
    assert all(bool((p == 1).all()) for p in agent.explore_policy.parameters())


def test_one_step_batches_are_torchrls(single_thread, monkeypatch):
    """RecipeCollector's one-step rollout and post-processing (a one-env run's every batch) yield TorchRL's
    Collector's batches, entry for entry, random frames and ε-greedy draws included."""
    from torchrl.collectors import Collector

    from morl_trl.recipes import build_agent, build_training_env, resolve_config
    from morl_trl.training.parts import RecipeCollector, make_collector

    def build(collector_cls):
        torch.manual_seed(11)
        cfg = resolve_config("envelope", "deep-sea-treasure-v0", hidden=[8], frames=80, init_random_frames=20, seed=4)
        env = build_training_env(cfg, torch.device("cpu"))
        agent = build_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
        agent.exploration_module.eps.fill_(0.5)
        with monkeypatch.context() as m:
            m.setattr("morl_trl.training.parts.RecipeCollector", collector_cls)
            return make_collector(cfg, env, agent.explore_policy, torch.device("cpu"), return_same_td=True)

    lean, generic = build(RecipeCollector), build(Collector)
    torchrl_rollouts = []
    original = Collector.rollout
    monkeypatch.setattr(Collector, "rollout", lambda self: (torchrl_rollouts.append(self is lean), original(self))[1])
    torch.manual_seed(12)
    a = [b.clone() for b in lean]
    state = torch.get_rng_state()
    torch.manual_seed(12)
    b = [b.clone() for b in generic]
    assert torch.equal(torch.get_rng_state(), state)
    assert len(a) == len(b) == 80 and not any(torchrl_rollouts)  # (every lean batch by the one-step path)
    for i, (x, y) in enumerate(zip(a, b)):
        assert sorted(map(str, x.keys(True, True))) == sorted(map(str, y.keys(True, True))), i
        assert (x == y).all(), i
    assert sum(int(x["next", "done"].sum()) for x in a) >= 3  # (resets inside the compared frames)
