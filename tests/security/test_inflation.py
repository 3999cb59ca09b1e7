"""A small file that inflates to a large one is refused before anything is allocated (issue 44,
finding 7). Planted as found: a 262 KB ``.pt`` whose entries are deflate-compressed, holding a
256 MiB tensor of zeros (``torch.load`` reads it: 256 MiB in a fraction of a second)."""

from __future__ import annotations

import hashlib
import json
import zipfile
from pathlib import Path

import pytest
import torch

from morl_trl.recipes import load_policy, resolve_config
from morl_trl.runs import UnsafeFileError, save_checkpoint
from morl_trl.runs.plain import INFLATION_SLACK, load_plain, save_plain

MIB = 2**20


@pytest.fixture(scope="module")
def bomb(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("bomb")
    plain = folder / "plain.pt"
    torch.save({"agent": {"w": torch.zeros(64 * MIB)}}, plain)  # 256 MiB of float32 zeros (calloc'd: no RSS)
    out = folder / "bomb.pt"
    # (streamed: never 256 MiB in memory at once)
    with zipfile.ZipFile(plain) as src, zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED,
                                                        compresslevel=9) as dst:
        for info in src.infolist():
            with src.open(info) as fin, dst.open(info.filename, "w", force_zip64=True) as fout:
                for chunk in iter(lambda: fin.read(MIB), b""):
                    fout.write(chunk)
    plain.unlink()
    return out


def test_the_bomb_is_live(bomb):
    assert bomb.stat().st_size < 300_000
    with zipfile.ZipFile(bomb) as z:
        assert sum(e.file_size for e in z.infolist()) > 256 * MIB


def test_load_plain_refuses_what_inflates_beyond_its_size(bomb):
    with pytest.raises(UnsafeFileError) as err:
        load_plain(bomb)
    msg = str(err.value)
    assert msg.startswith(f"{str(bomb)!r} would inflate to 268,4")
    assert msg.endswith(f"from {bomb.stat().st_size:,} on disk (7 compressed entries): a file morl_trl writes holds no "
                        f"more than its own size (+ {INFLATION_SLACK:,} bytes), so it is refused before anything is "
                        f"allocated; it was not written by morl_trl")


def test_a_file_of_ours_loads(tmp_path):
    path = tmp_path / "ours.pt"
    with path.open("wb") as fh:
        save_plain({"w": torch.arange(4.0)}, fh)
    assert load_plain(path)["w"].tolist() == [0.0, 1.0, 2.0, 3.0]


def test_a_bomb_planted_as_a_checkpoint_is_refused_by_load_policy(bomb, tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run)).save(run / "config.json")
    ckpt = save_checkpoint(run, 64, {"agent": {}, "frames": 64})
    (ckpt / "state.pt").write_bytes(bomb.read_bytes())
    manifest = json.loads((ckpt / "manifest.json").read_text())  # (rehashed: the manifest does not help)
    data = (ckpt / "state.pt").read_bytes()
    manifest["files"]["state.pt"] = {"size": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    (ckpt / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(UnsafeFileError, match=f"{str(ckpt / 'state.pt')!r} would inflate to 268,4"):
        load_policy(run)
