"""The documentation stays a front door plus docs/, and the code cites only files inside the repository."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS = ("benchmarks.md", "detection.md", "formats.md", "design.md")
OUTSIDE = re.compile(r"\b(STACK|DESIGN|STYLE)\.md\b")
SESSION = re.compile(r"\bsessions? [0-9]+|session-[0-9]+", re.IGNORECASE)
DOC_PATH = re.compile(r"\bdocs/[\w./-]+\.(?:md|png)")
DESIGN_SECTION = re.compile(r"docs/design\.md\s+(?:#\s*)?sections?\s+(\d+)(?:\s*(?:-|and|,)\s*(\d+))?")
EQUATION = re.compile(r"\b[AKP]\.\d+\b")
MD_LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def tracked(*patterns: str) -> list[Path]:
    """Files git tracks in the repository, optionally only those matching the patterns."""
    out = subprocess.run(["git", "ls-files", "-z", "--", *patterns], cwd=ROOT, capture_output=True, check=True)
    return [ROOT / name for name in out.stdout.decode().split("\0") if name]


def text(path: Path) -> str:
    """A tracked file's text ('' for a binary file)."""
    data = path.read_bytes()
    return "" if b"\0" in data else data.decode("utf-8", errors="replace")


def test_readme_is_a_front_door() -> None:
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 250
    head = "\n".join(lines[:40])
    assert "make demo" in head and "make test" in head


def test_docs_holds_the_four_documents() -> None:
    for name in DOCS:
        body = (ROOT / "docs" / name).read_text()
        assert body.startswith("# ") and len(body.splitlines()) > 20, name


def test_no_tracked_file_speaks_of_session_numbers() -> None:
    hits = [f"{p.relative_to(ROOT)}:{n}" for p in tracked() for n, line in enumerate(text(p).splitlines(), 1)
            if SESSION.search(line)]
    assert hits == []


def test_code_cites_no_file_outside_the_repository() -> None:
    hits = []
    for path in tracked("*.py", "*.toml", "*.proto"):
        for n, line in enumerate(text(path).splitlines(), 1):
            for m in OUTSIDE.finditer(line):
                if not (ROOT / m.group(0)).exists():
                    hits.append(f"{path.relative_to(ROOT)}:{n}: {m.group(0)}")
    assert hits == []


def test_every_cited_docs_file_exists() -> None:
    cited = {m.group(0) for p in tracked("*.py", "*.toml", "*.proto") for m in DOC_PATH.finditer(text(p))}
    assert "docs/design.md" in cited
    assert sorted(c for c in cited if not (ROOT / c).is_file()) == []


def test_cited_design_sections_and_equations_exist() -> None:
    design = (ROOT / "docs" / "design.md").read_text()
    sections = {int(n) for n in re.findall(r"^## (\d+)\. ", design, re.MULTILINE)}
    assert sections == set(range(1, max(sections) + 1))
    missing = set()
    for path in tracked("*.py", "*.proto", "*.md"):
        for m in DESIGN_SECTION.finditer(text(path)):
            missing |= {int(n) for n in m.groups() if n} - sections
    assert missing == set()
    labels = {m.group(0) for p in tracked("*.py") for m in EQUATION.finditer(text(p))}
    assert {"A.1", "A.29", "A.33", "K.2", "P.33"} <= labels
    assert sorted(label for label in labels if not re.search(rf"\b{re.escape(label)}\b", design)) == []


def test_relative_links_in_the_documents_resolve() -> None:
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for target in MD_LINK.findall(path.read_text()):
            if "://" not in target:
                assert (path.parent / target).exists(), f"{path.name}: {target}"
