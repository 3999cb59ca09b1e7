"""A run written by the code of 2026-11-26 (``tests/fixtures/envelope_lavagrid_run``, made by
``tests/fixtures/make_envelope_checkpoint.py``: Envelope on MOLavaGridDR-v0, 256 frames) still
loads, resumes and evaluates. A change of the checkpoint format must keep this passing (through
an explicit opt-in or a conversion step, never by rewriting the fixture)."""

import csv
import shutil
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict

from morl_trl.recipes import TrainConfig, evaluate_run, load_policy, train
from morl_trl.runs import latest_checkpoint

FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "envelope_lavagrid_run"

# the eval policy's Q-values at a fixed input, as the code of 2026-11-26 computed them
_OBS = torch.linspace(-1, 1, 2 * 125).reshape(2, 125)
_PREF = torch.tensor([[0.7, 0.3], [0.2, 0.8]])
_Q = torch.tensor([[[-0.14642, 0.60510], [0.18383, 0.12583], [0.17729, 0.11790]],
                   [[-1.2948, 0.47072], [0.46929, 0.0012675], [0.15306, 0.047155]]])


@pytest.fixture
def run(tmp_path) -> Path:
    dst = tmp_path / "run"
    shutil.copytree(FIXTURE, dst)  # (resuming and evaluating write into the run directory)
    return dst


def test_fixture_loads_with_the_trained_weights(run):
    policy = load_policy(run)
    assert (policy.config.algo, policy.env_id, policy.frames) == ("envelope", "MOLavaGridDR-v0", 256)
    out = policy(TensorDict(observation=_OBS, preference=_PREF, batch_size=[2]))
    torch.testing.assert_close(out["action_value"].detach(), _Q, rtol=0, atol=1e-4)
    assert out["action"].tolist() == [1, 0]


def test_fixture_resumes_and_evaluates(run, reference_dir):
    cfg = TrainConfig.load(run / "config.json")
    cfg.frames = 384  # two more batches of 64 frames
    summary = train(cfg, resume=run)
    assert summary["frames"] == 384
    assert latest_checkpoint(run).name == "frames_000000000384"
    log = (run / "log.txt").read_text()
    assert "resumed from frames_000000000256 at 256 frames" in log
    again = evaluate_run(run, reference_dir=str(reference_dir))
    assert again["frames"] == 384
    with (run / "reevaluation" / "eval" / "metrics.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["frames"], r["context"]) for r in rows] == [("384", "MOLavaGridRoom-v0")]
    assert 0.0 <= float(rows[0]["nhgr"]) <= 1.0
