"""Every citation of a doc resolves inside the repository: each ``docs/<name>.md`` path cited in a .py or .md file
exists, and each section cited as ``smac_interface.md §N`` (or ``smac_hard_reference §N``) is a numbered section of
``docs/smac_interface.md`` (``docs/smac_hard_reference.md``)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SKIP_DIRS = {"build", "dist", "node_modules", "__pycache__"}

DOC_PATH = re.compile(r"(?<![\w/.-])docs/[\w./-]*?\.md\b")
SECTIONS = r"(?:§\s*|section\s+)(\d+(?:\s*(?:-|/|,|and)\s*§?\s*\d+)*)"
EXTERNAL_DOCS = {  # other projects' docs that this repository cites by path -> the project named just before them
    "docs/" "environment.md": "pysc2",
    "docs/" "smac.md": "SMAC",
}
CITED_DOCS = {  # how a doc is named in a citation -> the file that must hold the section
    "smac_interface": "docs/smac_interface.md",
    "smac_hard_reference": "docs/smac_hard_reference.md",
}
CITATION = re.compile(r"(?<![\w-])(" + "|".join(CITED_DOCS) + r")(?:\.md)?`{0,2}\s*" + SECTIONS)


def _sources() -> list[Path]:
    out = []
    for path in ROOT.rglob("*"):
        rel = path.relative_to(ROOT).parts
        if path.suffix not in (".py", ".md") or not path.is_file():
            continue
        if any(p.startswith(".") or p in SKIP_DIRS or p.endswith(".egg-info") for p in rel[:-1]):
            continue
        out.append(path)
    return out


def _numbers(text: str) -> list[int]:
    """The section numbers of a citation's list: ``3-§6`` is 3, 4, 5, 6; ``7, §9`` and ``3/§4`` are each one."""
    out: list[int] = []
    for part in re.split(r"\s*(?:/|,|and)\s*", text):
        bounds = [int(n) for n in re.findall(r"\d+", part)]
        out += list(range(bounds[0], bounds[-1] + 1)) if len(bounds) > 1 else bounds
    return out


def _has_section(doc: str, n: int) -> bool:
    return re.search(rf"^#+\s*(?:§\s*{n}\b|{n}\.)", doc, flags=re.M) is not None


def broken_citations(text: str, where: str = "") -> list[str]:
    """What in ``text`` does not resolve: missing ``docs/`` files and missing numbered sections."""
    problems = []
    for match in DOC_PATH.finditer(text):
        project = EXTERNAL_DOCS.get(match.group(0))
        if project is not None and project in text[max(0, match.start() - 30):match.start()]:
            continue
        if not (ROOT / match.group(0)).is_file():
            problems.append(f"{where}: {match.group(0)} does not exist")
    for match in CITATION.finditer(text):
        doc_path = ROOT / CITED_DOCS[match.group(1)]
        if not doc_path.is_file():
            problems.append(f"{where}: {match.group(0)!r} cites {doc_path.name}, which does not exist")
            continue
        doc = doc_path.read_text(encoding="utf-8")
        for n in _numbers(match.group(2)):
            if not _has_section(doc, n):
                problems.append(f"{where}: {match.group(0)!r} cites section {n}, not in {CITED_DOCS[match.group(1)]}")
    return problems


def test_every_cited_doc_and_section_exists():
    problems = []
    sources = _sources()
    assert len(sources) > 50  # the scan found the repository
    for path in sources:
        problems += broken_citations(path.read_text(encoding="utf-8", errors="replace"),
                                     str(path.relative_to(ROOT)))
    assert not problems, "\n".join(problems)


def test_the_cited_docs_number_their_sections():
    doc = (ROOT / "docs" / "smac_interface.md").read_text(encoding="utf-8")
    assert all(_has_section(doc, n) for n in range(2, 10))
    doc = (ROOT / "docs" / "smac_hard_reference.md").read_text(encoding="utf-8")
    assert all(_has_section(doc, n) for n in (3, 6, 7))


@pytest.mark.parametrize("text, bad", [
    ("see " + "docs/" + "no_such_doc.md", 1),
    ("see " + "docs/" + "smac.md", 1),  # SMAC's doc only when SMAC is named
    ("SMAC's `" + "docs/" + "smac.md`", 0),
    ("(" + "smac_" + "interface §12)", 1),
    ("(``" + "smac_" + "interface.md`` §3-§11)", 2),
    ("smac_" + "hard_reference §4", 1),
    ("smac_" + "interface section 9, " + "docs/" + "smac_interface.md", 0),
    ("smac_" + "interface.md §3/§4 and §7, §9", 0),
])
def test_the_check_catches_a_missing_file_or_section(text, bad):
    assert len(broken_citations(text)) == bad, broken_citations(text)


def test_section_ranges_expand_to_section_numbers():
    assert _numbers("3-§6") == [3, 4, 5, 6]
    assert _numbers("7, §9") == [7, 9]
    assert _numbers("3/§4") == [3, 4]


MANUAL = [ROOT / "README.md", ROOT / "benchmarks" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
TRACKER = re.compile(r"\bissues?\s+[0-9]|\bissue\s+#?[0-9]+'s|\bthe issue\b", re.I)  # "issue 12", "Issue 14", ...
OTHER_PROJECT_ISSUE = re.compile(r"[\w.-]+/[\w.-]+ issue #\d+|smac issue #\d+")  # a cited issue of another project
MACHINE_PATH = re.compile(r"(?<![\w.~-])/(?:work|tmp|root)/")


def manual_problems(text: str, where: str = "") -> list[str]:
    """Passages of a manual page that only make sense on the machine or in the tracker it was written with: a
    reference to one of this project's issues ("issue 12's engine") or an absolute machine path."""
    problems = []
    for number, line in enumerate(text.splitlines(), 1):
        line_free = OTHER_PROJECT_ISSUE.sub("", line)
        if TRACKER.search(line_free):
            problems.append(f"{where}:{number}: names an issue instead of the thing itself: {line.strip()[:100]}")
        if MACHINE_PATH.search(line):
            problems.append(f"{where}:{number}: an absolute machine path: {line.strip()[:100]}")
    return problems


def test_the_manual_names_things_not_issues_or_machine_paths():
    # README.md, docs/ and benchmarks/README.md are a manual for a reader who has only the repository: history goes
    # into CHANGELOG.md, and commands use paths relative to the repository.
    problems = []
    for path in MANUAL:
        problems += manual_problems(path.read_text(encoding="utf-8"), str(path.relative_to(ROOT)))
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("text, bad", [
    ("on issue 12's engine", 1), ("Issue 14: one pass down", 1), ("the issue's bar", 1), ("see /work/main/x", 1),
    ("python3 -m venv /tmp/venv", 1), ("chaovven/SMIX issue #5", 0), ("(smac issue #91)", 0), ("../smax-venv", 0),
    ("an issue with the engine", 0), ("`runs/3m/model.zip`", 0),
])
def test_the_manual_check_catches_issue_numbers_and_machine_paths(text, bad):
    assert len(manual_problems(text)) == bad, manual_problems(text)
