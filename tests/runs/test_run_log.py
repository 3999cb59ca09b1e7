"""RunLog's training-episode rows: held in memory, appended together, complete at every checkpoint."""

import csv
from types import SimpleNamespace

import torch
from tensordict import TensorDict

from morl_trl.envs import domain_of
from morl_trl.runs.run_log import RunLog


def _batch(done: list[bool], ret: float) -> TensorDict:
    n = len(done)
    nxt = TensorDict(done=torch.tensor(done).reshape(n, 1), episode_return=torch.full((n, 2), ret),
                     episode_discounted_return=torch.full((n, 2), ret / 2), batch_size=[n])
    return TensorDict(next=nxt, preference=torch.tensor([[0.25, 0.75]] * n), batch_size=[n])


def test_episode_rows_wait_in_memory_until_a_flush(tmp_path, monkeypatch):
    log = RunLog(tmp_path, SimpleNamespace(logger="none"), domain_of("deep-sea-treasure-v0"))
    monkeypatch.setattr(RunLog, "FLUSH_SECONDS", 3600.0)
    log.training_episodes(1, _batch([True], 1.5))
    log.training_episodes(2, _batch([False], 9.0))  # (no episode ended)
    log.training_episodes(3, _batch([True, True], -2.0))
    path = tmp_path / "train" / "episodes.csv"
    assert not path.exists()
    log.flush()
    rows = list(csv.DictReader(path.open()))
    assert [(r["frames"], r["return_treasure"], r["discounted_return_time_penalty"], r["preference_time_penalty"])
            for r in rows] == [("1", "1.5", "0.75", "0.75"), ("3", "-2.0", "-1.0", "0.75"), ("3", "-2.0", "-1.0", "0.75")]
    log.training_episodes(4, _batch([True], 4.0))
    log.close()  # (the end of a run: nothing is left in memory)
    assert [r["frames"] for r in csv.DictReader(path.open())] == ["1", "3", "3", "4"]


def test_a_checkpoint_finds_every_episode_up_to_its_frame_on_disk(tmp_path, monkeypatch):
    from morl_trl.runs.run import Run

    monkeypatch.setattr(RunLog, "FLUSH_SECONDS", 3600.0)
    cfg = SimpleNamespace(frames=10, eval_interval=10, checkpoint_interval=5, keep_checkpoints=2, logger="none",
                          to_dict=lambda: {})
    run = Run(cfg, tmp_path)
    run.log = RunLog(tmp_path, cfg, domain_of("deep-sea-treasure-v0"))
    run.log.training_episodes(5, _batch([True], 3.0))
    run.frames = 5
    run.checkpoint({})
    assert [r["frames"] for r in csv.DictReader((tmp_path / "train" / "episodes.csv").open())] == ["5"]


def test_the_rows_and_scalars_of_ended_episodes_whether_every_row_or_some_ended(tmp_path):
    """A batch whose every row ended (a one-env ``[1, 1]`` batch, here with a context of width 0) and one where
    some did give the rows of the ended sub-envs and, per objective, the mean return over them."""
    log = RunLog(tmp_path, SimpleNamespace(logger="none"), domain_of("deep-sea-treasure-v0"))
    logged = []
    log.logger = SimpleNamespace(log_scalar=lambda name, value, step: logged.append((name, value, step)))
    one = _batch([True], 0.1).unsqueeze(-1)  # [1, 1]
    one["context"] = torch.zeros(1, 1, 0)
    log.training_episodes(1, one)
    some = _batch([True, False, True], 0.0)
    some["next", "episode_return"] = torch.tensor([[1.0, -1.0], [5.0, 5.0], [2.0, -3.0]])
    log.training_episodes(2, some)
    log.flush()
    rows = list(csv.DictReader((tmp_path / "train" / "episodes.csv").open()))
    assert [(r["frames"], r["return_treasure"], r["return_time_penalty"]) for r in rows] == [
        ("1", str(float(torch.tensor(0.1))), str(float(torch.tensor(0.1)))), ("2", "1.0", "-1.0"), ("2", "2.0", "-3.0")]
    assert logged == [("train/episode_return/treasure", float(torch.tensor(0.1)), 1),
                      ("train/episode_return/time_penalty", float(torch.tensor(0.1)), 1),
                      ("train/episode_return/treasure", 1.5, 2), ("train/episode_return/time_penalty", -2.0, 2)]
