"""A module named in a shared run's (or export's) config is never imported without the opt-in.

Planted as found (issue 44, finding 1): a run folder holding ``evil.py`` and a ``config.json``
naming ``"domain_modules": ["<run folder>.evil"]``, loaded from the folder that holds it (on
``sys.path``, as ``python -c`` / a REPL / a notebook started there); an export with a
``model/evil.py`` beside it; and the console script asked to import an installed module
(``["this"]`` printed the Zen of Python). ``evil.py`` writes a marker file when imported.
"""

from __future__ import annotations

import json
import shutil
import sys
import uuid
from pathlib import Path

import pytest

from morl_trl.envs.trust import UntrustedCodeError, check_trusted
from morl_trl.recipes import evaluate_run, load_policy, train
from morl_trl.recipes.convert import convert_run
from morl_trl.recipes.policy import export_policy


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    from tests.runs._helpers import train_tiny

    run = tmp_path_factory.mktemp("trust") / "run"
    train_tiny(run)
    return run


@pytest.fixture
def shared(finished, tmp_path, monkeypatch):
    """``<tmp>/shared_<id>/`` (a copy of a finished run) with ``evil.py`` named by its config,
    the folder holding it on ``sys.path``; yields (run, module name, marker)."""
    name = f"shared_{uuid.uuid4().hex[:8]}"
    run = tmp_path / name
    shutil.copytree(finished, run)
    marker = tmp_path / "executed"
    (run / "evil.py").write_text(f"open({str(marker)!r}, 'w').write('executed')\n")
    module = f"{name}.evil"
    cfg = json.loads((run / "config.json").read_text())
    cfg["domain_modules"] = [module]
    (run / "config.json").write_text(json.dumps(cfg))
    monkeypatch.syspath_prepend(str(tmp_path))
    yield run, module, marker
    for m in [m for m in sys.modules if m.startswith(name)]:
        del sys.modules[m]


def _refused(err: pytest.ExceptionInfo, module: str) -> None:
    msg = str(err.value)
    assert f"names the domain module {module!r}: importing it would run its code, so it was not imported" in msg
    assert f"pass --trust-code {module} (trust_code=True in Python)" in msg


LOADERS = {
    "load_policy": lambda run, **kw: load_policy(run, **kw),
    "export": lambda run, **kw: export_policy(run, run.parent / "policy.pt", **kw),
    "evaluate": lambda run, **kw: evaluate_run(run, **kw),
    "resume": lambda run, **kw: train(resume=run, **kw),
}


@pytest.mark.parametrize("loader", LOADERS)
def test_a_module_named_by_a_run_config_is_not_imported(shared, loader):
    run, module, marker = shared
    with pytest.raises(UntrustedCodeError) as err:
        LOADERS[loader](run)
    _refused(err, module)
    assert not marker.exists()


def test_convert_run_imports_nothing_the_config_names(shared):
    run, module, marker = shared
    assert convert_run(run) == []  # (nothing to convert: every checkpoint is of the current format)
    assert not marker.exists() and module not in sys.modules


def test_trust_code_imports_it(shared):  # the payload is live: the opt-in runs it
    run, module, marker = shared
    assert load_policy(run, trust_code=[module]).frames == 512
    assert marker.read_text() == "executed"


def test_a_module_named_by_an_export_is_not_imported(finished, tmp_path, monkeypatch):
    name = f"model_{uuid.uuid4().hex[:8]}"
    folder = tmp_path / name
    folder.mkdir()
    marker = tmp_path / "executed"
    (folder / "evil.py").write_text(f"open({str(marker)!r}, 'w').write('executed')\n")
    policy = load_policy(finished)
    policy.config.domain_modules = (f"{name}.evil",)
    out = policy.save(folder / "policy.pt")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(UntrustedCodeError) as err:
        load_policy(out)
    _refused(err, f"{name}.evil")
    assert not marker.exists()
    assert "the policy export" in str(err.value)


def test_the_console_script_does_not_import_an_installed_module_the_config_names(shared, tmp_path, capsys,
                                                                                  monkeypatch):
    from morl_trl.cli import main

    run, _, _ = shared
    cfg = json.loads((run / "config.json").read_text())
    cfg["domain_modules"] = ["this"]  # (the Zen of Python: printed when imported)
    (run / "config.json").write_text(json.dumps(cfg))
    monkeypatch.delitem(sys.modules, "this", raising=False)
    assert main(["export", str(run), "--out", str(tmp_path / "p.pt")]) == 2
    out = capsys.readouterr()
    assert "Beautiful is better than ugly" not in out.out + out.err and "this" not in sys.modules
    assert out.err.strip() == (
        f"morl-trl export: error: {str(run / 'config.json')!r} names the domain module 'this': importing it would run "
        f"its code, so it was not imported. If you trust where this run comes from, pass --trust-code this "
        f"(trust_code=True in Python), or install the package that registers its domains (entry point "
        f"'morl_trl.domains')")
    assert main(["export", str(run), "--out", str(tmp_path / "p.pt"), "--trust-code", "this"]) == 0
    assert "Beautiful is better than ugly" in capsys.readouterr().out  # (the opt-in imports it)


def test_modules_already_imported_or_trusted_pass():
    check_trusted(["morl_trl.envs.lava_grid.spec", "json"], False, source="x")  # imported: importing runs nothing
    check_trusted(["not_imported_anywhere"], True, source="x")
    check_trusted(["not_imported_anywhere"], ["not_imported_anywhere"], source="x")
    with pytest.raises(UntrustedCodeError, match="'x' names the domain module 'not_imported_anywhere'"):
        check_trusted(["not_imported_anywhere"], ["another"], source="'x'")
