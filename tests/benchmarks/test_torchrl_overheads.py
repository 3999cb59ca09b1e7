"""benchmarks/torchrl_overheads.py (issue 47's reproducers of TorchRL's per-call costs) runs on the installed
TorchRL / TensorDict and prints every row: it reaches into private names (``_set_str``, ``_transform.inv``,
``_sampler``) that an upgrade may move."""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_every_reproducer_runs_and_prints_its_row(capsys, monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    sys.modules.pop("torchrl_overheads", None)
    import torchrl_overheads

    assert torchrl_overheads.main(["--calls", "3"]) == 0
    rows = [line.strip() for line in capsys.readouterr().out.splitlines()[1:]]
    names = [" ".join(r.split()[:-1]) for r in rows]
    assert names == [
        "TensorDictReplayBuffer.extend (1 transition)", "TensorDictReplayBuffer.sample (32)",
        "LeanTensorDictReplayBuffer.extend (1 transition)", "LeanTensorDictReplayBuffer.sample (32)",
        "of which: empty Compose.inv (a clone)", "sampler.sample + storage.get",
        "collector batch clone (22 entries, [1, 1])", "TensorDict.set ([1, 2] float, existing key)",
        "the same write, validated=True", "a dict store", "EGreedyModule (one-env batch)",
        "its tensor ops and one write", "TensorDictModule([64, 64] MLP) call", "the MLP's own call"]
    assert all(float(r.split()[-1]) > 0 for r in rows)
