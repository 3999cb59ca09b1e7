"""Damaged reference data: every error names the file and what is wrong; truncated or altered
copies of the published files are caught by the shipped manifest; ``reference-table`` with
nothing to show is an error."""

import json
import shutil

import pytest

from morl_trl.cli import main as cli_main
from morl_trl.reporting.reference import (
    MANIFEST_PATH,
    build_manifest,
    load_domain_reference,
    load_generalist_fronts,
    load_manifest,
    verify_reference,
)
from morl_trl.reporting.table import reference_table

DOMAIN = "MOHopperDR-v5"
SPECIALIST = f"specialist_fronts/{DOMAIN}/MOHopperDefault-v5.csv"


@pytest.fixture
def hopper_copy(reference_dir, tmp_path):
    """A copy of the published Hopper data (bounds, specialist and generalist fronts)."""
    root = tmp_path / "ref"
    (root / "minmax_values").mkdir(parents=True)
    shutil.copy(reference_dir / "minmax_values" / f"{DOMAIN}.json", root / "minmax_values")
    for sub in ("specialist_fronts", "generalist_fronts"):
        shutil.copytree(reference_dir / sub / DOMAIN, root / sub / DOMAIN)
    return root


def _bounds(root):
    return root / "minmax_values" / f"{DOMAIN}.json"


# ----------------------------------------------------------------------------- the manifest
def test_the_shipped_manifest_lists_the_published_layout(reference_dir):
    assert MANIFEST_PATH.is_file() and MANIFEST_PATH.parent.name == "reporting"  # package data (*.json)
    manifest = load_manifest()
    assert manifest["files"][SPECIALIST]["rows"] > 0
    assert manifest["files"][f"minmax_values/{DOMAIN}.json"]["rows"] == 6  # contexts
    assert build_manifest(reference_dir) == manifest  # regenerated from the data: identical
    assert verify_reference(reference_dir) == []


def test_a_specialist_front_cut_at_a_row_boundary_is_caught(hopper_copy):
    path = hopper_copy / SPECIALIST
    lines = path.read_text().splitlines(keepends=True)
    expected = len(lines) - 1
    path.write_text("".join(lines[:60]))  # header + 59 rows: a valid-looking CSV
    with pytest.raises(ValueError, match=rf"{path}: expected {expected} rows .*found 59"):
        load_domain_reference(hopper_copy, DOMAIN)
    load_domain_reference(hopper_copy, DOMAIN, manifest=None)  # other data in the same layout: opt out
    assert any("found 59" in p for p in verify_reference(hopper_copy))


def test_an_altered_value_with_the_right_row_count_is_caught(hopper_copy):
    path = hopper_copy / SPECIALIST
    text = path.read_text()
    first = text.splitlines()[1].split(",")[0]
    path.write_text(text.replace(first, "1.0", 1))
    with pytest.raises(ValueError, match=rf"{path}: its content differs from the published file"):
        load_domain_reference(hopper_copy, DOMAIN)


def test_a_truncated_generalist_front_is_caught(hopper_copy):
    algo = sorted(p for p in (hopper_copy / "generalist_fronts" / DOMAIN).iterdir() if p.is_dir())[0]
    path = sorted((algo / "seed_0").glob("*.csv"))[0] if (algo / "seed_0").is_dir() else sorted(algo.rglob("*.csv"))[0]
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:2]))
    with pytest.raises(ValueError, match=rf"{path}: expected {len(lines) - 1} rows .*found 1"):
        load_generalist_fronts(hopper_copy, DOMAIN)


def test_reference_manifest_cli(hopper_copy, tmp_path, capsys):
    out = tmp_path / "m.json"
    assert cli_main(["reference-manifest", str(hopper_copy), "--write", "--output", str(out)]) == 0
    written = json.loads(out.read_text())
    assert written["files"][SPECIALIST] == load_manifest()["files"][SPECIALIST]
    # the copy holds one domain: every other published file is reported missing
    assert cli_main(["reference-manifest", str(hopper_copy)]) == 2
    assert "difference(s) from the published data" in capsys.readouterr().err


# ----------------------------------------------------------------------------- malformed files
@pytest.mark.parametrize(
    "content, message",
    [
        ("[1, 2, 3]", r"expected an object \{context: .*got a JSON list"),
        ('{"A": {"0": [0, 1]', r"not valid JSON"),
        ("{}", r"no contexts"),
        ('{"A": [0, 1]}', r"context 'A' maps to a JSON list"),
        ('{"A": {"0": [0]}}', r"context 'A', objective '0' is \[0\]; expected \[min, max\]"),
        ('{"A": {"1": [0, 1]}}', r"context 'A': .*lacks objective"),
    ],
)
def test_bad_bounds_files_name_the_file(tmp_path, content, message):
    (tmp_path / "minmax_values").mkdir()
    path = tmp_path / "minmax_values" / "D.json"
    path.write_text(content)
    with pytest.raises(ValueError, match=rf"{path}: {message}"):
        load_domain_reference(tmp_path, "D")


@pytest.mark.parametrize(
    "content, message",
    [
        ("objective_1,objective_2\n1.0,2.0\n3.0\n", r"row 3 has 1 values, the header 2"),
        ("objective_1,objective_2\n1.0,x\n", r"malformed front"),
        ("a,b\n1.0,2.0\n", r"header row is \['a', 'b'\]"),
        ("", r"is empty"),
    ],
)
def test_bad_front_files_name_the_file(tmp_path, content, message):
    (tmp_path / "minmax_values").mkdir()
    (tmp_path / "minmax_values" / "D.json").write_text('{"A": {"0": [0, 1], "1": [0, 1]}}')
    path = tmp_path / "specialist_fronts" / "D" / "A.csv"
    path.parent.mkdir(parents=True)
    path.write_text(content)
    with pytest.raises(ValueError, match=rf"{path}.*{message}"):
        load_domain_reference(tmp_path, "D")


def test_reference_table_with_nothing_to_show_is_an_error(hopper_copy, capsys):
    shutil.rmtree(hopper_copy / "generalist_fronts")
    with pytest.raises(ValueError, match=rf"{hopper_copy}: nothing to show: no generalist fronts"):
        reference_table(hopper_copy)
    assert cli_main(["reference-table", str(hopper_copy)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(hopper_copy) in err and "generalist_fronts/<domain>" in err
    (hopper_copy / "generalist_fronts" / DOMAIN).mkdir(parents=True)  # a domain folder with no runs
    assert cli_main(["reference-table", str(hopper_copy)]) == 2
