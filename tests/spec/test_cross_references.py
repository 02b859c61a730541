"""Every section the code, tests and spec cite exists in spec/FORMAT.md, and no text points to
a document that is not in the repository (older comments cited draft files and a design file
that were never committed)."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SPEC = REPO / "spec" / "FORMAT.md"
#: Folders whose text may cite the spec by section number.
CITING = ("csgs_codec", "cli", "spec", "tests", "docs")
#: Folders whose text may name documents (benchmarks too).
NAMING = CITING + ("benchmarks",)
SUFFIXES = {".py", ".md", ".mjs", ".js", ".toml", ".txt"}
SKIP_PARTS = {"vectors", "node_modules", "__pycache__"}

HEADING = re.compile(r"^#{2,4} (\d+(?:\.\d+)*)\.? ", re.MULTILINE)
CITATION = re.compile(r"(?:§|\b[Ss]ections? )(\d+(?:\.\d+)*)")
DOC_PATH = re.compile(r"\b((?:spec|docs|benchmarks|samples)/[\w./-]*\w\.md)\b")
#: Names that older text used for documents that do not exist.
GONE = ("DESIGN" + ".md", "spec/" + "drafts")


def _text_files(folders: tuple[str, ...]) -> list[Path]:
    files = []
    for folder in folders:
        root = REPO / folder
        if root.is_dir():
            files += [p for p in sorted(root.rglob("*"))
                      if p.is_file() and p.suffix in SUFFIXES
                      and not SKIP_PARTS.intersection(p.relative_to(REPO).parts)]
    files.append(REPO / "README.md")
    return files


def spec_sections() -> set[str]:
    """Section numbers that are headings of spec/FORMAT.md ("12.8", "16.2.4", ...)."""
    return set(HEADING.findall(SPEC.read_text(encoding="utf-8")))


def test_the_spec_has_the_range_coder_sections_and_its_revisions_apart():
    sections = spec_sections()
    assert {"15.5", "16.2.3", "16.2.4", "16.2.5"} <= sections
    # The draft's revision list lives beside the normative text, not in it (issue #33).
    assert "Changelog" not in SPEC.read_text(encoding="utf-8")
    changes = (SPEC.parent / "CHANGES.md").read_text(encoding="utf-8")
    assert changes.startswith("# Revisions of spec/FORMAT.md")
    assert cited_but_missing(changes, sections) == []


def cited_but_missing(text: str, sections: set[str]) -> list[str]:
    """Section numbers ``text`` cites (§N.N, "section N.N") that are not spec headings."""
    return sorted({m for m in CITATION.findall(text) if m not in sections})


def test_the_checks_catch_what_older_text_had():
    sections = spec_sections()
    assert cited_but_missing("histogram stream (FORMAT §16.6), see §15.5", sections) == ["16.6"]
    assert cited_but_missing("draft, section 9.9", sections) == ["9.9"]
    assert DOC_PATH.findall("see docs/nothing_here.md.") == ["docs/nothing_here.md"]


def test_every_cited_section_exists():
    sections = spec_sections()
    problems = {}
    for path in _text_files(CITING):
        if path == Path(__file__).resolve():
            continue  # its own examples cite missing sections on purpose
        missing = cited_but_missing(path.read_text(encoding="utf-8"), sections)
        if missing:
            problems[str(path.relative_to(REPO))] = missing
    assert not problems, f"sections cited but not headings of spec/FORMAT.md: {problems}"


def test_no_reference_to_documents_outside_the_repository():
    problems = {}
    for path in _text_files(NAMING):
        if path == Path(__file__).resolve():
            continue
        text = path.read_text(encoding="utf-8")
        bad = [name for name in GONE if name in text]
        bad += sorted({p for p in DOC_PATH.findall(text) if not (REPO / p).exists()})
        if bad:
            problems[str(path.relative_to(REPO))] = bad
    assert not problems, f"documents named but not in the repository: {problems}"
