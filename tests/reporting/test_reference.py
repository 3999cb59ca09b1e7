"""The reference-data loader, its round trip, and the paper's table recomputed from the published data."""

import json

import numpy as np
import pytest

from morl_trl.cli import reference_table_main as main
from morl_trl.metrics import Bounds, hypervolume
from morl_trl.reporting import (
    DomainReference,
    load_domain_reference,
    load_generalist_fronts,
    read_front_csv,
    write_front_csv,
)
from morl_trl.reporting.table import PAPER_NHGR, reference_table


# ----------------------------------------------------------------------------- our own data
def test_from_fronts_merges_specialists_and_takes_bounds_over_all_fronts():
    ref = DomainReference.from_fronts(
        "ToyDR-v0",
        {"A": [np.array([[4.0, 0.0], [1.0, 1.0]]), np.array([[0.0, 4.0], [1.0, 1.0], [0.5, 0.5]])]},
        other_fronts=[{"A": [[-2.0, 1.0]]}],
    )
    assert ref.contexts == ("A",)
    # the combined front: non-dominated union, duplicates and (0.5, 0.5) gone
    assert sorted(map(tuple, ref.specialist_fronts["A"])) == [(0.0, 4.0), (1.0, 1.0), (4.0, 0.0)]
    assert ref.bounds["A"].lower.tolist() == [-2.0, 0.0]
    assert ref.bounds["A"].upper.tolist() == [4.0, 4.0]
    # specialist normalized HV with bounds [-2,4]x[0,4]: points -> (1/3,1), (.5,.25), (1,0)
    assert ref.specialist_normalized_hypervolume("A") == pytest.approx(1 / 3 + (0.5 - 1 / 3) * 0.25)
    assert ref.nhgr("A", ref.specialist_fronts["A"]) == pytest.approx(1.0)


def test_save_and_load_round_trip_in_the_published_layout(tmp_path):
    ref = DomainReference(
        "ToyDR-v0",
        {"B": Bounds([0.0, -1.0], [2.0, 3.0]), "A": ([0.0, 0.0], [1.0, 1.0])},
        {"A": [[0.5, 0.5]], "B": [[1.0 / 3.0, 2.0], [1.5, 0.0]]},
    )
    ref.save(tmp_path)
    assert json.loads((tmp_path / "minmax_values" / "ToyDR-v0.json").read_text()) == {
        "B": {"0": [0.0, 2.0], "1": [-1.0, 3.0]},
        "A": {"0": [0.0, 1.0], "1": [0.0, 1.0]},
    }
    back = load_domain_reference(tmp_path, "ToyDR-v0")
    assert back.contexts == ("B", "A")  # the order of the bounds file
    np.testing.assert_array_equal(back.specialist_fronts["B"], [[1.0 / 3.0, 2.0], [1.5, 0.0]])  # exact floats
    assert back.nhgr("B", [[1.0, 1.0]]) == pytest.approx(ref.nhgr("B", [[1.0, 1.0]]))


def test_generalist_fronts_loader_reads_algorithms_and_seeds(tmp_path):
    DomainReference("D", {"A": ([0, 0], [1, 1])}, {"A": [[1.0, 1.0]]}).save(tmp_path)
    for algo, seed, pts in [("algo x", 5, [[0.5, 0.5]]), ("algo x", 26, [[0.2, 0.9]]), ("y", 1, [[1.0, 0.0]])]:
        write_front_csv(tmp_path / "generalist_fronts" / "D" / algo / f"seed_{seed}" / "A.csv", pts)
    (tmp_path / "generalist_fronts" / "D" / "no_history").mkdir()  # other runs folder: no seeds, skipped
    runs = load_generalist_fronts(tmp_path, "D", ["A"])
    assert list(runs) == ["algo x", "y"]
    assert list(runs["algo x"]) == [5, 26]
    np.testing.assert_array_equal(runs["algo x"][26]["A"], [[0.2, 0.9]])
    rows = reference_table(tmp_path, ["D"], eugr=False)
    assert [r.label for r in rows] == ["algo x", "y"]
    # NHGR per seed: .25 and .18 -> mean .215, population std .035
    assert rows[0].nhgr.ravel().tolist() == pytest.approx([0.25, 0.18])
    assert (rows[0].mean, rows[0].std) == pytest.approx((0.215, 0.035))
    assert rows[1].nhgr.tolist() == [[0.0]]


def test_bad_reference_folders_raise(tmp_path):
    with pytest.raises(ValueError, match="minmax_values"):
        load_domain_reference(tmp_path, "D")
    DomainReference("D", {"A": ([0, 0], [1, 1])}, {"A": [[1.0, 1.0]]}).save(tmp_path)
    with pytest.raises(ValueError, match="no bounds for domain 'E'"):
        load_domain_reference(tmp_path, "E")
    with pytest.raises(ValueError, match="no generalist fronts"):
        load_generalist_fronts(tmp_path, "D")
    with pytest.raises(ValueError, match="no reference for context 'Z'"):
        load_domain_reference(tmp_path, "D").nhgr("Z", [[1.0, 1.0]])
    with pytest.raises(ValueError, match="no specialist front"):
        DomainReference("D", {"A": ([0, 0], [1, 1])}, {})
    with pytest.raises(ValueError, match="upper must be > lower"):
        Bounds.from_json_entry({"0": [1.0, 1.0]})
    (tmp_path / "bad.csv").write_text("objective_1,objective_2\n1.0,nan\n")
    with pytest.raises(ValueError, match="finite"):
        read_front_csv(tmp_path / "bad.csv")
    assert main([str(tmp_path / "nowhere")]) == 2


# ----------------------------------------------------------------------------- the published data
@pytest.fixture(scope="module")
def table(reference_dir):
    return {(r.domain, r.label): r for r in reference_table(reference_dir, eugr=True)}


@pytest.mark.parametrize(
    "domain, label, expected",
    [
        ("MOLunarLanderDR-v0", "GPI-LS", "0.66 ± 0.06"),
        ("MOHopperDR-v5", "MORL/D SB+PSA", "0.54 ± 0.15"),
        ("MOHumanoidDR-v5", "MORL/D SB", "0.44 ± 0.19"),
        ("MOLavaGridDR-v0", "MORL/D SB", "0.37 ± 0.21"),
    ],
)
def test_the_issue_targets(table, domain, label, expected):
    r = table[domain, label]
    assert f"{r.mean:.2f} ± {r.std:.2f}" == expected
    assert r.nhgr.shape[0] == 5  # five seeds, pooled with every context


def test_every_published_value_of_the_nhgr_table(table):
    checked = 0
    for domain, algos in PAPER_NHGR.items():
        for label, (m, s) in algos.items():
            r = table[domain, label]
            assert f"{r.mean:.2f} ± {r.std:.2f}" == f"{m:.2f} ± {s:.2f}", (domain, label)
            checked += 1
    assert checked == 39  # 7 + 8 + 7 + 7 + 6 + 4
    # GPI-PD on LavaGrid has fronts but no published score
    assert table["MOLavaGridDR-v0", "GPI-PD"].paper is None


@pytest.mark.parametrize(
    "domain, label, iqm, og",
    [  # the paper's text (§5): IQM and optimality gap of each domain's best algorithm
        ("MOLunarLanderDR-v0", "GPI-LS", 0.66, 0.339),
        ("MOHopperDR-v5", "MORL/D SB+PSA", 0.56, 0.464),
        ("MOHalfCheetahDR-v5", "MORL/D SB+PSA", 0.28, None),
        ("MOHumanoidDR-v5", "MORL/D SB", 0.41, None),
        ("MOSuperMarioBrosZeroShot-v2", "GPI-LS", 0.07, 0.877),
        ("MOLavaGridDR-v0", "MORL/D SB", 0.37, None),
    ],
)
def test_iqm_and_optimality_gap_match_the_paper_text(table, domain, label, iqm, og):
    r = table[domain, label]
    assert round(r.iqm, 2) == iqm
    if og is not None:
        assert round(r.optimality_gap, 3) == og


def test_eugr_on_energy_weights_matches_the_appendix_where_weights_do_not_matter(table):
    # Appendix Table: Hopper and Humanoid EUGR agree exactly; LunarLander's used other weights
    assert f"{table['MOHopperDR-v5', 'MORL/D SB+PSA'].eugr.mean():.2f}" == "0.80"
    assert f"{table['MOHumanoidDR-v5', 'CAPQL'].eugr.mean():.2f}" == "0.55"
    assert abs(table["MOLunarLanderDR-v0", "GPI-LS"].eugr.mean() - 0.50) < 0.03


@pytest.mark.parametrize(
    "domain, algo, ref_point, scale, expected",
    [  # appendix Table (HV, mean ± pooled std): the unnormalized HV with the paper's reference points
        ("MOLunarLanderDR-v0", "GPI-LS", [-101, -1001, -101, -101], 1e8, "9.08 ± 0.55"),
        ("MOHopperDR-v5", "CAPQL", [-100, -100, -100], 1e7, "1.40 ± 0.20"),
        ("MOLavaGridDR-v0", "MORL-D(MOSACDiscrete)-SB", [-1000, -500], 1e5, "3.54 ± 1.88"),
    ],
)
def test_unnormalized_hypervolume_matches_the_appendix(reference_dir, domain, algo, ref_point, scale, expected):
    runs = load_generalist_fronts(reference_dir, domain, load_domain_reference(reference_dir, domain).contexts)[algo]
    hv = np.array(
        [[hypervolume(f, ref_point, drop_unbounded=True) for f in by_ctx.values()] for by_ctx in runs.values()]
    ) / scale
    assert f"{hv.mean():.2f} ± {hv.std():.2f}" == expected


def test_cli_prints_the_table(reference_dir, capsys, tmp_path):
    out_csv = tmp_path / "t.csv"
    assert main([str(reference_dir), "--domain", "MOHopperDR-v5", "--ci", "--reps", "2000", "--csv", str(out_csv)]) == 0
    out = capsys.readouterr().out
    assert "MO-Hopper (MOHopperDR-v5)" in out
    line = next(l for l in out.splitlines() if l.strip().startswith("MORL/D SB+PSA"))
    assert "0.54 ± 0.15" in line and "0.557" in line and "0.464" in line and "(match)" in line
    assert "DIFFERS" not in out
    assert out_csv.read_text().count("\n") == 9  # header + 8 algorithms
