"""The parity benchmark's MORL/D cases (issue 48): SB and SB+PSA map onto MB 1.3.0's MORLD with the same settings
on both sides, and MB's MORL/D is evaluated right after each exchange (its archive's only update). No MB needed."""

from pathlib import Path

import pytest

PARITY = Path(__file__).resolve().parents[2] / "benchmarks" / "parity"
MORLD_CASES = ["morld-hopper-2obj", "morld_psa-hopper-2obj", "morld-hopper-2obj-6k"]



@pytest.mark.parametrize("name", MORLD_CASES)
def test_morld_cases_give_both_sides_the_same_settings(mb_runner, name):
    """SB: MB's shared_buffer=True on both cases (ours' buffer is always shared); SB+PSA: MB's
    weight_adaptation_method="PSA" where ours' registry name is morld_psa (its weight_adaptation "psa"), none for SB;
    the same exchange period, learning start and archive episodes on both sides; a turn is whole batches of ours'
    collector (frames_per_batch 50) and every evaluation comes after an exchange."""
    from common import CASES

    from morl_trl.recipes.config.resolve import resolve_config

    case = CASES[name]
    ours, mb = case["ours"], case["mb"]
    assert mb_runner.mb_algo(case) == "morld"
    assert mb["shared_buffer"] is True
    assert mb.get("weight_adaptation_method") == ("PSA" if case["algo"] == "morld_psa" else None)
    assert ours["exchange_every"] == mb["exchange_every"]
    assert ours["init_random_frames"] == mb["policy_args"]["learning_starts"]
    assert ours["morld_eval_episodes"] == case["mb_train"]["num_eval_episodes_for_front"]
    cfg = resolve_config(case["algo"], case["env"], **ours)
    assert cfg.weight_adaptation == ("psa" if case["algo"] == "morld_psa" else "none")
    assert cfg.morld_schedule == "round_robin" and cfg.pop_size == 6 and cfg.alpha == 1.0
    assert cfg.exchange_every % cfg.frames_per_batch == 0
    assert case["eval_every"] % ours["exchange_every"] == 0 and case["frames"] % case["eval_every"] == 0


def test_mb_morld_is_evaluated_right_after_each_exchange(mb_runner):
    """MB's MORLD changes its archive only in __eval_all_policies (once before training, then after every
    exchange): the runner evaluates after the call that reaches the next multiple of eval_every, frame 0 after the
    call before the loop (the untrained members archived, as ours' archive_initial_members), with the archive that
    call made, and returns what the call returns (the members' evaluations, which PSA adapts the weights from)."""

    class FakeMORLD:
        def __init__(self):
            self.global_step, self.archive = 0, []

        def _MORLD__eval_all_policies(self, *args, **kwargs):
            self.archive = [self.global_step]
            return ["evals", self.global_step]

    agent, seen = FakeMORLD(), []
    mb_runner.evaluate_after_archive_updates(agent, lambda frames: seen.append((frames, list(agent.archive))), 2000,
                                             mb_runner.ARCHIVE_UPDATES["morld"], first=0)
    returned = []
    for step in (0, 1000, 2000, 3000, 4000):  # train(): before the loop, then after each exchange of 1,000 frames
        agent.global_step = step
        returned.append(agent._MORLD__eval_all_policies())
    assert seen == [(0, [0]), (2000, [2000]), (4000, [4000])]
    assert returned[-1] == ["evals", 4000]


def test_other_cases_keep_their_mb_method(mb_runner):
    from common import CASES

    assert {mb_runner.mb_algo(c) for c in CASES.values()} >= {"envelope", "gpi_ls", "pcn", "capql", "morld", "pgmorl"}
    assert all(mb_runner.mb_algo(c) == c["algo"] for c in CASES.values() if c["algo"] != "morld_psa")
