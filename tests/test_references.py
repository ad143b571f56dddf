"""Code comments and docstrings cite only documents a user of this repository has.

* No citation of the internal specification ("SPEC §…"), of the internal stack notes
  ("STACK.md") or of issue numbers ("issue 4"): point into ``docs/`` instead.
* Every ``docs/<name>.md`` cited in code exists, and every ``§<n>`` cited after it
  (``docs/method.md §2.1``, ``docs/method.md §5.2, §5.3``) is the number of one of that
  page's section headings (``## §2 …``, ``### §2.1 …``; ``## 1. …`` also counts).
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("npsim_core", "npsim_gui", "npsim_cli", "benchmarks", "tests")
THIS = Path(__file__).resolve()

FORBIDDEN = re.compile(r"\bSPEC\b|STACK\.md|\bissue \d+")
#: ``docs/name.md`` optionally followed by section numbers: ``§2.1``, ``§3, §4``, ``§5.2 and §5.3``, ``§3-4``.
DOC_REF = re.compile(r"docs/([\w.-]+?\.md)((?:\s*(?:,|and|-|–|/)?\s*§\d+(?:\.\d+)*)*)")
SECTION_NUM = re.compile(r"§(\d+(?:\.\d+)*)")
HEADING = re.compile(r"^#{1,6}\s+§?(\d+(?:\.\d+)*)\.?(?:\s|$)")


def _python_files() -> list[Path]:
    files: list[Path] = []
    for top in SCANNED:
        base = ROOT / top
        if base.is_dir():
            files += [p for p in sorted(base.rglob("*.py")) if p.resolve() != THIS and "__pycache__" not in p.parts]
    return files


def _lines():
    for path in _python_files():
        rel = path.relative_to(ROOT).as_posix()
        for no, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            yield rel, no, line


def _heading_numbers(doc: Path) -> set[str]:
    nums = set()
    for line in doc.read_text(encoding="utf-8").splitlines():
        m = HEADING.match(line)
        if m:
            nums.add(m.group(1))
    return nums


def test_scanner_sees_the_code():
    files = {p.relative_to(ROOT).as_posix() for p in _python_files()}
    assert "npsim_core/camera.py" in files and "tests/test_references.py" not in files


def test_no_internal_references_in_code():
    hits = [f"{rel}:{no}: {line.strip()}" for rel, no, line in _lines() if FORBIDDEN.search(line)]
    assert not hits, ("code cites documents users do not have (SPEC, STACK.md, issue numbers); "
                      "point into docs/ instead (docs/method.md §…, docs/stack.md):\n" + "\n".join(hits))


def test_doc_references_in_code_exist():
    docs = ROOT / "docs"
    headings: dict[str, set[str]] = {}
    bad = []
    for rel, no, line in _lines():
        for m in DOC_REF.finditer(line):
            name, tail = m.group(1), m.group(2)
            doc = docs / name
            if not doc.is_file():
                bad.append(f"{rel}:{no}: docs/{name} does not exist")
                continue
            if name not in headings:
                headings[name] = _heading_numbers(doc)
            for num in SECTION_NUM.findall(tail):
                if num not in headings[name]:
                    bad.append(f"{rel}:{no}: docs/{name} has no section §{num}")
    assert not bad, "broken references to docs/ in code:\n" + "\n".join(bad)


def test_method_doc_numbers_its_sections():
    nums = _heading_numbers(ROOT / "docs" / "method.md")
    # the sections the code cites most
    for n in ("1", "1.2", "1.3", "1.4", "2", "2.2", "3", "3.1", "3.2", "3.3", "4", "5", "5.6", "6", "6.5", "7",
              "8", "9", "10"):
        assert n in nums, f"docs/method.md lost its section §{n}"
    assert "2" in _heading_numbers(ROOT / "docs" / "stack.md")
