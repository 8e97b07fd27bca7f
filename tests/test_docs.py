"""What the code, the tests and the conform reports cite is in the repository: every
``docs/NAME.md#anchor`` named in a source file or a document exists, with that anchor."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CITATION = re.compile(r"docs/([a-z0-9_-]+\.md)(?:#([a-z0-9-]+))?")
LINK = re.compile(r"\]\(([a-z0-9_-]+\.md)(?:#([a-z0-9-]+))?\)")  # a Markdown link beside the document
ANCHOR = re.compile(r'<a id="([a-z0-9-]+)"></a>')


def _cited() -> list[tuple[str, str, str | None]]:
    """(where, document, anchor or None) for every citation of a docs/ file."""
    found = []
    files = [p for d in ("protocol", "roles", "fieldbox", "tests", "benchmarks", "docs") for p in (ROOT / d).rglob("*")
             if p.suffix in (".py", ".md")] + [ROOT / "README.md"]
    for path in files:
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for m in CITATION.finditer(line):
                found.append((f"{path.relative_to(ROOT)}:{n}", m.group(1), m.group(2)))
            if path.parent.name == "docs":
                for m in LINK.finditer(line):
                    found.append((f"{path.relative_to(ROOT)}:{n}", m.group(1), m.group(2)))
    return found


def test_every_cited_document_and_section_exists():
    cited = _cited()
    assert any(doc == "protocol.md" and anchor for _, doc, anchor in cited)  # the scan finds them
    anchors: dict[str, set[str]] = {}
    missing = []
    for where, doc, anchor in cited:
        path = ROOT / "docs" / doc
        if not path.is_file():
            missing.append(f"{where}: docs/{doc} does not exist")
            continue
        if doc not in anchors:
            anchors[doc] = set(ANCHOR.findall(path.read_text(encoding="utf-8")))
        if anchor is not None and anchor not in anchors[doc]:
            missing.append(f"{where}: docs/{doc} has no section #{anchor}")
    assert not missing, "\n".join(missing)


def test_the_documents_the_code_once_cited_outside_the_repository_are_in_it():
    for doc in ("design.md", "protocol.md", "style.md"):
        assert (ROOT / "docs" / doc).is_file(), doc
