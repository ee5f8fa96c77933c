"""docs/ as a site (mkdocs.yml, `make docs`): it builds with --strict, so a link to a page or an anchor that does
not exist, or a page left out of the nav, fails the build; shown failing on a copy with one broken link each."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytest.importorskip("mkdocs", reason="mkdocs is not installed (the docs and test extras have it)")


def _build(root: Path, site: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(root / "mkdocs.yml"),
                           "-d", str(site)], capture_output=True, text=True, timeout=120)


def test_the_docs_build_strict_and_every_page_is_in_the_nav(tmp_path: Path) -> None:
    res = _build(ROOT, tmp_path / "site")
    assert res.returncode == 0, res.stderr
    pages = {p.stem for p in (ROOT / "docs").glob("*.md")}
    built = {p.parent.name for p in (tmp_path / "site").glob("*/index.html")} | {"index"}
    assert pages <= built, pages - built


@pytest.mark.parametrize(("page", "broken", "says"), [
    ("user-guide.md", "[the lessons](lesons.md)", "lesons.md"),
    ("user-guide.md", "[keys](#no-such-heading)", "no-such-heading"),
    ("orphan.md", "# A page no nav names", "orphan.md"),
])
def test_a_broken_link_or_an_orphan_page_fails_the_build(tmp_path: Path, page: str, broken: str, says: str) -> None:
    copy = tmp_path / "copy"
    shutil.copytree(ROOT / "docs", copy / "docs", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "mkdocs.yml", copy)
    with (copy / "docs" / page).open("a") as f:
        f.write(f"\n{broken}\n")
    res = _build(copy, tmp_path / "site")
    assert res.returncode != 0 and says in res.stderr, res.stderr
