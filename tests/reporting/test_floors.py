"""The honest floors: the shipped floors.json, a recomputation, and where the floors show up."""

from __future__ import annotations

import json

import numpy as np
import pytest

from morl_trl.cli import COMMANDS
from morl_trl.envs import domain_of
from morl_trl.reporting.floors import (
    Floor,
    best_floor,
    evaluate_floor,
    floor_entries,
    load_floors,
    trivial_policies,
    update_floors_file,
)
from morl_trl.reporting.reference import load_domain_reference
from morl_trl.reporting.report import floor_column
from morl_trl.reporting.table import format_table

SHIPPED = load_floors()
DOMAINS = ("MOLunarLanderDR-v0", "MOLavaGridDR-v0", "MOHopperDR-v5", "MOHalfCheetahDR-v5", "MOHumanoidDR-v5",
           "MOSuperMarioBrosZeroShot-v2")


def test_floors_is_a_registered_command():
    assert "floors" in COMMANDS


_EXTRA = {"MOLunarLanderDR-v0": "Box2D", "MOHopperDR-v5": "mujoco", "MOHalfCheetahDR-v5": "mujoco",
          "MOHumanoidDR-v5": "mujoco", "MOSuperMarioBrosZeroShot-v2": "nes_py"}


def _needs(domain):
    if domain in _EXTRA:
        pytest.importorskip(_EXTRA[domain])


def test_trivial_policies_are_random_and_every_constant_action():
    _needs("MOLunarLanderDR-v0")
    _needs("MOHopperDR-v5")
    lunar = trivial_policies("MOLunarLanderDR-v0")
    assert list(lunar) == ["random", "noop", "left", "main", "right"]
    assert [int(lunar[k]) for k in ("noop", "left", "main", "right")] == [0, 1, 2, 3]
    assert list(trivial_policies("MOLavaGridDR-v0")) == ["random", "left", "right", "forward"]
    hopper = trivial_policies("MOHopperDR-v5")
    assert list(hopper) == ["random", "zero"] and hopper["zero"].tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("domain", DOMAINS)
def test_shipped_floors_file_structure(domain):
    _needs(domain)  # (the policies' names come from the env's action space)
    assert SHIPPED["command"].startswith("morl-trl floors --reference") and SHIPPED["seed"] == 0
    d = SHIPPED["domains"][domain]
    spec = domain_of(domain)
    assert d["weights"] == spec.eval_weights  # the paper's: 100, Mario 32
    assert d["seed"] == 0 and d["gamma"] == spec.gamma and d["episodes_per_weight"] == 1
    names = list(trivial_policies(domain)) if domain != "MOSuperMarioBrosZeroShot-v2" else None
    pols = d["policies"]
    assert "random" in pols
    if names is not None:  # every trivial policy was computed (Mario: record which were not)
        assert set(pols) == set(names) and d["not_computed"] == []
    else:
        assert "noop" in pols
        assert set(pols) | set(d["not_computed"]) == {"random", "noop", "right", "right + A", "right + B",
                                                     "right + A + B", "A", "left"}
    for name, e in pols.items():
        assert list(e["nhgr"]) == list(spec.evaluation_ids), name
        v = np.array(list(e["nhgr"].values()))
        assert ((0.0 <= v) & (v <= 1.0)).all()
        assert e["mean"] == pytest.approx(v.mean()) and e["std"] == pytest.approx(v.std())
        assert e["command"].startswith("morl-trl floors")
    best = best_floor(SHIPPED, domain)
    assert d["best"] == best.policy and best.mean == max(f.mean for f in floor_entries(SHIPPED, domain))


def test_lunar_lander_noop_floor_is_above_the_papers_envelope():
    noop = SHIPPED["domains"]["MOLunarLanderDR-v0"]["policies"]["noop"]
    assert noop["mean"] > 0.18  # the paper's Envelope: 0.18 ± 0.06


@pytest.mark.parametrize("domain, policy", [("MOLunarLanderDR-v0", "noop"), ("MOLavaGridDR-v0", "random")])
def test_a_shipped_floor_recomputes_exactly(reference_dir, domain, policy):
    _needs(domain)
    # the full protocol (100 weights, seed 0) takes a few seconds on these two
    ref = load_domain_reference(reference_dir, domain)
    floor = evaluate_floor(domain, policy, ref)
    shipped = SHIPPED["domains"][domain]["policies"][policy]["nhgr"]
    assert floor.nhgr == pytest.approx(shipped, abs=1e-9)


def test_reduced_recomputation_is_reproducible(reference_dir, tmp_path):
    _needs("MOLunarLanderDR-v0")
    ref = load_domain_reference(reference_dir, "MOLunarLanderDR-v0")
    a = evaluate_floor("MOLunarLanderDR-v0", "random", ref, weights=6, seed=3)
    b = evaluate_floor("MOLunarLanderDR-v0", "random", ref, weights=6, seed=3)
    assert a.nhgr == b.nhgr and len(a.nhgr) == 8
    path = tmp_path / "floors.json"
    data = update_floors_file(path, a, weights=6, seed=3, gamma=0.99, command="morl-trl floors ...", seconds=1.0,
                              all_policies=["random", "noop"])
    assert data["domains"]["MOLunarLanderDR-v0"]["not_computed"] == ["noop"]
    assert load_floors(path)["domains"]["MOLunarLanderDR-v0"]["policies"]["random"]["nhgr"] == a.nhgr


def _fake_floors():
    return {"domains": {"MOHopperDR-v5": {"policies": {
        "random": {"nhgr": {"a": 0.01, "b": 0.03}}, "zero": {"nhgr": {"a": 0.1, "b": 0.2}}}}}}


def test_floor_row_in_the_reference_table(reference_dir):
    from morl_trl.reporting.table import reference_table

    rows = reference_table(reference_dir, ["MOHopperDR-v5"], eugr=False)
    text = format_table(rows, floors=_fake_floors())
    assert "floor: zero     0.15 ± 0.05" in text
    assert "floor:" not in format_table(rows, floors={})
    assert "floor: " in format_table(rows)  # the shipped file


def test_floor_column_of_the_report():
    label, values = floor_column("MOHopperDR-v5", _fake_floors())
    assert label == "floor: zero" and values == {"a": 0.1, "b": 0.2}
    assert floor_column("MOLavaGridDR-v0", _fake_floors()) is None
    assert Floor("x", "p", {"a": 0.2, "b": 0.4}).std == pytest.approx(0.1)


def test_readme_table_from_the_floors_file():
    from morl_trl.reporting.floors import floors_markdown

    text = floors_markdown(_fake_floors())
    assert "| MO-Hopper |  | 0.02 ± 0.01 | 0.15 ± 0.05 (zero) | 0.54 ± 0.15 (MORL/D SB+PSA) | - |" in text
    shipped = floors_markdown()
    assert "| MO-LunarLander | 100 | " in shipped and "(noop)" in shipped


def test_docs_floors_table_is_generated_from_the_shipped_file():
    import sys
    from pathlib import Path

    from morl_trl.reporting.floors import floors_markdown

    docs = Path(__file__).resolve().parents[2] / "docs"
    page = (docs / "concepts" / "nhgr-and-floors.md").read_text()
    assert "<!-- morl:floors -->" in page  # rendered by docs/hooks/generated.py at build time
    sys.path.insert(0, str(docs / "hooks"))
    import generated

    assert generated.render("x\n<!-- morl:floors -->\ny") == "x\n" + floors_markdown() + "\ny"


def test_floor_at_weights_uses_shipped_file_only_at_its_weights(tmp_path):
    from morl_trl.reporting import load_domain_reference
    from morl_trl.reporting.floors import floor_at_weights

    ref = load_domain_reference("MOLavaGridDR-v0")
    contexts = list(ref.contexts)[:2]
    shipped = {"domains": {"MOLavaGridDR-v0": {"weights": 100, "not_computed": [], "policies": {
        "random": {"nhgr": {c: 0.5 for c in ref.contexts}}, "forward": {"nhgr": {c: 0.25 for c in ref.contexts}}}}}}
    best, where = floor_at_weights("MOLavaGridDR-v0", 100, contexts, ref, shipped=shipped)
    assert best.policy == "random" and best.nhgr == {c: 0.5 for c in contexts} and "shipped" in where
    # at 2 weights the shipped (100-weight) floors do not apply: every trivial policy is evaluated
    cache = tmp_path / "floors.json"
    known = {"random": {c: 0.0 for c in contexts}}
    best, where = floor_at_weights("MOLavaGridDR-v0", 2, contexts, ref, cache=cache, known=known, shipped=shipped)
    assert "2 weights" in where and cache.is_file()
    cached = json.loads(cache.read_text())["domains"]["MOLavaGridDR-v0"]
    assert cached["weights"] == 2 and set(cached["policies"]) == {"random", "left", "right", "forward"}
    assert cached["policies"]["random"]["nhgr"] == {c: 0.0 for c in contexts}   # the known values, not re-evaluated
    again, where2 = floor_at_weights("MOLavaGridDR-v0", 2, contexts, ref, cache=cache, shipped=shipped)
    assert again.nhgr == best.nhgr and "floors.json" in where2
    assert floor_at_weights("MOLunarLanderContinuousDR-v0", 8, contexts, None)[0] is None
