"""mkdocs hook: the site's navigation, built from the pages that exist.

Several pages are written by other work in progress (``OPTIONAL`` below); the strict build must
pass before and after each lands. So the nav lists a page only if its file exists, every other
Markdown file under docs/ is appended to its section (or to "More"), and a link to a missing
optional page is rendered as its text instead of a broken link.
"""

from __future__ import annotations

import re
from pathlib import Path

# (section title, [(page title, path relative to docs/), ...]); None title: the page's own.
LAYOUT: list[tuple[str | None, list[tuple[str | None, str]]]] = [
    (None, [("Home", "index.md"), ("Getting started", "getting-started.md")]),
    ("Concepts", [
        (None, "concepts/contexts.md"),
        (None, "concepts/preferences.md"),
        (None, "concepts/evaluation.md"),
        (None, "concepts/nhgr-and-floors.md"),
        (None, "concepts/architecture.md"),
    ]),
    ("Domains", [
        ("Overview", "domains/index.md"),
        (None, "domains/lunar-lander.md"),
        (None, "domains/hopper.md"),
        (None, "domains/halfcheetah.md"),
        (None, "domains/humanoid.md"),
        (None, "domains/lava-grid.md"),
        (None, "domains/mario.md"),
        (None, "domains/dmc.md"),
        (None, "any-environment.md"),
        (None, "gymnasium.md"),
    ]),
    ("Algorithms", [
        ("Overview", "algorithms/index.md"),
        (None, "algorithms/envelope.md"),
        (None, "algorithms/capql.md"),
        (None, "algorithms/mosac.md"),
        (None, "algorithms/morld.md"),
        (None, "algorithms/sac.md"),
        (None, "algorithms/gpi.md"),
        (None, "algorithms/pcn.md"),
        (None, "algorithms/pgmorl.md"),
        (None, "fidelity.md"),
        (None, "algorithms-fidelity-mechanisms.md"),
        (None, "claims.md"),
    ]),
    ("Training and runs", [
        (None, "training.md"),
        (None, "reports.md"),
        (None, "safety.md"),
        (None, "fsorl.md"),
        (None, "speed.md"),
        (None, "gpu.md"),
        (None, "benchmarks.md"),
    ]),
    ("Tutorials", [
        (None, "tutorials/compose-transforms.md"),
        (None, "tutorials/own-trainer.md"),
        (None, "tutorials/own-domain.md"),
        (None, "tutorials/mo-gymnasium.md"),
        (None, "tutorials/ray-grid.md"),
    ]),
    ("API reference", [("Overview", "reference/index.md")]),  # + every reference/*.md
    ("Project", [(None, "project.md"), (None, "contributing.md")]),
]

# pages other work writes; linked from ours, possibly absent at build time
OPTIONAL = {
    "fidelity.md", "algorithms-fidelity-mechanisms.md", "safety.md", "fsorl.md", "any-environment.md",
    "tutorials/own-domain.md", "tutorials/mo-gymnasium.md", "speed.md", "gpu.md",
}
_SECTION_OF_DIR = {"tutorials": "Tutorials", "reference": "API reference", "domains": "Domains",
                   "algorithms": "Algorithms", "concepts": "Concepts"}


def build_nav(docs_dir: Path) -> list:
    present = {p.relative_to(docs_dir).as_posix() for p in docs_dir.rglob("*.md") if "hooks" not in p.parts}
    listed = {path for _, pages in LAYOUT for _, path in pages}
    extra: dict[str, list[str]] = {}
    for path in sorted(present - listed):
        section = _SECTION_OF_DIR.get(path.split("/")[0], "More") if "/" in path else "More"
        extra.setdefault(section, []).append(path)
    nav: list = []
    for section, pages in LAYOUT:
        entries = [({title: path} if title else path) for title, path in pages if path in present]
        entries += extra.pop(section or "", [])
        if section is None:
            nav.extend(entries)
        elif entries:
            nav.append({section: entries})
    for section, paths in extra.items():
        nav.append({section: paths})
    return nav


def on_config(config, **kwargs):
    config["nav"] = build_nav(Path(config["docs_dir"]))
    return config


_LINK = re.compile(r"\[([^\]]+)\]\(([^)#\s]+\.md)(#[^)]*)?\)")


def on_page_markdown(markdown, page, config, files, **kwargs):
    """A link to an optional page that is not there yet becomes its plain text."""
    docs_dir = Path(config["docs_dir"])
    here = (docs_dir / page.file.src_uri).parent

    def fix(m: re.Match) -> str:
        target = (here / m.group(2)).resolve()
        try:
            rel = target.relative_to(docs_dir.resolve()).as_posix()
        except ValueError:
            return m.group(0)
        if rel in OPTIONAL and not target.is_file():
            return m.group(1)
        return m.group(0)

    return _LINK.sub(fix, markdown)
