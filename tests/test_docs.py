"""The user's guide builds, its citations resolve, and the repository names no numbered work periods.

* ``mkdocs build --strict`` (mkdocs.yml at the root, docs/ the pages): a broken link, a missing
  page or anchor, or a page left out of the navigation fails it.
* Every "SPEC §N" the code cites is a numbered section of docs/paper.md, the page that says what
  the paper's numbers are.
* No tracked text or file name refers to a past work period by its number (the word "session"
  followed by one, or a numbered training folder, var/train<N>): the repository says what
  holds and why, its history is git's.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from support import REPO_ROOT

SPEC_CITATION = re.compile(r"SPEC ?§ ?(\d+)")
PAPER_SECTION = re.compile(r"^## (\d+)\. ", re.MULTILINE)
WORK_PERIOD = re.compile(r"\bsessions? ?\d+|\btrain\d+", re.IGNORECASE)
TEXT_SUFFIXES = {".py", ".md", ".txt", ".yaml", ".yml", ".toml", ".ini", ".cfg", ".sh", ".json", ".ts",
                 ".js", ".html", ".css", ".csv", ""}


def _repository_files() -> list[Path]:
    """Tracked files and untracked ones git does not ignore, as paths relative to the root."""
    listed = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
                            cwd=REPO_ROOT, capture_output=True, check=True).stdout.decode()
    return [Path(name) for name in listed.split("\0") if name and (REPO_ROOT / name).is_file()]


def test_the_guide_builds_strictly(tmp_path: Path) -> None:
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}  # Material's notice about its successor
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path)],
                          cwd=REPO_ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-4000:]
    assert (tmp_path / "paper" / "index.html").is_file()
    fields = (tmp_path / "guide" / "scenarios" / "index.html").read_text(encoding="utf-8")
    assert "ego.start_distance_m" in fields  # the field table generated from the scenario schema


def test_every_spec_citation_of_the_code_is_a_section_of_the_paper_page() -> None:
    sections = set(PAPER_SECTION.findall((REPO_ROOT / "docs" / "paper.md").read_text(encoding="utf-8")))
    cited: dict[str, set[str]] = {}
    for path in (REPO_ROOT / "backend" / "crossroads").rglob("*.py"):
        for number in SPEC_CITATION.findall(path.read_text(encoding="utf-8")):
            cited.setdefault(number, set()).add(str(path.relative_to(REPO_ROOT)))
    assert cited, "the code cites no SPEC section: has the citation style changed?"
    missing = {n: sorted(files) for n, files in cited.items() if n not in sections}
    assert not missing, f"cited but not a section of docs/paper.md: {missing}"


def test_no_numbered_work_periods_in_texts_or_file_names() -> None:
    found = []
    for rel in _repository_files():
        if WORK_PERIOD.search(rel.as_posix()) or re.search(r"run\d+", rel.name):
            found.append(f"{rel}: file name")
        if rel.suffix not in TEXT_SUFFIXES:
            continue
        try:
            text = (REPO_ROOT / rel).read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        for number, line in enumerate(text.splitlines(), 1):
            if WORK_PERIOD.search(line):
                found.append(f"{rel}:{number}: {line.strip()[:120]}")
    assert not found, "numbered work periods:\n" + "\n".join(found[:50])
