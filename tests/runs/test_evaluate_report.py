"""``morl-trl evaluate`` writes the report the training run wrote: the random policy's and the
floor's NHGR columns included, each naming its weights."""

from morl_trl.recipes import resolve_config, train
from morl_trl.recipes.off_policy import evaluate_run


def test_reevaluation_keeps_the_random_policy_and_the_floor(tmp_path, capsys):
    cfg = resolve_config("envelope", "MOLavaGridDR-v0", frames=128, num_envs=2, frames_per_batch=64,
                         init_random_frames=64, updates_per_batch=1, batch_size=16, hidden=(8, 8), eval_interval=128,
                         eval_weights=2, checkpoint_interval=128, buffer_size=256, progress=False,
                         eval_contexts=("MOLavaGridRoom-v0",), eval_random_baseline=True,
                         run_dir=str(tmp_path / "run"))
    train(cfg)
    trained = (tmp_path / "run" / "report.md").read_text()
    capsys.readouterr()
    evaluate_run(tmp_path / "run")
    again = (tmp_path / "run" / "reevaluation" / "report.md").read_text()
    header = "| context | envelope (ours, 2 weights, 128 frames) | random policy (2 weights) | floor: "
    assert header in trained and header in again
    room = [line for line in again.splitlines() if line.startswith("| MOLavaGridRoom-v0 | ")][-1]
    assert room == [line for line in trained.splitlines() if line.startswith("| MOLavaGridRoom-v0 | ")][-1]
    assert "| context | envelope (ours" in capsys.readouterr().out  # (the CLI's evaluate prints the tables)
