"""The morl-trl command line: --version, plain help, KEY=VALUE overrides, warnings, readable envs."""

from __future__ import annotations

import re
from importlib.metadata import version

import pytest

from morl_trl.cli import group_names, main, parse_overrides, plain
from tests.runs._helpers import TINY


def _run(capsys, *args):
    capsys.readouterr()
    try:
        rc = main([str(a) for a in args])
    except SystemExit as exit_:  # argparse's --help / --version
        rc = exit_.code
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_version_comes_from_the_package_metadata(capsys):
    rc, out, _ = _run(capsys, "--version")
    assert rc == 0 and out.strip() == f"morl-trl {version('morl-trl')}"


@pytest.mark.parametrize("command", ["", "train", "evaluate", "envs", "demo", "reference-table", "reference-pack", "grid"])
def test_help_has_no_restructuredtext(capsys, command):
    rc, out, _ = _run(capsys, *([command] if command else []), "--help")
    assert rc == 0 and "usage: morl-trl" in out
    assert "``" not in out and not re.search(r":(func|class|mod|meth):`", out)


def test_plain_strips_markup():
    assert plain("The ``morl-trl`` CLI, :func:`~morl_trl.reporting.table.reference_table`, :class:`Foo`") == \
        "The morl-trl CLI, reference_table, Foo"


def test_overrides_parse_as_toml():
    assert parse_overrides(["lr=1e-3", "hidden=[64, 64]", "prioritized=false", "device=cuda", 'logger="none"',
                            "optim.tau=0.01"]) == dict(lr=1e-3, hidden=[64, 64], prioritized=False, device="cuda",
                                                       logger="none", tau=0.01)
    with pytest.raises(ValueError, match="override 'lr' is not KEY=VALUE"):
        parse_overrides(["lr"])


def test_key_value_overrides_beside_config_and_flags_win(capsys, tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text("lr = 0.5\nbatch_size = 7\nframes = 999\n")
    rc, out, err = _run(capsys, "train", "envelope", "MOLavaGridDR-v0", "lr=1e-3", "hidden=[64,64]", "--config", cfg,
                        "--set", "prioritized=false", "frames=5000", "--frames", "1234", "--print-config")
    assert rc == 0, err
    assert "lr = 0.001 " in out and "hidden = [64, 64] " in out and "prioritized = false " in out
    assert "batch_size = 7 " in out  # the file's, where no override names it
    assert "frames = 1234 " in out  # the flag wins over frames=5000, which wins over the file


def test_unknown_override_says_what_was_meant(capsys):
    rc, _, err = _run(capsys, "train", "envelope", "MOLavaGridDR-v0", "learning_rate=1e-3", "--print-config")
    assert rc == 2
    assert err == ("morl-trl train: error: overrides: unknown config key 'learning_rate' (did you mean 'lr'?); "
                   "morl-trl config envelope ENV_ID prints every key of envelope\n")
    rc, _, err = _run(capsys, "train", "envelope", "MOLavaGridDR-v0", "batchsize=3", "--print-config")
    assert rc == 2 and "unknown config key 'batchsize' (did you mean 'batch_size'?)" in err
    rc, _, err = _run(capsys, "train", "envelope", "MOLavaGridDR-v0", "hidden=[0]", "--print-config")
    assert rc == 2 and "config key 'hidden' (network)" in err


def test_frames_below_the_learning_start_warns(capsys, tmp_path, monkeypatch):
    monkeypatch.delenv("MORL_TRL_REFERENCE", raising=False)
    monkeypatch.chdir(tmp_path)
    values = {**TINY, "frames": 128, "init_random_frames": 256, "eval_interval": 128}
    overrides = [f"{k}={v!r}".replace("'", '"').replace("(", "[").replace(")", "]") for k, v in values.items()
                 if k not in ("frames",)]
    overrides = [o.replace("False", "false").replace("True", "true") for o in overrides]
    rc, out, err = _run(capsys, "train", "envelope", "MOLavaGridDR-v0", *overrides, "--frames", 128,
                        "--run-dir", tmp_path / "run", "--logger", "none")
    assert rc == 0, err
    warning = "warning: frames (128) is below init_random_frames (256): the run takes uniformly random actions only"
    assert warning in out and warning in (tmp_path / "run" / "log.txt").read_text()


def test_envs_groups_numbered_parameters(capsys):
    rc, out, _ = _run(capsys, "envs")
    assert rc == 0
    assert ("context (93): lava_x2_y2..lava_x10_y10 (81), goal0_x..goal2_y (6), weight0..weight2 (3), "
            "agent_x, agent_y, agent_dir") in out
    assert "context (7): gravity, wind_power, turbulence_power" in out
    assert group_names(["a1", "a2", "b", "c3", "c4", "c5"]) == ["a1", "a2", "b", "c3..c5 (3)"]
    # the ids without reference data say so where they are listed
    cont = out[out.index("train: MOLunarLanderContinuousDR-v0"):]
    cont = cont[: cont.index("\nMO-SuperMarioBros")]
    assert "reference data: none (the authors published no bounds or specialist fronts)" in cont
    discrete = out[out.index("train: MOLunarLanderDR-v0"): out.index("train: MOLunarLanderContinuousDR-v0")]
    assert "reference data: none" not in discrete


def test_progress_bar_shows_one_frame_rate():
    from morl_trl.runs.run import BAR_FORMAT

    # tqdm's frame rate once; its frame-rate ETA replaced by the run's own estimate (the postfix:
    # tests/runs/test_progress.py shows what it holds: the time left and the latest NHGR, no rate)
    assert BAR_FORMAT == "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}, {rate_fmt}{postfix}]"


def test_api_errors_name_python_arguments_and_cli_errors_name_flags(tmp_path, capsys):
    from morl_trl.cli import cli_wording, main
    from morl_trl.recipes import resolve_config, train

    run = tmp_path / "taken"
    run.mkdir()
    (run / "notes.txt").write_text("not a run")
    with pytest.raises(ValueError) as api:
        train(resolve_config("envelope", "MOLavaGridDR-v0", quick=True, run_dir=str(run)))
    message = str(api.value)
    assert f"continue it with resume={str(run)!r}, replace it with overwrite=True, or choose another run_dir=" in message
    assert "--" not in message
    assert main(["train", "envelope", "MOLavaGridDR-v0", "--quick", "--run-dir", str(run)]) == 2
    err = capsys.readouterr().err
    assert f"continue it with --resume {str(run)!r}, replace it with --overwrite, or choose another --run-dir" in err
    assert "overwrite=True" not in err and "resume=" not in err
    assert cli_wording("pass one with ref_point=[...] (a config key)") == "pass one with --ref-point (a config key)"
    assert cli_wording("config key 'frames' (collector) is 'x'") == "config key 'frames' (collector) is 'x'"


# ---------------------------------------------------------------------- issue 45: a CLI that answers at once
def test_help_and_argument_errors_import_no_torch():
    """``--help``, ``train --help`` and argument errors are answered before torch is imported
    (benchmarks/bench_cli.py times them)."""
    import subprocess
    import sys

    probe = ("import sys\nfrom morl_trl.cli import main\nfor argv in (['--help'], ['train', '--help'], "
             "['train', 'envelop', 'x'], ['train', 'envelope', 'x', '--frames', '0'], "
             "['train', 'envelope', 'x', 'learning_rate=1'], ['train']):\n"
             "    try:\n        main(argv)\n    except SystemExit:\n        pass\n"
             "print(sorted(m for m in ('torch', 'torchrl', 'tensordict', 'gymnasium', 'numpy') if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip().splitlines()[-1] == "[]", out.stderr


@pytest.mark.parametrize("text, frames", [("3000", 3000), ("1e5", 100_000), ("100k", 100_000), ("3M", 3_000_000),
                                          ("1.5k", 1500), ("2_000", 2000)])
def test_frames_take_exponents_and_suffixes(capsys, text, frames):
    from morl_trl.cli_args import frame_count

    assert frame_count(text) == frames


@pytest.mark.parametrize("text", ["0", "-5", "abc", "1.5", "1e-3", "inf", "k"])
def test_frames_that_are_not_a_count_are_refused_naming_the_value(capsys, text):
    rc, _, err = _run(capsys, "train", "envelope", "MOLavaGridDR-v0", "--frames", text)
    assert rc == 2
    assert f"argument --frames: {text!r} is not a frame count: give a whole number >= 1, e.g. 3000, 1e5, 100k or 3M" in err


def test_negative_ref_point_works_as_typed(capsys):
    rc, out, err = _run(capsys, "train", "envelope", "deep-sea-treasure-v0", "--ref-point", "-1,-30", "--print-config")
    assert rc == 0, err
    assert "ref_point = [-1.0, -30.0]" in out
    rc, _, err = _run(capsys, "train", "envelope", "deep-sea-treasure-v0", "--ref-point", "-1,x", "--print-config")
    assert rc == 2 and "--ref-point '-1,x': give one number per objective, comma-separated, e.g. 0,-25" in err


def test_unknown_algorithm_and_env_id_say_what_was_meant(capsys):
    rc, _, err = _run(capsys, "train", "envelop", "MOLavaGridDR-v0")
    assert rc == 2
    assert err.startswith("morl-trl train: error: unknown algorithm 'envelop' (did you mean 'envelope'?); valid: "
                          "envelope, capql, ")
    rc, _, err = _run(capsys, "train", "envelope", "four-rooms-v0", "--print-config")
    assert rc == 2 and "unknown env id 'four-rooms-v0' (did you mean 'four-room-v0'?)" in err
    rc, _, err = _run(capsys, "train")
    assert rc == 2 and "the following arguments are required: ALGO, ENV_ID (or --resume RUN_DIR alone)" in err


def test_resume_reads_algo_and_env_from_the_run(capsys, tmp_path):
    from morl_trl.recipes import resolve_config

    run = tmp_path / "run"
    run.mkdir()
    resolve_config("pcn", "MOLavaGridDR-v0", quick=True, frames=4000).save(run / "config.json")
    rc, out, err = _run(capsys, "train", "--resume", run, "--frames", "8k", "--print-config")
    assert rc == 0, err
    assert 'algo = "pcn"' in out and 'env_id = "MOLavaGridDR-v0"' in out and "frames = 8000 " in out
    rc, out, err = _run(capsys, "train", "pcn", "MOLavaGridDR-v0", "--resume", run, "--print-config")
    assert rc == 0, err  # given, they agree with the run's
    rc, _, err = _run(capsys, "train", "envelope", "--resume", run, "--print-config")
    assert rc == 2 and "cannot resume: algo is 'envelope' in the command line but 'pcn' in the run's config.json" in err
    rc, _, err = _run(capsys, "train", "pcn", "MOLavaGridDR-v0", "--resume", run, "--ref-point", "-1,-1,-1",
                      "--print-config")
    assert rc == 2 and "cannot resume: ref_point is (-1.0, -1.0, -1.0) in the command line" in err
