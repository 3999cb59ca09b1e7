"""Every damaged or tampered file of a run or an export gets one clear line (issue 44, finding 5):
the file, what is wrong, what to do. Planted as found: the manifest rehashed (as anyone who can
edit the files can), so that only the loading itself can tell."""

from __future__ import annotations

import hashlib
import json
import shutil
import warnings
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict

from morl_trl.recipes import TrainConfig, evaluate_run, load_policy, train
from morl_trl.recipes.policy import export_policy
from morl_trl.runs.plain import load_plain, save_plain
from tests.runs._helpers import cli, train_tiny

LAST = "frames_000000000512"


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("damaged") / "run"
    train_tiny(run)
    return run


@pytest.fixture
def run(finished, tmp_path) -> Path:
    shutil.copytree(finished, tmp_path / "run")
    return tmp_path / "run"


def _rehash(ckpt: Path) -> None:
    manifest = json.loads((ckpt / "manifest.json").read_text())
    manifest["files"] = {p.name: {"size": p.stat().st_size, "sha256": hashlib.sha256(p.read_bytes()).hexdigest()}
                         for p in ckpt.iterdir() if p.name != "manifest.json"}
    (ckpt / "manifest.json").write_text(json.dumps(manifest))


def _plant_state(run: Path, edit) -> Path:
    ckpt = run / "checkpoints" / LAST
    state = load_plain(ckpt / "state.pt")
    with (ckpt / "state.pt").open("wb") as fh:
        save_plain(edit(state), fh)
    _rehash(ckpt)
    return ckpt


def _one_line(err: BaseException, *parts: str) -> str:
    msg = str(err)
    assert "\n" not in msg and len(msg) < 700, msg
    for part in parts:
        assert part in msg, msg
    return msg


def _resume(run: Path) -> dict:
    """Resume the (finished) run for 64 more frames: it loads its newest checkpoint."""
    return train(TrainConfig.load(run / "config.json").replace(frames=576), resume=run)


LOADERS = {
    "load_policy": lambda run: load_policy(run),
    "export": lambda run: export_policy(run, run.parent / "p.pt"),
    "evaluate": lambda run: evaluate_run(run),
    "resume": _resume,
}


@pytest.mark.parametrize("loader", LOADERS)
def test_a_zero_byte_state_pt_is_one_line(run, loader):
    ckpt = run / "checkpoints" / LAST
    (ckpt / "state.pt").write_bytes(b"")
    _rehash(ckpt)
    with pytest.raises(ValueError) as err:
        LOADERS[loader](run)
    _one_line(err.value, f"{str(ckpt / 'state.pt')!r} is empty (0 bytes)", f"Move checkpoint {str(ckpt)!r} out of")


def test_a_zero_byte_export_is_one_line(run, tmp_path):
    out = tmp_path / "policy.pt"
    out.write_bytes(b"")
    with pytest.raises(ValueError) as err:
        load_policy(out)
    _one_line(err.value, f"{str(out)!r} is empty (0 bytes)", "export the policy again")


def _batch_mismatch(state):
    state["agent"]["loss"] = TensorDict(a=torch.zeros(3, 500), batch_size=[3])  # (its repr is a long dump)
    return state


def _wrong_shape(state):
    loss = state["agent"]["loss"]
    key = next(k for k in loss if k.endswith("weight"))
    loss[key] = torch.zeros(7, 3)
    return state


WRONG_LAYOUTS = {
    "not a dict": (lambda s: [1, 2], "state.pt holds a list, not the dict of a checkpoint"),
    "no agent": (lambda s: {k: v for k, v in s.items() if k != "agent"},
                 {"load_policy": "state.pt has no ['agent']", "resume": "holds no agent, not the state of a envelope "
                                                                        "agent"}),
    "agent not a dict": (lambda s: {**s, "agent": torch.zeros(2)},
                         {"load_policy": "agent is a Tensor, not a dict", "resume": "holds an agent that is a Tensor, "
                                                                                    "not the state of a envelope agent"}),
    "agent empty": (lambda s: {**s, "agent": {}}, "does not hold a envelope agent of this run's config (KeyError"),
    "loss not a state": (lambda s: {**s, "agent": {**s["agent"], "loss": 3}}, "does not hold a envelope agent"),
    "a weight of another shape": (_wrong_shape, "does not hold a envelope agent of this run's config ("),
    "a TensorDict of another batch size": (_batch_mismatch, "does not hold a envelope agent"),
}


@pytest.mark.parametrize("layout", WRONG_LAYOUTS)
@pytest.mark.parametrize("loader", ["load_policy", "resume"])
def test_a_state_pt_of_another_layout_is_one_line(run, loader, layout):
    edit, problem = WRONG_LAYOUTS[layout]
    problem = problem[loader] if isinstance(problem, dict) else problem
    ckpt = _plant_state(run, edit)
    with pytest.raises(ValueError) as err:
        LOADERS[loader](run)
    msg = _one_line(err.value, str(ckpt), problem)
    assert "use the previous checkpoint" in msg


def test_resume_with_generator_states_of_another_layout_is_one_line(run):
    ckpt = _plant_state(run, lambda s: {**s, "rng": {"python": 1}})
    with pytest.raises(ValueError) as err:
        _resume(run)
    _one_line(err.value, f"checkpoint {str(ckpt)!r} is damaged: its random generator states are not what morl_trl "
                         f"writes (TypeError: 'int' object is not subscriptable)")


def _edit_config(run: Path, **changes) -> None:
    cfg = json.loads((run / "config.json").read_text())
    cfg.update(changes)
    (run / "config.json").write_text(json.dumps(cfg))


def test_huge_hidden_sizes_are_refused_before_allocating(run):
    _edit_config(run, hidden=[2e9, 2e9])
    with pytest.raises(ValueError) as err:
        load_policy(run)
    _one_line(err.value, "config key 'hidden' (network) is (2000000000.0, 2000000000.0); valid: a non-empty list of ints "
                         "in [1, 65,536]")


def test_an_algo_changed_in_config_json_is_one_line(run):
    _edit_config(run, algo="gpi_ls")
    with pytest.raises(ValueError) as err:
        load_policy(run)
    _one_line(err.value, f"{str(run / 'config.json')!r} says algo 'gpi_ls', but",
              "was written by a 'envelope' run: the config was changed; set algo back to 'envelope'")


def test_a_config_json_that_is_not_utf8_is_named(run):
    (run / "config.json").write_bytes(b'{"algo": "\xff\xfe"}')
    for load in (load_policy, evaluate_run, _resume):
        with pytest.raises(ValueError) as err:
            load(run)
        _one_line(err.value, f"cannot read the config {str(run / 'config.json')!r}: it is not UTF-8 text (byte 0xff "
                             f"at position 10)")
    out = cli("evaluate", run)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert f"cannot read the config {str(run / 'config.json')!r}: it is not UTF-8 text" in out.stderr


@pytest.mark.parametrize("latest", [b"\xff\xfe\x00garbled", b"frames_999"])
def test_a_garbled_latest_falls_back_to_the_newest_intact_checkpoint_and_says_so(run, latest):
    (run / "checkpoints" / "latest").write_bytes(latest)
    with pytest.warns(UserWarning, match="skipped damaged checkpoint latest of .*: (is not UTF-8 text \\(garbled\\)|names "
                                         "'frames_999', which is not a checkpoint of this run); using the newest "
                                         f"intact checkpoint instead; using {LAST}"):
        assert load_policy(run).frames == 512
    assert _resume(run)["frames"] == 576  # (and the resume continues from it)
    assert "warning: skipped damaged checkpoint latest: " in (run / "log.txt").read_text()


def test_export_falls_back_with_a_warning_when_the_newest_checkpoint_is_damaged(run, tmp_path):
    (run / "checkpoints" / LAST / "state.pt").write_bytes(b"damaged")
    out = cli("export", run, "--out", tmp_path / "p.pt")
    assert out.returncode == 0, out.stderr
    assert out.stderr.strip() == (f"warning: skipped damaged checkpoint {LAST} of {str(run)!r}: state.pt has 7 bytes; "
                                  f"{(run / 'checkpoints' / 'frames_000000000256' / 'state.pt').stat().st_size} were "
                                  f"written; using frames_000000000256").replace(
        f"{(run / 'checkpoints' / 'frames_000000000256' / 'state.pt').stat().st_size}",
        str(json.loads((run / "checkpoints" / LAST / "manifest.json").read_text())["files"]["state.pt"]["size"]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert load_policy(tmp_path / "p.pt").frames == 256
