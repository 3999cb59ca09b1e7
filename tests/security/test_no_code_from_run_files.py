"""No loading path executes code planted in a run directory.

A run directory someone shares may have been edited: every file it holds is replaced, one at a
time, by a pickle whose unpickling writes a marker file (the manifest's checksums recomputed,
as an attacker would), and every loading path (``load_policy``, ``evaluate_run``, a resume,
the grid's ``run_cell`` and ``grid_status``) is run on it. The marker must never appear; a
path may fail, but only with a clear error.
"""

from __future__ import annotations

import hashlib
import json
import pickle
import shutil
from pathlib import Path

import pytest
import torch

from morl_trl.grid.runner import run_cell
from morl_trl.grid.spec import Cell
from morl_trl.grid.status import grid_status
from morl_trl.recipes import TrainConfig, evaluate_run, load_policy, resolve_config, train
from morl_trl.runs import UnsafeFileError
from tests.runs._helpers import TINY

NAME = "envelope__MOLavaGridDR-v0__s0"


class Payload:
    """Unpickling this runs ``exec``: it writes ``marker``."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return exec, (f"open({str(self.marker)!r}, 'w').write('executed')",)


def _plant(path: Path, marker: Path) -> None:
    if path.suffix == ".pt":
        torch.save({"agent": Payload(marker)}, path)  # torch's own zip format, as a real checkpoint
    else:
        path.write_bytes(pickle.dumps(Payload(marker)))


def _rehash(run: Path) -> None:
    """Make every manifest match the files again (anyone who can edit the files can)."""
    for manifest in run.glob("checkpoints/frames_*/manifest.json"):
        try:
            data = json.loads(manifest.read_text())
        except ValueError:
            continue  # the manifest itself is the planted file
        ckpt = manifest.parent
        data["files"] = {p.relative_to(ckpt).as_posix(): {"size": p.stat().st_size,
                                                          "sha256": hashlib.sha256(p.read_bytes()).hexdigest()}
                         for p in sorted(ckpt.rglob("*")) if p.is_file() and p.name != "manifest.json"}
        manifest.write_text(json.dumps(data))


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory) -> Path:
    grid = tmp_path_factory.mktemp("grid")
    run = grid / "runs" / NAME
    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), logger="csv", **TINY))
    return run


def _files(run: Path) -> list[str]:
    return sorted(p.relative_to(run).as_posix() for p in run.rglob("*") if p.is_file() and p.name != ".lock")


def _load_policy(run: Path) -> None:
    load_policy(run)


def _evaluate(run: Path) -> None:
    evaluate_run(run)


def _resume(run: Path) -> None:
    cfg = TrainConfig.load(run / "config.json")
    cfg.frames += 64
    train(cfg, resume=run)


def _grid(run: Path) -> None:
    grid_status(run.parent.parent, [(NAME, None)])
    run_cell(Cell("envelope", "MOLavaGridDR-v0", 0, overrides={**TINY, "logger": "csv", "frames": 576}), run)


LOADERS = [_load_policy, _evaluate, _resume, _grid]
# the files a torch/pickle reader would open (the others are JSON / CSV / text, parsed, never
# unpickled: the slow test covers them too)
BINARY = ["checkpoints/frames_000000000512/state.pt", "checkpoints/frames_000000000512/buffer.pt"]


def test_the_payload_is_live(finished_run, tmp_path):
    """(The test can fail: a pickle-loading reader runs the payload.)"""
    marker = tmp_path / "marker"
    _plant(tmp_path / "state.pt", marker)
    torch.load(tmp_path / "state.pt", weights_only=False)
    assert marker.read_text() == "executed"


def test_every_file_of_a_run_is_listed(finished_run):
    files = _files(finished_run)
    assert "checkpoints/frames_000000000512/state.pt" in files and "checkpoints/frames_000000000512/buffer.pt" in files
    assert not [f for f in files if f.endswith(".pkl")]  # no pickles written any more
    assert len(files) > 20


@pytest.mark.parametrize("loader", LOADERS, ids=lambda f: f.__name__.strip("_"))
def test_no_loading_path_runs_code_planted_in_a_checkpoint_file(finished_run, tmp_path, loader):
    assert set(BINARY) <= set(_files(finished_run))
    for rel in BINARY:
        run = tmp_path / rel.replace("/", "_") / "runs" / NAME
        shutil.copytree(finished_run, run)
        marker = tmp_path / f"marker_{rel.replace('/', '_')}"
        _plant(run / rel, marker)
        _rehash(run)
        try:
            loader(run)
        except (ValueError, UnsafeFileError) as err:  # a clear refusal is fine
            assert "Traceback" not in str(err)
        assert not marker.exists(), f"{loader.__name__} ran code planted in {rel}"


@pytest.mark.slow
@pytest.mark.parametrize("loader", LOADERS, ids=lambda f: f.__name__.strip("_"))
def test_no_loading_path_runs_code_planted_in_any_file(finished_run, tmp_path, loader):
    for rel in _files(finished_run):
        run = tmp_path / rel.replace("/", "_") / "runs" / NAME
        shutil.copytree(finished_run, run)
        marker = tmp_path / f"marker_{rel.replace('/', '_')}"
        _plant(run / rel, marker)
        _rehash(run)
        try:
            loader(run)
        except (ValueError, UnsafeFileError):
            pass
        assert not marker.exists(), f"{loader.__name__} ran code planted in {rel}"


def test_an_old_format_checkpoint_with_a_payload_is_refused_without_trust(finished_run, tmp_path):
    """A manifest saying "format 1" (the old pickled layout) is refused unless trusted: the planted
    TorchRL buffer dump (``buffer/prefetch.pkl``) and ``state.pt`` are never read."""
    run = tmp_path / "runs" / NAME
    shutil.copytree(finished_run, run)
    marker = tmp_path / "marker"
    ckpt = run / "checkpoints" / "frames_000000000512"
    (ckpt / "buffer").mkdir()
    _plant(ckpt / "buffer" / "prefetch.pkl", marker)
    _plant(ckpt / "state.pt", marker)
    manifest = json.loads((ckpt / "manifest.json").read_text())
    del manifest["format"]
    (ckpt / "manifest.json").write_text(json.dumps(manifest))
    _rehash(run)
    for loader in LOADERS:
        with pytest.raises(UnsafeFileError, match="old pickled format .* convert it once with `morl-trl convert-run"):
            loader(run)
    assert not marker.exists()
