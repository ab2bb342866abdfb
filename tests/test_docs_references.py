"""No document or test names a script or a figure that is not in the checkout.

A script of benchmarks/ or scripts/ named in README.md, Makefile, .ci/, docs/ (with docs/research/) or tests/ must
exist; a deleted one is named with the commit that has it (``264b8a3:benchmarks/NAME.py``, as ``git show`` reads
it).
An image a markdown file shows (``![...](path.png)``) must exist beside it."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = re.compile(r"(?<![\w/.-])((?:[0-9a-f]{7,40}:)?)((?:benchmarks|scripts)/[\w.-]+\.(?:py|sh))")
IMAGE = re.compile(r"!\[[^\]]*\]\(([^)\s]+\.png)\)")


def _documents() -> list[Path]:
    files = [ROOT / "README.md", ROOT / "Makefile", *sorted((ROOT / ".ci").glob("*")),
             *sorted((ROOT / "docs").rglob("*.md")),
             *sorted(f for f in (ROOT / "tests").rglob("*.py") if f.name != Path(__file__).name)]
    return [f for f in files if f.is_file()]


def missing_scripts(text: str, root: Path = ROOT) -> list[str]:
    """The ``benchmarks/…`` / ``scripts/…`` paths in ``text`` that are not files under ``root`` and carry no
    commit prefix."""
    return [path for commit, path in SCRIPT.findall(text) if not commit and not (root / path).is_file()]


def test_every_script_a_document_or_test_names_exists():
    bad = {str(f.relative_to(ROOT)): m for f in _documents() if (m := missing_scripts(f.read_text()))}
    assert not bad, f"scripts named but not in the checkout (name a deleted one as COMMIT:path): {bad}"


def test_every_image_a_document_shows_exists():
    bad = [(str(f.relative_to(ROOT)), p) for f in _documents() if f.suffix == ".md"
           for p in IMAGE.findall(f.read_text()) if not p.startswith("http") and not (f.parent / p).is_file()]
    assert not bad, f"images shown but missing: {bad}"


def test_the_check_sees_a_deleted_script_and_accepts_its_commit_form(tmp_path):
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / "benchmarks" / "kept.py").write_text("")
    text = ("run `python benchmarks/kept.py`, then benchmarks/gone.py; old: 264b8a3:benchmarks/gone2.py, "
            "scripts/x.sh")
    assert missing_scripts(text, tmp_path) == ["benchmarks/gone.py", "scripts/x.sh"]


def test_benchmarks_holds_only_what_the_docs_cite_and_at_most_20_files():
    """benchmarks/ keeps the benchmarks the documents cite and ``tune.py`` (issue 40: at most 20 files); a study
    whose decision is taken is deleted and named as ``COMMIT:benchmarks/NAME.py``."""
    files = sorted(p.name for p in (ROOT / "benchmarks").iterdir() if p.is_file())
    assert len(files) <= 20, f"benchmarks/ holds {len(files)} files: {files}"
    text = "\n".join(f.read_text() for f in _documents() if not f.is_relative_to(ROOT / "tests"))
    uncited = [name for name in files if f"benchmarks/{name}" not in text]
    assert not uncited, f"benchmarks/ files no document names: {uncited}"
