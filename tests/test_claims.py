"""Every "as the authors" / "as the paper" claim in the package, README.md, the examples and the
docs has a row in docs/claims.md (issue 27), and every test a row names exists.

A row is matched to a claim by its file path and a short quoted snippet of the claim's line
(robust to line moves). Rows whose verdict is ``changed`` record a claim that was reworded; the
others must still find their snippet in their file.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CLAIMS = ROOT / "docs" / "claims.md"
PHRASE = re.compile(r"as the (authors|paper)", re.IGNORECASE)
VERDICTS = {"tested", "source-only", "changed", "not yet checked"}
# docs/fidelity.md is generated from the fidelity table (morl_trl/recipes/fidelity.py)
SKIP_DOCS = {"claims.md", "fidelity.md"}


def _scanned_files() -> list[Path]:
    files = sorted((ROOT / "morl_trl").rglob("*.py")) + [ROOT / "README.md"]
    files += sorted((ROOT / "examples").rglob("*.py"))
    files += sorted(p for p in (ROOT / "docs").rglob("*.md") if p.name not in SKIP_DOCS)
    return files


def _rows() -> list[dict[str, str]]:
    """The claims table: | location | snippet | claim | source | test | verdict |."""
    rows = []
    for line in CLAIMS.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 6 or not cells[0].startswith("`") or cells[0] == "location":
            continue
        location, snippet, claim, source, test, verdict = cells
        rows.append({
            "path": location.strip("`").split(":")[0],
            "snippet": snippet.strip("`").strip('"'),
            "claim": claim, "source": source, "test": test, "verdict": verdict,
        })
    return rows


def _hits() -> list[tuple[str, int, str]]:
    hits = []
    for path in _scanned_files():
        rel = path.relative_to(ROOT).as_posix()
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if PHRASE.search(line):
                hits.append((rel, number, " ".join(line.split())))
    return hits


def _named_tests(cell: str) -> list[str]:
    return re.findall(r"tests/[\w/]+\.py::\w+(?:::\w+)?", cell)


def test_the_table_parses_into_rows_with_known_verdicts():
    rows = _rows()
    assert len(rows) >= 50, len(rows)
    bad = [(r["path"], r["snippet"], r["verdict"]) for r in rows if r["verdict"] not in VERDICTS]
    assert not bad, f"verdicts must be one of {sorted(VERDICTS)}: {bad}"


def _match(hits: list[str], rows: list[str]) -> dict[int, int]:
    """A one-to-one matching of hit lines to row snippets (Kuhn's augmenting paths): a second claim in a
    file never hides behind another claim's row with the same short snippet."""
    owner: dict[int, int] = {}  # row -> hit

    def take(h: int, seen: set[int]) -> bool:
        for r, snippet in enumerate(rows):
            if r not in seen and snippet and snippet in hits[h]:
                seen.add(r)
                if r not in owner or take(owner[r], seen):
                    owner[r] = h
                    return True
        return False

    for h in range(len(hits)):
        take(h, set())
    return {h: r for r, h in owner.items()}


def test_every_claim_phrase_has_a_row():
    rows = [r for r in _rows() if r["verdict"] != "changed"]
    missing = []
    by_file: dict[str, list[tuple[int, str]]] = {}
    for rel, number, line in _hits():
        by_file.setdefault(rel, []).append((number, line))
    for rel, hits in by_file.items():
        snippets = [r["snippet"] for r in rows if r["path"] == rel]
        matched = _match([line for _, line in hits], snippets)
        missing += [f"{rel}:{n}: {line[:100]}" for h, (n, line) in enumerate(hits) if h not in matched]
    assert not missing, (
        "these 'as the authors' / 'as the paper' claims have no row in docs/claims.md (add one "
        "with the file path and a snippet of the line, its source and its test):\n" + "\n".join(missing))


def test_every_row_that_is_not_changed_still_finds_its_claim():
    stale = []
    for r in _rows():
        if r["verdict"] == "changed":
            continue
        path = ROOT / r["path"]
        text = " ".join(path.read_text(encoding="utf-8").split()) if path.exists() else ""
        if not r["snippet"] or r["snippet"] not in text:
            stale.append((r["path"], r["snippet"]))
    assert not stale, f"rows whose claim is no longer in their file (mark them changed or drop them): {stale}"


def test_tested_rows_name_a_test_and_source_only_rows_a_source():
    for r in _rows():
        if r["verdict"] == "tested":
            assert _named_tests(r["test"]), (r["path"], r["snippet"], r["test"])
        if r["verdict"] in ("tested", "source-only"):
            assert r["source"] not in ("", "-", "—"), (r["path"], r["snippet"])


@pytest.mark.parametrize("name", sorted({t for r in _rows() for t in _named_tests(r["test"])}))
def test_every_named_test_exists(name):
    file, *parts = name.split("::")
    path = ROOT / file
    assert path.exists(), f"{name}: no file {file}"
    text = path.read_text(encoding="utf-8")
    if len(parts) == 2:
        assert re.search(rf"^class {parts[0]}\b", text, re.M), f"{name}: no class {parts[0]} in {file}"
    assert re.search(rf"^\s*(async )?def {parts[-1]}\(", text, re.M), f"{name}: no test {parts[-1]} in {file}"
