"""The training recipes on a DeepMind Control Suite domain: no reference data, so NHGR is
reported as unavailable and the report sets hypervolume and EUM beside the random policy's."""

import csv

import pytest

pytest.importorskip("dm_control", reason="the DMC domains need dm_control (pip install 'morl-trl[dmc]')")

from morl_trl.recipes import resolve_config, train  # noqa: E402


def test_config_takes_the_dmc_domains_defaults():
    cfg = resolve_config("capql", "DMCWalkerDR-v0")
    assert (cfg.frames, cfg.history_len, cfg.eval_interval, cfg.eval_weights) == (1_000_000, 2, 50_000, 32)


def test_no_reference_data_means_no_nhgr():
    from morl_trl.envs import domain_of
    from morl_trl.training.parts import load_reference, no_reference_note

    spec = domain_of("DMCHopperDR-v0")
    assert load_reference(resolve_config("capql", "DMCHopperDR-v0"), spec) is None
    assert no_reference_note(spec).startswith("NHGR unavailable for DMCHopperDR-v0: no reference data")


@pytest.mark.slow  # ~40 s: three evaluations of 1000-step episodes
def test_capql_runs_on_dmc_and_says_nhgr_is_unavailable(tmp_path, capsys):
    cfg = resolve_config(
        "capql", "DMCCheetahDR-v0", quick=True, run_dir=str(tmp_path / "run"), frames=256, num_envs=4,
        frames_per_batch=64, init_random_frames=128, updates_per_batch=2, batch_size=32, hidden=(32, 32),
        eval_interval=256, eval_weights=3, checkpoint_interval=256, buffer_size=4096, progress=False,
        eval_contexts=("DMCCheetahDefault-v0", "DMCCheetahSlippery-v0"), reference_dir=None,
    )
    summary = train(cfg)
    out = capsys.readouterr().out + capsys.readouterr().err
    assert "NHGR unavailable for DMCCheetahDR-v0: no reference data" in out
    with (tmp_path / "run" / "eval" / "metrics.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["frames"], r["context"]) for r in rows] == [
        (f, c) for f in ("0", "256") for c in ("DMCCheetahDefault-v0", "DMCCheetahSlippery-v0")]
    # 2 objectives in [0, 1] per step, gamma 0.99: every discounted return is in [0, 100]
    assert all(0.0 < float(r["hypervolume"]) <= 100.0 ** 2 for r in rows)
    assert all(0.0 < float(r["eum"]) <= 100.0 for r in rows)
    report = (tmp_path / "run" / "report.md").read_text()
    assert "NHGR: unavailable" in report and "| nhgr" not in report
    assert "## Against a uniformly random policy" in report and "eum (random)" in report
    assert summary["frames"] == 256
