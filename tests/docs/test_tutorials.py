"""The tutorials run as written: their Python snippets, the module they define, the entry point."""

import importlib
import re
import sys
import textwrap
import tomllib
from pathlib import Path

import pytest

pytest.importorskip("mo_gymnasium")

DOCS = Path(__file__).resolve().parents[2] / "docs"


def _blocks(page: str, lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", (DOCS / page).read_text(), flags=re.S)


def _run(code: str, tmp_path: Path, capsys) -> str:
    exec(compile(code, str(tmp_path / "snippet.py"), "exec"), {"__name__": "__snippet__"})
    return capsys.readouterr().out


@pytest.fixture
def own_domain_module(tmp_path, monkeypatch):
    """Write the tutorial's ``my_domains.py`` where Python finds it."""
    from morl_trl.envs import registry

    registry.list_envs()  # the built-in domains loaded before the snapshot (and before tmp_path is on sys.path)
    saved = dict(registry._DOMAINS), dict(registry._IDS)
    module = next(b for b in _blocks("tutorials/own-domain.md", "python") if b.startswith("# my_domains.py"))
    (tmp_path / "my_domains.py").write_text(module)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    yield tmp_path
    sys.modules.pop("my_domains", None)
    # the tutorial's domains leave with their module: later tests iterate every registered id
    registry._DOMAINS.clear(), registry._DOMAINS.update(saved[0])
    registry._IDS.clear(), registry._IDS.update(saved[1])


@pytest.mark.slow  # (a training run: ~10 s on a free CPU)
def test_own_domain_tutorial_runs_and_its_domain_trains(own_domain_module, capsys):
    snippets = [b for b in _blocks("tutorials/own-domain.md", "python") if not b.startswith("# my_domains.py")]
    lines = _run(snippets[0], own_domain_module, capsys).strip().splitlines()
    first, hv = lines[0], lines[-1]
    assert first == "tensor([ 4., -4.])"  # speed 2 x run (2): progress 4, energy -4
    assert float(hv) >= 0.0


def test_own_domain_module_builds_and_steps(own_domain_module):
    from morl_trl.envs import load_domain_modules, make_env
    import torch

    assert load_domain_modules("my_domains") == ["CorridorDR-v0"]
    env = make_env("CorridorFast-v0", num_envs=2, seed=0)
    td = env.reset().set("action", torch.tensor([1, 2]))
    assert env.step(td)["next", "reward"].tolist() == [[2.0, -1.0], [4.0, -4.0]]


def test_own_domain_through_the_cli_flag_and_the_grid_spec(own_domain_module):
    from morl_trl.grid.spec import GridSpec
    from morl_trl.recipes import resolve_config

    cfg = resolve_config("envelope", "CorridorDR-v0", domain_modules=["my_domains"])
    assert cfg.frames == 20_000 and cfg.eval_weights == 8  # the DomainSpec's protocol
    toml = _blocks("tutorials/own-domain.md", "toml")[0]
    import tomllib

    spec = GridSpec.from_dict(tomllib.loads(toml))
    assert [c.name for c in spec.cells()][:2] == ["envelope__CorridorDR-v0__s0", "envelope__CorridorDR-v0__s1"]
    with pytest.raises(ValueError, match="domain module 'no_such_module' cannot be imported"):
        resolve_config("envelope", "CorridorDR-v0", domain_modules=["no_such_module"])


def test_entry_point_group_registers_an_installed_domain(own_domain_module, monkeypatch):
    dist = own_domain_module / "my_domains-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: my-domains\nVersion: 0.1\n")
    # the tutorial's pyproject.toml table, as pip writes it into the installed entry_points.txt
    table = tomllib.loads(_blocks("tutorials/own-domain.md", "toml")[1])["project"]["entry-points"]["morl_trl.domains"]
    (dist / "entry_points.txt").write_text("[morl_trl.domains]\n" + "".join(f"{k} = {v}\n" for k, v in table.items()))
    from morl_trl.envs import registry

    monkeypatch.setattr(registry, "_IDS", dict(registry._IDS))
    monkeypatch.setattr(registry, "_DOMAINS", dict(registry._DOMAINS))
    importlib.invalidate_caches()  # importlib.metadata caches each sys.path entry's listing
    registry._load_entry_points()
    assert registry.domain_of("CorridorFast-v0").train_id == "CorridorDR-v0"


@pytest.mark.slow  # (a training run)
def test_mo_gymnasium_tutorial_snippet(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    out = _run(_blocks("tutorials/mo-gymnasium.md", "python")[0], tmp_path, capsys)
    lines = out.strip().splitlines()
    assert lines[0] == "torch.Size([4, 2]) (0.0, -25.0)"
    assert all(k in lines[-1] for k in ("'hypervolume'", "'eum'", "'igd'", "'hv_ratio'"))


@pytest.mark.slow  # (a training run)
def test_any_environment_snippet(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    out = _run(_blocks("any-environment.md", "python")[0], tmp_path, capsys)
    lines = out.strip().splitlines()
    assert lines[0].startswith("tensor([[ 0.7000, -1.0000],")
    assert float(lines[-1]) >= 0.0
